"""The robot route on a robot's log WITHOUT odometry: its odometry read from its scans
(``MotionSettings(scan_odometry=True)``, the default; docs/robot-logs.md).

A log of egocentric range scans and turn commands given no odometry is recognised
(:func:`is_scan_log`: one episode, no GDS, a ring of beams a row, and either the continuous path
learned no odometry from its commands -- they move a robot differently with its heading -- or
it kept the view clusters where the scans turn as the commands say, :func:`scan_turn_share`:
0.25-0.33 on turn commands, 0.0002-0.002 on compass walkers, whose scans never turn).  Its
odometry is then read from the scans (:func:`~.registration.scan_odometry`, point-to-line ICP
against keyframes) and closed by loops (:func:`~.registration.scan_poses`; its headings, closed
already, are not solved again),
and the robot route (:func:`~.robot_fit.fit_robot`) learns on those poses behind the guards of a
log with odometry (point symmetry -- a cell's reflection matched within
:data:`~.symmetry.SCAN_REACH` spacings, as this odometry's maps bend by centimetres --, unwalked
floor, the held-out check, whose held-out steps are placed by their unclosed registration).
Where a guard fails the map is the view clusters the log got before, with the warning and the
reason.  ``predict`` without odometry places a new walk by its own registration closed by its
own loops (:func:`walk_odometry`; the check's verdicts are the same placed either way on
five walks that reach it, benchmarks/notes/robots.md).

Measured (``benchmarks/notes/robots.md``, 2026-12-03; 12 walks of four 1 m plans and the three
of ``robot_office@0.3333``): never above K-means on the views (the guards send 4 walks of 15
back), 0.09-0.36x its error on the 11 where the route is taken; the fit 8-9x as long as with
the setting off (20.2 s for 18,000 steps against 3.7 s, load 1.0-1.3; the scans read on a
thread of their own beside the view clusters, :func:`early_scan_reading`).
"""

from __future__ import annotations

import threading
import time
from concurrent.futures import Future
from contextlib import nullcontext

import numpy as np

from .commands import MIN_TURN_SHARE, turn_share
from .registration import scan_odometry, scan_poses
from .robot_fit import MIN_BEAMS, fit_robot
from .scans import despike, loop_closures, scan_turns

__all__ = ["is_scan_log", "scan_turn_share", "fit_scan_robot", "walk_odometry",
           "closed_odometry", "read_scans", "early_scan_reading", "ScanReading", "SOURCE"]

#: ``motion_info_["odometry_from"]`` of a map whose odometry was read from its scans
SOURCE = "scans"


def scan_turn_share(X, u) -> float:
    """The share (0-1) of the variance of a walk's per-step turns read off its scans ``X`` (T,
    beams; :func:`~.scans.scan_turns` of consecutive despiked scans) that its commands ``u``
    explain (:func:`~.commands.turn_share`, as for a given odometry's turns): 0.25 on
    ``robot_office@0.3333`` seed 0's turn commands, 0 where the scans never turn."""
    Xd = despike(np.asarray(X, dtype=np.float64))
    heading = np.cumsum(np.r_[0.0, scan_turns(Xd[:-1], Xd[1:])])
    return turn_share(np.column_stack([np.zeros((len(heading), 2)), heading]), u)


def is_scan_log(data, odometry, info: dict) -> bool:
    """Whether a continuous log is a robot's log of range scans and turn commands without
    odometry: none given, one episode, no GDS, :data:`~.robot_fit.MIN_BEAMS` beams or more a
    row, non-negative readings, and either no odometry learned from its actions by the
    continuous path (``info["odometry"]`` False) or the view clusters chosen there
    (``info["chosen"]``) where its scans turn as its commands say (:func:`scan_turn_share` at
    least :data:`~.commands.MIN_TURN_SHARE`: a robot whose commands' displacements the
    continuous path read off one part of the log but not another)."""
    if not _scan_shaped(data, odometry):
        return False
    if info.get("odometry") is False:
        return True
    return info.get("chosen") == "views" and scan_turn_share(data.X, data.u) >= MIN_TURN_SHARE


def _scan_shaped(data, odometry) -> bool:
    """Whether ``data`` could be a robot's scans without odometry (:func:`is_scan_log`'s shape):
    no odometry, one episode, no GDS, a ring of beams a row, non-negative readings."""
    return (odometry is None and len(data.lengths) == 1 and not np.any(data.gds >= 0)
            and data.X.shape[1] >= MIN_BEAMS and bool(np.all(data.X >= 0)))


