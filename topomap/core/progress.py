"""Progress of the core's long loops, for whoever listens (the ``topomap`` command's bars).

The core never draws a bar: a loop calls :func:`report` after each of its steps, which does
nothing unless a listener was set with :func:`reporting` (a context variable, so nested or
concurrent fits do not mix).  A listener is called as ``listener(stage, done, total)``: ``stage``
names the loop (``"BIC"``, ``"EM"``, ``"held-out scoring"``), ``done`` counts its steps so far
and ``total`` is its most steps (None when unknown); a loop that ends early reports a last time
with ``done == total``.
"""

from __future__ import annotations

from contextlib import contextmanager
from contextvars import ContextVar
from typing import Callable, Optional

__all__ = ["reporting", "report"]

Listener = Callable[[str, int, Optional[int]], None]
_listener: ContextVar[Listener | None] = ContextVar("topomap_progress_listener", default=None)


@contextmanager
def reporting(listener: Listener | None):
    """Call ``listener`` with the progress of the core's loops inside the block."""
    token = _listener.set(listener)
    try:
        yield
    finally:
        _listener.reset(token)


def report(stage: str, done: int, total: int | None = None) -> None:
    """One more step of the loop ``stage``: ``done`` of at most ``total`` so far."""
    listener = _listener.get()
    if listener is not None:
        listener(stage, int(done), None if total is None else int(total))
