"""The learning-rate schedule: constant, then a cosine down to the final fraction."""
from __future__ import annotations

import pytest

from mna.fit import lr_factor


def test_constant_before_decay_start():
    assert [lr_factor(p, 0.55, 0.02) for p in (0.0, 0.3, 0.55)] == [1.0, 1.0, 1.0]


def test_cosine_values():
    assert lr_factor(1.0, 0.5, 0.02) == pytest.approx(0.02)
    assert lr_factor(0.75, 0.5, 0.02) == pytest.approx((1 + 0.02) / 2)  # half way: cos(pi/2) = 0
    assert lr_factor(0.625, 0.5, 0.0) == pytest.approx(0.5 * (1 + 2**-0.5))  # cos(pi/4)


def test_no_decay_when_start_is_one():
    assert lr_factor(1.0, 1.0, 0.02) == 1.0
