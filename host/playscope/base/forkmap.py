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
"""

from __future__ import annotations

import multiprocessing
import os
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


def fork_map(fn: Callable, items: Sequence, cost: Callable | None = None, pack: Callable = _same,
             unpack: Callable = _same) -> list:
    """[fn(x) for x in items], in the items' order, shared with a forked child when `can_fork`
    (else in turn). cost(item): a relative cost, the costly items taken first (None: in order);
    pack(result) in the child before the pipe and unpack(result) here after it, for results whose
    bulk is cheaper to recompute than to send. Errors: RuntimeError with the child's traceback
    when fn raised there; fn's own errors here."""
    if len(items) < 2 or not can_fork():
        return [fn(x) for x in items]
    ctx = multiprocessing.get_context("fork")
    order = list(range(len(items)))
    if cost is not None:
        c = [cost(x) for x in items]
        order.sort(key=lambda i: -c[i])
    nxt = ctx.Value("l", 0)
    recv, send = ctx.Pipe(duplex=False)
    child = ctx.Process(target=_child, args=(fn, items, order, nxt, pack, send), daemon=True)
    child.start()
    send.close()
    out: list = [None] * len(items)
    got = [False] * len(items)
    try:
        for i in _take(order, nxt):
            out[i], got[i] = fn(items[i]), True
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
