"""Ending a run cleanly: SIGTERM taken as Ctrl-C, and signals held back while a few renames
that must happen together are made."""

from __future__ import annotations

import signal
from contextlib import contextmanager

__all__ = ["interrupt_on_sigterm", "held_signals"]


def interrupt_on_sigterm() -> None:
    """Make SIGTERM end the process as Ctrl-C does (a :class:`KeyboardInterrupt`), so that a
    killed run or sweep ends as cleanly as an interrupted one."""

    def handler(signum, frame):
        raise KeyboardInterrupt(f"signal {signal.Signals(signum).name}")

    signal.signal(signal.SIGTERM, handler)


@contextmanager
def held_signals():
    """Hold SIGINT and SIGTERM back inside (they are delivered on leaving): a few renames that
    must happen together are not cut in half by Ctrl-C or a kill."""
    sigs = {signal.SIGINT, signal.SIGTERM}
    old = signal.pthread_sigmask(signal.SIG_BLOCK, sigs)
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)
