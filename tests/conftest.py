"""Shared test helpers: where the shared real meshes live (used by path, never copied)."""
from __future__ import annotations

import os
from pathlib import Path

import pytest

# Helper processes or a busy CI box oversubscribe the 2 cores; spinning OpenMP workers then
# slow torch down many times over. Must be set before torch is imported.
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

SHARED_MESHES = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "meshes"
ON_CI = os.environ.get("CI", "").lower() in ("1", "true", "yes")


@pytest.fixture(scope="session")
def shared_meshes() -> Path:
    """Folder of the shared real meshes; skips when it is absent (it is optional)."""
    if not SHARED_MESHES.is_dir():
        pytest.skip(f"shared meshes not found at {SHARED_MESHES}")
    return SHARED_MESHES
