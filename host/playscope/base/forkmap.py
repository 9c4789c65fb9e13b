"""[fn(x) for x in items] on two cores: a forked child and this process each take the next item
until none is left. For the calibration's independent fits (the record model's starts and terms,
the model choice per B alternative), which take 0.1 to 7 s each and cannot be sized in advance.

Why fork and one child: the machines this runs on have two cores or more, the items share large
read-only arrays (a 1 kHz grid) that a forked child sees without copying, and the results are
few. Why taken and not split beforehand: the record model's term search on the 3-minute bench
record gave its first half 11 of 16 s, so the halves' split saved nothing.

The child is forked before this process computes anything, so an item never sees what another's
computation left in shared objects (each fn must be a function of its item alone; the callers'
tests check the result bit for bit against the items run in turn). A child that dies leaves its
items to this process; an item that raised in the child raises here; when one raises here, the
child is stopped rather than awaited.

Within `lockstep` (the calibration's), the child is forked once, for the whole block, rather than
once a map: both processes run the block's code, each item of a map is computed by the one that
takes it, and at the map's end each hands the other its results, so both go on from the same
results. Why: a fork costs more than its system call. The child's first evaluations after it ran
2-6 times slower (8.3 and 4.5 ms, then 1.5 ms, on the bench record; the copy-on-write of the pages
it writes and its idle core are the likely causes, not measured apart), which on the bench session
was 50-90 ms more in the child's first item of every map; a fork_map of items that do nothing took
35-40 ms.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import os
import signal
import sys
import traceback
from typing import Callable, Sequence


def can_fork() -> bool:
    """Whether a child may compute beside this process: on Linux, with two or more cores to run
    on, and not from a daemonic process (which may have no children)."""
    if not sys.platform.startswith("linux") or multiprocessing.current_process().daemon:
        return False
    return len(os.sched_getaffinity(0)) >= 2


def _take(order: list, nxt):
    """The items' indices in order, each taken once between the processes sharing the counter nxt."""
    while True:
        with nxt.get_lock():
            k = nxt.value
            nxt.value += 1
        if k >= len(order):
            return
        yield order[k]


def _child(fn, items, order, nxt, pack, conn) -> None:
    """In the forked child: fn on the items it takes, on one BLAS thread; sends {index: pack(result)},
    or the traceback (str) when fn raised."""
    from threadpoolctl import threadpool_limits

    try:
        with threadpool_limits(1):
            done = {i: pack(fn(items[i])) for i in _take(order, nxt)}
        conn.send(done)
    except Exception:
        conn.send(traceback.format_exc())
    finally:
        conn.close()


def _same(x):
    return x


def _order(items: Sequence, cost: Callable | None) -> list:
    """The items' indices, the costly first by cost(item) (ties, and cost None: in order)."""
    order = list(range(len(items)))
    if cost is not None:
        c = [cost(x) for x in items]
        order.sort(key=lambda i: -c[i])
    return order


def fork_map(fn: Callable, items: Sequence, cost: Callable | None = None, pack: Callable = _same,
             unpack: Callable = _same) -> list:
    """[fn(x) for x in items], in the items' order, shared with a forked child when `can_fork`
    (else in turn); within `lockstep`, with its child. cost(item): a relative cost, the costly
    items taken first (None: in order); pack(result) before the pipe (in the process that computed
    it; it must not change the result itself, which that process keeps within `lockstep`) and
    unpack(result) after it, for results whose bulk is cheaper to recompute than to send. Errors:
    RuntimeError with the child's traceback when fn raised there; fn's own errors here."""
    global _IN_ITEM
    peer = _PEER
    if _IN_ITEM or len(items) < 2:
        return [fn(x) for x in items]  # an item's own map, in the process computing it; or one item (in both sides)
    if peer is not None and peer.alive:
        return peer.map(fn, items, cost, pack, unpack)
    if not can_fork():
        return [fn(x) for x in items]
    ctx = multiprocessing.get_context("fork")
    order = _order(items, cost)
    nxt = ctx.Value("l", 0)
    recv, send = ctx.Pipe(duplex=False)
    child = ctx.Process(target=_child, args=(fn, items, order, nxt, pack, send), daemon=True)
    child.start()
    send.close()
    out: list = [None] * len(items)
    got = [False] * len(items)
    try:
        _IN_ITEM = True
        try:
            for i in _take(order, nxt):
                out[i], got[i] = fn(items[i]), True
        finally:
            _IN_ITEM = False
        try:
            done = recv.recv()
        except EOFError:  # the child died: its items are computed below
            done = {}
    except BaseException:  # fn raised here, or an interrupt: the child's work is moot, not awaited
        child.terminate()
        raise
    finally:
        recv.close()
        child.join()
    if isinstance(done, str):
        raise RuntimeError(f"a computation in the forked child raised:\n{done}")
    for i, r in done.items():
        out[i], got[i] = unpack(r), True
    return [r if ok else fn(x) for r, ok, x in zip(out, got, items)]


# --------------------------------------------------------------------------- lockstep
_SLOTS = 4096  # the maps a lockstep block shares (a counter each); later maps run in turn in both processes
_PEER: "_Peer | None" = None  # this process's side of the lockstep block it is in, if any
_IN_ITEM = False  # this process is computing an item of a map: a map within it runs in turn (not a third process)


