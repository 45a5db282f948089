"""Every signal handler of a run and of a sweep, in one place: Ctrl-C and SIGTERM end either
cleanly, and are held back while a few renames that must happen together are made.

The ``topomap`` command takes both signals once, at its start (:func:`take_interrupts`): each is
recorded and raised as :class:`Interrupted` (a :class:`KeyboardInterrupt`) wherever the program
stands.  Python cannot raise it everywhere: an exception raised inside a destructor or a weak
reference's callback -- matplotlib runs such callbacks while it draws -- is printed as
"Exception ignored in ..." and dropped.  The record stays, so :func:`stop_if_interrupted` raises
it again at the points a run or a sweep passes: before a run's files move into its folder (after
its figures are drawn), at the start and the end of every job, and when the sweep ends.

Once the command has taken the interrupt and is ending (:func:`ending`: writing the job's
``status.json``, the sweep's report), a second Ctrl-C -- people press it twice -- is recorded but
not raised, so that it cannot cut that short.
"""

from __future__ import annotations

import signal
import threading
from contextlib import contextmanager

__all__ = ["Interrupted", "INTERRUPTS", "take_interrupts", "give_back", "interrupted",
           "stop_if_interrupted", "ending", "held_signals"]

#: the signals that end a run or a sweep: Ctrl-C and a kill (SIGTERM)
INTERRUPTS = (signal.SIGINT, signal.SIGTERM)

#: the signals received since :func:`take_interrupts` (names, in order)
_received: list[str] = []
#: whether the command is ending after an interrupt (:func:`ending`)
_ending = [False]


class Interrupted(KeyboardInterrupt):
    """Ctrl-C or SIGTERM received: a run writes ``interrupted`` into its ``status.json``, a
    sweep its report (with the interrupted job and those that did not start), and the command
    ends with status 130."""


def _record(signum, frame):
    name = signal.Signals(signum).name
    _received.append(name)
    if not _ending[0]:
        raise Interrupted(f"signal {name}")


def take_interrupts() -> dict:
    """Make Ctrl-C and SIGTERM end the run or the sweep (recorded, and raised as
    :class:`Interrupted`), forgetting any earlier record.  Only the main thread takes signals:
    elsewhere nothing changes.  Returns the handlers replaced, for :func:`give_back`."""
    _received.clear()
    _ending[0] = False
    if threading.current_thread() is not threading.main_thread():
        return {}
    return {sig: signal.signal(sig, _record) for sig in INTERRUPTS}


def give_back(replaced: dict) -> None:
    """Put back the handlers :func:`take_interrupts` replaced, and forget the record."""
    for sig, handler in replaced.items():
        signal.signal(sig, handler)
    _received.clear()
    _ending[0] = False


def ending() -> None:
    """Say that the command is ending after an interrupt it took: from now on Ctrl-C and
    SIGTERM are recorded but not raised, so that a second one does not cut the ending short (a
    job's ``status.json``, the sweep's report)."""
    _ending[0] = True


def interrupted() -> str | None:
    """The name of the first signal received since :func:`take_interrupts` (``"SIGINT"``,
    ``"SIGTERM"``), None if none was."""
    return _received[0] if _received else None


def stop_if_interrupted() -> None:
    """Raise :class:`Interrupted` if a signal was received, even one whose exception Python
    dropped where it landed."""
    if _received:
        raise Interrupted(f"signal {_received[0]}")


@contextmanager
def held_signals():
    """Hold SIGINT and SIGTERM back inside (they are delivered on leaving): a few renames that
    must happen together are not cut in half by Ctrl-C or a kill."""
    old = signal.pthread_sigmask(signal.SIG_BLOCK, set(INTERRUPTS))
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)