class ScanReading:
    """The odometry of a walk's scans read on a thread of its own (:func:`read_scans`), so that
    it runs beside what the continuous path does meanwhile; called: waits for ``(raw, poses)``.
    Leaving its ``with`` block stops it where it has not finished (its result unused)."""

    def __init__(self, X):
        self._stop = threading.Event()
        self._done = _started(lambda: read_scans(X, self._stop.is_set), "topomap-scans")

    def __call__(self) -> tuple[np.ndarray, np.ndarray]:
        return self._done()

    def __enter__(self) -> ScanReading:
        return self

    def __exit__(self, *exc) -> None:
        self._stop.set()


def early_scan_reading(settings, data, odometry):
    """Where a continuous log may take the robot route on odometry read from its scans
    (``settings.scan_odometry``, :func:`is_scan_log`'s shape, its scans turning as its commands
    say: :func:`scan_turn_share` at least :data:`~.commands.MIN_TURN_SHARE`, 0.036 s on 18,000
    scans of 60 beams), a :class:`ScanReading` of its scans started beside the view clusters;
    else a ``with`` block that gives None.  The same poses as read in turn."""
    if (settings.scan_odometry and _scan_shaped(data, odometry)
            and scan_turn_share(data.X, data.u) >= MIN_TURN_SHARE):
        return ScanReading(data.X)
    return nullcontext()


def read_scans(X, stop=None) -> tuple[np.ndarray, np.ndarray] | None:
    """``(raw, poses)`` of one walk's scans ``X`` (T, B): its registration
    (:func:`~.registration.scan_odometry`) and that closed by its loops
    (:func:`~.registration.scan_poses`), the candidate closures searched on a thread of their
    own beside the registration (1.8 s on a 2-hour walk of 73,000 scans, which the closing
    would otherwise wait for with a core idle); None where ``stop()`` turned true on the way."""
    closures = _started(lambda: loop_closures(despike(X)), "topomap-closures")
    alternatives: list = []
    raw = scan_odometry(X, alternatives=alternatives, stop=stop)
    if raw is None:
        return None
    return raw, scan_poses(X, odometry=raw, alternatives=alternatives, closures=closures())


def _started(fn, name: str):
    """``fn()`` started on a new daemon thread called ``name``; returns a function without
    arguments that waits for its result and returns it (or raises what ``fn`` raised)."""
    done = Future()

    def run():
        try:
            done.set_result(fn())
        except BaseException as error:  # noqa: BLE001 -- raised again where the result is asked
            done.set_exception(error)

    threading.Thread(target=run, name=name, daemon=True).start()
    return done.result


def fit_scan_robot(learner, data, settings, fallback, start: float | None = None,
                   reading: ScanReading | None = None) -> bool:
    """:func:`~.robot_fit.fit_robot` with ``mode="auto"``'s guards on the log's odometry read
    from its scans (closed by loops; the held-out check places by the unclosed registration);
    ``fallback`` as there; ``motion_info_["odometry_from"]`` is :data:`SOURCE` (the seconds
    go to ``timings_["places"]``, as the route's); ``reading``: the scans read already
    (:func:`early_scan_reading`; None: read here)."""
    start = time.perf_counter() if start is None else start
    raw, poses = read_scans(data.X) if reading is None else reading()
    views, info, build = fallback
    return fit_robot(learner, data, settings, poses, (views, {**info, "odometry_from": SOURCE},
                                                      build), start=start, place_odometry=raw,
                     headings=poses[:, 2])


def closed_odometry(X) -> np.ndarray:
    """(T, 3) poses of one walk's scans ``X`` (T, B): its registration
    (:func:`~.registration.scan_odometry`) closed by the walk's own loops
    (:func:`~.registration.scan_poses`), as the map's walk was.  A stretch of poor
    registrations bends the unclosed odometry by centimetres over a few seconds, and the
    decoder, which follows the odometry's moves, then carries the walk into the alike room beside
    (``robot_three@0.3333`` seed 1: 31 % of the held-out walk in the wrong room by the unclosed
    registration, 9 % closed, as by the true poses)."""
    return read_scans(X)[1]


def walk_odometry(X, lengths) -> np.ndarray:
    """(T, 3) odometry of a new walk's scans ``X`` (T, B), each episode of ``lengths`` read from
    its own scans and closed by its own loops (:func:`closed_odometry`)."""
    ends = np.cumsum(lengths)
    return np.concatenate([closed_odometry(X[a:b]) for a, b in zip(ends - lengths, ends)])
