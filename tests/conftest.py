"""Shared test helpers: where the shared real meshes live (used by path, never copied)."""
from __future__ import annotations

import os
from pathlib import Path

import pytest

SHARED_MESHES = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "meshes"
ON_CI = os.environ.get("CI", "").lower() in ("1", "true", "yes")


@pytest.fixture(scope="session")
def shared_meshes() -> Path:
    """Folder of the shared real meshes; skips when it is absent (it is optional)."""
    if not SHARED_MESHES.is_dir():
        pytest.skip(f"shared meshes not found at {SHARED_MESHES}")
    return SHARED_MESHES
