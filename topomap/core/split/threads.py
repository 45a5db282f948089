"""Compiled kernels run on threads: calls that release the GIL spread over a pool of
``NUMBA_NUM_THREADS`` threads, their results returned in call order, so that what is computed
is the same whatever the number of threads (one thread: the calls run one after the other).

The pool is made on first use and kept (a process forked from this one makes its own).
Python threads, not ``numba.prange``: numba's OpenMP layer spins its threads while they wait,
which made the split's passes several times slower when other processes kept the cores busy.
"""

from __future__ import annotations

import os
from concurrent.futures import Future, ThreadPoolExecutor

import numba
import numpy as np

__all__ = ["CHUNK", "THREAD_STEPS", "n_threads", "in_threads", "rows_in_threads", "beside",
           "pieces"]

#: steps per piece of a pass cut into pieces (a fixed size: the pieces are the same whatever the
#: number of threads)
CHUNK = 1 << 14
#: the fewest steps work must cover to go to threads (:func:`in_threads`, :func:`beside`):
#: below, handing it over cost more than it saved (fits of 10,000 steps were up to 10 % slower)
THREAD_STEPS = CHUNK

_POOLS: dict[int, ThreadPoolExecutor] = {}
os.register_at_fork(after_in_child=_POOLS.clear)


def n_threads() -> int:
    """The threads compiled work may use: numba's ``NUMBA_NUM_THREADS`` (by default the CPUs)."""
    return max(1, int(numba.config.NUMBA_NUM_THREADS))


def _pool(n: int) -> ThreadPoolExecutor:
    pool = _POOLS.get(n)
    if pool is None:
        pool = _POOLS[n] = ThreadPoolExecutor(n, thread_name_prefix="topomap")
    return pool


def in_threads(fn, items, steps: int | None = None) -> list:
    """``[fn(i) for i in items]``, the calls spread over :func:`n_threads` threads (``fn``
    should spend its time in compiled code that releases the GIL); in turn on the calling
    thread where the calls cover fewer than :data:`THREAD_STEPS` ``steps`` in all."""
    items = list(items)
    n = min(n_threads(), len(items))
    if n < 2 or (steps is not None and steps < THREAD_STEPS):
        return [fn(i) for i in items]
    return list(_pool(n).map(fn, items))


def rows_in_threads(fn, shared: tuple, *arrays) -> tuple:
    """``fn(*shared, *arrays)`` for an ``fn`` that treats each row of ``arrays`` apart and
    returns a tuple of arrays a row each (compiled code that releases the GIL): the rows cut
    into :func:`n_threads` pieces of consecutive rows, each piece's call on a thread
    (:func:`in_threads`), the pieces' results joined -- the same arrays as one call."""
    cuts = np.array_split(np.arange(len(arrays[0])), n_threads())
    parts = in_threads(lambda rows: fn(*shared, *(a[rows] for a in arrays)), cuts)
    return tuple(np.concatenate(piece) for piece in zip(*parts))


def beside(fn, *args, steps: int | None = None):
    """Start ``fn(*args)`` on a thread of the pool, so that the calling thread goes on with
    other work; returns a function without arguments that waits for the result and returns it
    (or raises what ``fn`` raised).  On one thread, or where the work covers fewer than
    :data:`THREAD_STEPS` ``steps`` (too little to pay for handing it over), ``fn`` runs at
    once, in this call (what it raises is raised by the function returned, as with threads)."""
    if n_threads() >= 2 and (steps is None or steps >= THREAD_STEPS):
        return _pool(n_threads()).submit(fn, *args).result
    done = Future()
    try:
        done.set_result(fn(*args))
    except Exception as error:  # noqa: BLE001 -- handed to the caller, as a thread's would be
        done.set_exception(error)
    return done.result


def pieces(n: int, chunk: int = CHUNK) -> list[slice]:
    """``range(n)`` cut into slices of ``chunk`` (the last one shorter)."""
    return [slice(lo, min(lo + chunk, n)) for lo in range(0, n, chunk)]
