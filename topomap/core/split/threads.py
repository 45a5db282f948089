"""Compiled kernels run on threads: calls that release the GIL spread over a pool of
``NUMBA_NUM_THREADS`` threads, their results returned in call order, so that what is computed
is the same whatever the number of threads (one thread: the calls run one after the other).

The pool is made on first use and kept (a process forked from this one makes its own).
Python threads, not ``numba.prange``: numba's OpenMP layer spins its threads while they wait,
which made the split's passes several times slower when other processes kept the cores busy.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import os
from concurrent.futures import ThreadPoolExecutor

import numba

__all__ = ["CHUNK", "n_threads", "in_threads", "pieces"]

#: steps per piece of a pass cut into pieces (a fixed size: the pieces are the same whatever the
#: number of threads)
CHUNK = 1 << 14

_POOLS: dict[int, ThreadPoolExecutor] = {}
os.register_at_fork(after_in_child=_POOLS.clear)


def _trimmer():
    """glibc's ``malloc_trim`` (None elsewhere): each thread allocates from a heap of its own,
    which keeps the memory freed in it; trimmed after every batch, the threads' heaps do not add
    up (the 1e7-step fit's peak memory stays that of one thread)."""
    try:
        return ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6").malloc_trim
    except (OSError, AttributeError):
        return None


_TRIM = _trimmer()


def n_threads() -> int:
    """The threads compiled work may use: numba's ``NUMBA_NUM_THREADS`` (by default the CPUs)."""
    return max(1, int(numba.config.NUMBA_NUM_THREADS))


def in_threads(fn, items) -> list:
    """``[fn(i) for i in items]``, the calls spread over :func:`n_threads` threads (``fn``
    should spend its time in compiled code that releases the GIL)."""
    items = list(items)
    n = min(n_threads(), len(items))
    if n < 2:
        return [fn(i) for i in items]
    pool = _POOLS.get(n)
    if pool is None:
        pool = _POOLS[n] = ThreadPoolExecutor(n, thread_name_prefix="topomap")
    done = list(pool.map(fn, items))
    if _TRIM is not None:
        _TRIM(0)
    return done


def pieces(n: int, chunk: int = CHUNK) -> list[slice]:
    """``range(n)`` cut into slices of ``chunk`` (the last one shorter)."""
    return [slice(lo, min(lo + chunk, n)) for lo in range(0, n, chunk)]
