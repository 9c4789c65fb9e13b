"""base.forkmap: the items' results in their order whichever process computed them, an item that
raised in the child raises here, and a child that dies leaves its items to this process. This
process's items sleep, so that the child (started first) surely takes some."""

import contextlib
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


@pytest.mark.parametrize("within", ["a map", "lockstep"])
def test_an_item_that_raises_here_stops_the_child_rather_than_awaiting_it(within):
    # the child's items take 3 s each, six of them: awaited, the call would last 9 s or more; within a
    # lockstep block, the same (the block's child stopped where the item raised)
    parent = os.getpid()

    def fn(x):
        if os.getpid() == parent:
            time.sleep(0.2)
            raise KeyError(x)
        time.sleep(3.0)
        return x

    t0 = time.monotonic()
    with pytest.raises(KeyError):
        with forkmap.lockstep() if within == "lockstep" else contextlib.nullcontext():
            forkmap.fork_map(fn, list(range(8)))
    assert time.monotonic() - t0 < 2.5


# --------------------------------------------------------------------------- lockstep
def _child_pid(out) -> set:
    return {p for _, p in out} - {os.getpid()}


def test_within_lockstep_both_sides_go_on_from_a_maps_results_to_the_next_one():
    # the second map's items are made from the first map's results: the child, which computed some
    # of each, must hold every result of the first to reach the same second map
    parent = os.getpid()

    def square(x):
        _slow_here(parent, 0.02)
        return x * x, os.getpid()

    with forkmap.lockstep():
        first = forkmap.fork_map(square, list(range(8)))
        second = forkmap.fork_map(square, [r + 1 for r, _ in first])
        if os.getpid() == parent:
            got = (first, second)
    first, second = got
    assert [r for r, _ in first] == [x * x for x in range(8)]
    assert [r for r, _ in second] == [(x * x + 1) ** 2 for x in range(8)]
    assert _child_pid(first) and _child_pid(second) and _child_pid(first) == _child_pid(second)  # one child, both maps


def test_a_lockstep_child_prints_nothing_and_is_gone_when_the_block_ends(capfd):
    parent = os.getpid()
    with forkmap.lockstep():
        print("in the block", flush=True)
        out = forkmap.fork_map(lambda x: (_slow_here(parent, 0.05), os.getpid())[1], list(range(6)))
    child = set(out) - {parent}
    assert len(child) == 1 and capfd.readouterr().out.count("in the block") == 1
    with pytest.raises(ChildProcessError):  # stopped and reaped
        os.waitpid(child.pop(), os.WNOHANG)


def test_a_lockstep_side_that_reaches_another_map_is_left_and_the_parent_computes_what_it_took():
    parent = os.getpid()

    def fn(x):
        _slow_here(parent, 0.05)
        return x + 1

    with forkmap.lockstep():
        # the child goes astray: another map, whose results taken for this one's would be 100 off
        items = list(range(6)) if os.getpid() == parent else [x + 100 for x in range(7)]
        out = forkmap.fork_map(fn, items)
        again = forkmap.fork_map(fn, items)  # alone now, or forked as outside the block
    assert out == again == [x + 1 for x in range(6)]


def test_a_lockstep_item_that_raises_in_the_child_is_computed_here():
    parent = os.getpid()

    def fn(x):
        _slow_here(parent, 0.05)
        if os.getpid() != parent:
            raise ArithmeticError("only in the child")
        return 2 * x

    with forkmap.lockstep():
        out = forkmap.fork_map(fn, list(range(6)))
    assert out == [2 * x for x in range(6)]


def test_lockstep_within_a_maps_item_forks_no_third_process():
    # an item's own maps run in turn where it is computed, so a block there would only burn a core
    def fn(x):
        with forkmap.lockstep():
            return forkmap._PEER is None

    assert all(forkmap.fork_map(fn, [1, 2, 3]))


def test_a_lockstep_child_dies_with_its_parent():
    # a calibration killed without a word leaves no child computing on: the block's child is
    # killed with its parent (here a forked stand-in for the calibrating process, killed mid-block)
    import signal

    r, w = os.pipe()
    stand_in = os.fork()
    if stand_in == 0:
        try:
            os.close(r)
            with forkmap.lockstep():
                if forkmap._PEER.role == "parent":
                    os.write(w, str(forkmap._PEER.pid).encode())
                time.sleep(30)
        finally:
            os._exit(0)
    os.close(w)
    child = int(os.read(r, 32))
    os.kill(stand_in, signal.SIGKILL)
    os.waitpid(stand_in, 0)
    def gone() -> bool:  # dead: reaped, or a zombie its new parent has not reaped yet
        try:
            with open(f"/proc/{child}/stat") as f:
                return f.read().rsplit(")", 1)[1].split()[0] in "ZX"
        except FileNotFoundError:
            return True

    for _ in range(100):
        if gone():
            break
        time.sleep(0.05)
    else:
        os.kill(child, signal.SIGKILL)
        pytest.fail(f"the block's child {child} outlived its parent")
