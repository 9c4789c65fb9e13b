"""base.forkmap: the items' results in their order whichever process computed them, an item that
raised in the child raises here, and a child that dies leaves its items to this process. This
process's items sleep, so that the child (started first) surely takes some."""

import os
import time

import pytest

from playscope.base import forkmap

pytestmark = pytest.mark.skipif(not forkmap.can_fork(), reason="needs Linux and two cores")


def _slow_here(parent: int, s: float = 0.05) -> None:
    if os.getpid() == parent:
        time.sleep(s)


def test_results_come_in_the_items_order_from_both_processes():
    parent = os.getpid()

    def fn(x):
        _slow_here(parent)
        return x * x, os.getpid()

    out = forkmap.fork_map(fn, list(range(12)), cost=lambda x: x % 5)
    assert [r for r, _ in out] == [x * x for x in range(12)]
    assert {p for _, p in out} - {parent}  # the child computed some


def test_an_item_that_raises_in_the_child_raises_here_with_its_traceback():
    parent = os.getpid()

    def fn(x):
        _slow_here(parent, 0.3)
        if os.getpid() != parent:
            raise ArithmeticError(f"item {x} in the child")
        return x

    with pytest.raises(RuntimeError, match="ArithmeticError: item . in the child"):
        forkmap.fork_map(fn, [1, 2, 3])


def test_a_child_that_dies_leaves_its_items_to_this_process():
    parent = os.getpid()

    def fn(x):
        _slow_here(parent)
        if os.getpid() != parent:
            os._exit(3)  # the child dies without a word
        return x + 1

    assert forkmap.fork_map(fn, [1, 2, 3, 4]) == [2, 3, 4, 5]


def test_pack_runs_in_the_child_and_unpack_here():
    parent = os.getpid()

    def fn(x):
        _slow_here(parent)
        return [x]

    out = forkmap.fork_map(fn, list(range(6)), pack=lambda r: r + ["packed"],
                           unpack=lambda r: r + ["unpacked"])
    assert [r[0] for r in out] == list(range(6))
    assert all(r[1:] in ([], ["packed", "unpacked"]) for r in out) and any(r[1:] for r in out)


def test_an_item_that_raises_here_stops_the_child_rather_than_awaiting_it():
    # the child's items take 3 s each, six of them: awaited, the call would last 9 s or more
    parent = os.getpid()

    def fn(x):
        if os.getpid() == parent:
            time.sleep(0.2)
            raise KeyError(x)
        time.sleep(3.0)
        return x

    t0 = time.monotonic()
    with pytest.raises(KeyError):
        forkmap.fork_map(fn, list(range(8)))
    assert time.monotonic() - t0 < 2.5
