"""Fixtures shared by the host test modules."""

from __future__ import annotations

import fcntl

import pytest

from .goodfiles import good_paths, make_good


@pytest.fixture(scope="session")
def good(request, tmp_path_factory):
    """goodfiles.make_good's valid inputs (a 138-s angle session, its calibration, table and CSV),
    made once per run and shared by every module that damages copies of them (test_output_guard,
    test_malformed_corpus, test_table_plausibility): one calibration of ~7 s instead of one per
    module. Under pytest-xdist the workers share one copy, made by the first to ask, under a file
    lock, in the run's temporary folder common to the workers. Tests read these files or copy
    them (copy_good), never change them."""
    if not hasattr(request.config, "workerinput"):  # not an xdist worker
        return make_good(tmp_path_factory.mktemp("good"))
    shared = tmp_path_factory.getbasetemp().parent  # pytest-of-USER/pytest-N: this run's, all workers
    root = shared / "good"
    with open(shared / "good.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not (shared / "good.done").is_file():
            make_good(root)
            (shared / "good.done").write_text("")
    return good_paths(root)
