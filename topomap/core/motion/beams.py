"""Which way a robot's range beams go round, and which of them looks ahead, read from its log.

The robot route (:mod:`topomap.core.motion.robot`) reads each row of scans as a ring of ``B``
beams, beam ``k`` at ``2 pi k / B`` anticlockwise from the robot's heading.  Range finders do
not all number their beams that way: a ``sensor_msgs/LaserScan`` often starts at ``angle_min =
-pi`` (beam 0 looks back), and a sensor or simulator may number its beams clockwise.  Fed such
scans, the route turned each scan the wrong way into the map frame or projected its beams
behind the robot, and the log got the view clusters (``robot_alike@0.3333`` seed 0 with the
beams reversed or starting at ``-pi``: 0.645 m from the truth against 0.084 m with the beams as
the route reads them; ``benchmarks/notes/robots.md``).

:func:`beam_order` reads both from the log and its wheel odometry:

* **the direction**: scans turn against their beams' numbering when the robot turns, so the
  turn read from consecutive scans (:func:`~.scans.scan_turns`, which assumes anticlockwise
  beams) agrees in sign with the odometry's turn where the beams go anticlockwise and opposes it
  where they go clockwise;
* **the front**: driving straight ahead ``d`` metres shortens the range of a beam at angle
  ``phi`` from the heading by about ``d cos(phi)``, so the first Fourier harmonic of each
  beam's median range change per metre points at the beam that looks ahead.

It gives the column order that brings the scans to the route's numbering, or None where they
have it already (the scans are then used as they are: the same numbers as without this step).
"""

from __future__ import annotations

import numpy as np

from . import scans as S

__all__ = ["beam_order", "in_route_frame", "described", "MIN_TURN_AGREEMENT", "MIN_FRONT_STRENGTH",
           "MIN_FORWARD_M", "MAX_STRAIGHT_TURN"]

#: the least correlation (absolute) between the scans' and the odometry's per-step turns for
#: the beams' direction to be read from it (correlation): 0.86 on the benchmark's robots
#: (``robot_alike``, ``robot_office`` at a third of their size), -0.86 with their beams
#: reversed; below this the beams are taken as anticlockwise
MIN_TURN_AGREEMENT = 0.3
#: the least strength of the range changes' first harmonic, as a share of a pure ``-cos``
#: (share), for the front beam to be read from it: 0.99-1.00 on the benchmark's robots; below
#: this beam 0 is taken as the front
MIN_FRONT_STRENGTH = 0.3
#: a step counts as driving ahead where the odometry moved it at least this far along its
#: heading (m): a hundredth of a robot's 0.01 m step at 0.1 m/s and 10 Hz
MIN_FORWARD_M = 1e-4
#: ... and turned it by at most this much (rad): the ranges of a turning robot change with the
#: turn, not the travel
MAX_STRAIGHT_TURN = 0.05


def _wrap(a):
    return (a + np.pi) % (2 * np.pi) - np.pi


def _clockwise(D, heading) -> bool:
    """Whether the beams of the despiked scans ``D`` go clockwise: the scans' turns oppose
    the odometry's ``heading`` turns (correlation at most ``-MIN_TURN_AGREEMENT``)."""
    turns = S.scan_turns(D[:-1], D[1:])
    dh = _wrap(np.diff(heading))
    norm = float(np.sqrt(np.sum(turns ** 2) * np.sum(dh ** 2)))
    return norm > 0 and float(np.sum(turns * dh)) / norm <= -MIN_TURN_AGREEMENT


def _front(D, odometry) -> int:
    """The beam of the anticlockwise despiked scans ``D`` that looks ahead (0 where the range
    changes of straight drives do not show it)."""
    B = D.shape[1]
    step = np.diff(odometry[:, :2], axis=0)
    h = odometry[:-1, 2]
    ahead = step[:, 0] * np.cos(h) + step[:, 1] * np.sin(h)
    straight = (ahead >= MIN_FORWARD_M) & (np.abs(_wrap(np.diff(odometry[:, 2])))
                                          <= MAX_STRAIGHT_TURN)
    if not straight.any():
        return 0
    change = np.median((D[1:][straight] - D[:-1][straight]) / ahead[straight, None], axis=0)
    # change_k ~ -cos(theta_k - phi): its harmonic sum(change e^{-i theta}) is -(B/2) e^{-i phi}
    harmonic = np.sum(change * np.exp(-2j * np.pi * np.arange(B) / B))
    if abs(harmonic) < MIN_FRONT_STRENGTH * B / 2:
        return 0
    return int(np.round(-np.angle(-harmonic) * B / (2 * np.pi))) % B


def beam_order(X, odometry) -> np.ndarray | None:
    """(B,) the column order that numbers the beams of the scans ``X`` (T, B) [m] as the robot
    route reads them (beam 0 ahead, anticlockwise), read from the log with its wheel
    ``odometry`` (T, 3: x [m], y [m], heading [rad]) -- or None where ``X`` numbers them so
    already."""
    X = np.asarray(X, dtype=np.float64)
    O = np.asarray(odometry, dtype=np.float64)
    if len(X) < 2:
        return None
    D = S.despike(X)
    order = np.arange(X.shape[1])
    if _clockwise(D, O[:, 2]):
        order, D = order[::-1], D[:, ::-1]
    order = np.roll(order, -_front(D, O))
    return None if np.array_equal(order, np.arange(X.shape[1])) else order


def in_route_frame(X, order):
    """The scans ``X`` (T, B) with their columns in ``order`` (None: ``X`` itself)."""
    return X if order is None else np.asarray(X)[:, order]


def described(order) -> dict:
    """What a :func:`beam_order` says of the scans as they come: ``{"ahead": the column that
    looks ahead, "clockwise": whether the columns go clockwise}``."""
    order = np.asarray(order)
    B = order.size
    return {"ahead": int(order[0]), "clockwise": bool(B > 2 and order[1] == (order[0] - 1) % B)}
