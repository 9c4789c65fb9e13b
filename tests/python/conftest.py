"""Shared pytest fixtures for the Python suites (host, sim, ...)."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
# The catheter recordings have no licence: read in place at run time, never copied.
REAL_CATHETER = Path(os.environ.get("PLAYSCOPE_REAL_DATA", REPO.parent / "shared" / "data" / "real")) / "catheter"


@pytest.fixture
def real_catheter_dir() -> Path:
    """Folder of the real catheter recordings; skips the test when they are absent."""
    if not (REAL_CATHETER / "data_2_1.txt").is_file():
        pytest.skip(f"real catheter data not found in {REAL_CATHETER}")
    return REAL_CATHETER
