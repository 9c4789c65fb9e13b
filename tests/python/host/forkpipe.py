"""A stand-in for base.forkmap.fork_map in tests: every item as if the forked child had computed it."""


def through_the_pipe(fn, items, cost=None, pack=lambda r: r, unpack=lambda r: r):
    """base.forkmap.fork_map as if the forked child had computed every item: each result packed,
    pickled, unpickled and unpacked, as the pipe hands a child's result back."""
    import pickle

    return [unpack(pickle.loads(pickle.dumps(pack(fn(x))))) for x in items]


def in_a_child(fn, items, cost=None, pack=lambda r: r, unpack=lambda r: r):
    """base.forkmap.fork_map with a forked child computing every item on its own copy of the
    process (what fn changes there is not seen here), each result packed, sent through a pipe and
    unpacked here, as fork_map hands a child's result back. Errors: RuntimeError with the child's
    traceback when fn raised there, or when the child died without sending (never a hang)."""
    import multiprocessing
    import traceback

    ctx = multiprocessing.get_context("fork")
    recv, send = ctx.Pipe(duplex=False)

    def child():
        try:
            send.send([pack(fn(x)) for x in items])
        except Exception:
            send.send(traceback.format_exc())
        finally:
            send.close()

    p = ctx.Process(target=child)
    p.start()
    send.close()  # the child's end only: a child that dies leaves recv an EOF, not a wait
    try:
        out = recv.recv()
    except EOFError:
        out = "the child died without sending a result"
    p.join()
    if isinstance(out, str):
        raise RuntimeError(f"in the forked child: {out}")
    return [unpack(r) for r in out]
