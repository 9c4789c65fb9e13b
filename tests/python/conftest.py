"""Shared pytest configuration and fixtures for the Python suites (host, sim, link, main).

One BLAS thread per test process. The suite's least-squares problems are small, and a threaded
BLAS on a busy 2-core machine (pytest-xdist runs two workers, CI may run beside other work)
spins its threads against each other: the diagnosis tests of sim/test_recover.py took 3-4 s
with one thread and 175-185 s with two on this machine under load. The variables are read when
numpy is first imported, which is after this file for `pytest tests/python`; if something
imported numpy earlier (a plugin), threadpoolctl sets the same limit on the loaded libraries.
A variable already set by the caller is kept.

The `slow` marker: a test that cannot be made small (see CONTRIBUTING.md). The README's
`./tools/run-tests.sh` leaves them out; `./tools/run-tests.sh --all` and `bench/run_all.py` run
them."""

from __future__ import annotations

import os
import sys
from pathlib import Path

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")
if "numpy" in sys.modules:  # loaded before this file: limit the loaded BLAS/OpenMP pools instead
    from threadpoolctl import threadpool_limits

    threadpool_limits(limits=int(os.environ["OPENBLAS_NUM_THREADS"]))

import pytest  # noqa: E402

REPO = Path(__file__).resolve().parents[2]
# The catheter recordings have no licence: read in place at run time, never copied.
REAL_CATHETER = Path(os.environ.get("PLAYSCOPE_REAL_DATA", REPO.parent / "shared" / "data" / "real")) / "catheter"


def pytest_configure(config):
    config.addinivalue_line(
        "markers", "slow: cannot be made small; left out of ./tools/run-tests.sh, run by "
        "./tools/run-tests.sh --all and bench/run_all.py (CONTRIBUTING.md)")


@pytest.fixture
def real_catheter_dir() -> Path:
    """Folder of the real catheter recordings; skips the test when they are absent."""
    if not (REAL_CATHETER / "data_2_1.txt").is_file():
        pytest.skip(f"real catheter data not found in {REAL_CATHETER}")
    return REAL_CATHETER
