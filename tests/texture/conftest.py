"""Fixtures for tests/texture: defined in texture_helpers.py, which the tests also import by that
unique name (several test folders have a conftest.py, so `from conftest import` is ambiguous)."""
from texture_helpers import *  # noqa: F401,F403