class _Peer:
    """One side of a `lockstep` block: role "parent" or "child", the duplex pipe to the other side,
    the per-map counters (shared memory) and their lock, the maps so far, whether the other side is
    still there, and the child's pid (the parent's side)."""

    def __init__(self, role: str, conn, counts, lock, pid: int = 0):
        self.role, self.conn, self.counts, self.lock, self.pid = role, conn, counts, lock, pid
        self.maps, self.alive = 0, True

    def _take(self, slot: int, order: list):
        while True:
            with self.lock:
                k = self.counts[slot]
                self.counts[slot] = k + 1
            if k >= len(order):
                return
            yield order[k]

    def map(self, fn, items, cost, pack, unpack) -> list:
        """fork_map within the block: each item computed by the side that takes it, the results swapped."""
        k = self.maps
        self.maps += 1
        if k >= _SLOTS:
            return [fn(x) for x in items]
        global _IN_ITEM
        mine = {}
        _IN_ITEM = True
        try:
            for i in self._take(k, _order(items, cost)):
                mine[i] = fn(items[i])
        except BaseException:
            self.leave()  # the child leaves; the parent stops it and raises as fn did
            raise
        finally:
            _IN_ITEM = False
        theirs = self._swap((k, len(items), getattr(fn, "__qualname__", "")), {i: pack(r) for i, r in mine.items()})
        out = [None] * len(items)
        got = [False] * len(items)
        for i, r in mine.items():
            out[i], got[i] = r, True
        for i, r in theirs.items():
            out[i], got[i] = unpack(r), True
        return [r if ok else fn(x) for r, ok, x in zip(out, got, items)]  # what the other side took and never sent

    def _swap(self, tag: tuple, payload: dict) -> dict:
        """Hand the other side this map's results and take its own: {index: packed result}; {} when
        it is gone or its map was not this one (tag: the map's number, size and function), after which
        the parent goes on alone and the child leaves."""
        try:
            if self.role == "child":
                self.conn.send((tag, payload))
                got = self.conn.recv()
            else:
                got = self.conn.recv()
        except Exception:  # EOF: the other side is gone (or a result that does not pickle)
            self.leave()
            return {}
        if got[0] != tag:
            self.leave()
            return {}
        if self.role == "parent":
            try:
                self.conn.send((tag, payload))
            except Exception:  # a result of this side's that does not pickle: the child leaves, its own kept
                self.leave()
        return got[1]

    def leave(self) -> None:
        """The child exits at once; the parent stops and reaps it and goes on alone (its maps then
        forked each, as outside the block)."""
        if self.role == "child":
            os._exit(0)
        if self.alive:
            self.alive = False
            self.conn.close()
            with contextlib.suppress(ProcessLookupError):
                os.kill(self.pid, signal.SIGKILL)
            with contextlib.suppress(ChildProcessError):
                os.waitpid(self.pid, 0)


def _die_with(parent: int) -> None:
    """In a lockstep child: be killed when the parent dies (Linux's PR_SET_PDEATHSIG), so that a child
    never outlives its calibration, even one killed without a word; exits at once when the parent is
    already gone."""
    import ctypes

    with contextlib.suppress(OSError, AttributeError):
        ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGKILL, 0, 0, 0)  # 1: PR_SET_PDEATHSIG
    if os.getppid() != parent:
        os._exit(0)


@contextlib.contextmanager
def lockstep():
    """Run the block in this process and in one forked child at once, its fork_maps shared between
    the two (module doc): the child is forked on entry, runs the block's code as this process does,
    with no output of its own (its stdout and stderr to /dev/null, no stage sink, no warnings), and
    exits where the block ends; this process stops it there (and were this process killed, the child
    dies with it, `_die_with`). A no-op when `can_fork` says no, within
    another block, or within a map's item (whose own maps run in turn).

    The block's code must be a function of its inputs and of the maps' results alone, as a map's
    items must be of their item alone: the two sides then reach the same maps with the same items.
    A side that reaches another map (its number, size or function differ) or finds the other gone is
    left: the parent computes what the child took, and goes on alone. An item that raises ends the
    child; in the parent it raises as fn's own error."""
    global _PEER
    if _PEER is not None or _IN_ITEM or not can_fork():
        yield
        return
    ctx = multiprocessing.get_context("fork")
    here, there = ctx.Pipe(duplex=True)
    counts, lock = ctx.RawArray("q", _SLOTS), ctx.Lock()
    sys.stdout.flush()
    sys.stderr.flush()
    parent = os.getpid()
    pid = os.fork()
    if pid == 0:  # the child: the block, quietly, then out
        code = 1
        try:
            _die_with(parent)
            here.close()
            null = os.open(os.devnull, os.O_WRONLY)
            os.dup2(null, 1)
            os.dup2(null, 2)
            sys.stdout = sys.stderr = open(os.devnull, "w")  # also where these had been set elsewhere
            import warnings

            from .stage import _SINK
            warnings.simplefilter("ignore")
            _SINK.set(None)
            _PEER = _Peer("child", there, counts, lock)
            yield
            code = 0
        finally:
            os._exit(code)
    there.close()
    _PEER = peer = _Peer("parent", here, counts, lock, pid)
    try:
        yield
    finally:
        _PEER = None
        peer.leave()
