"""Driving an action's legs: reach zones, turn counting, sliding around obstacles.

Motion along a leg is straight and computed exactly (ray/circle intersections), so no reach zone is
ever skipped.  The objects within reach when an action starts never end it (so an action never ends
where it started); if a straight move would run into one of them, the robot slides around it
(steps of ``step_size`` along a circle of radius ``radius + robot_clearance``).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Iterator
from typing import TYPE_CHECKING

import numpy as np

from .actions import GoTo, GoToWall, Pose
from .geometry import TOL, WALL_NORMALS, wrap

if TYPE_CHECKING:
    from .world import OfficeWorld

__all__ = ["Drive", "wall_following_legs"]


class Drive:
    """Mutable state of one action while :meth:`OfficeWorld.drive` runs it."""

    def __init__(self, world: "OfficeWorld", pose: Pose):
        self.w = world
        self.p = pose.xy
        self.heading = pose.heading
        self.turned = 0.0
        self.path = 0.0
        self.entered = -1
        self.armed = world.surface_distances(self.p) > world.reach + TOL
        self.cap = world.max_action_steps * world.step_size
        self.R_reach = world.object_radii + world.reach
        self.R_body = world.object_radii + world.robot_clearance

    def run(self, legs: Iterable) -> str:
        """Drive ``legs`` in order; return why the action stopped (see :meth:`OfficeWorld.drive`)."""
        w = self.w
        prev_heading = None
        for n_legs, leg in enumerate(legs, start=1):
            if n_legs > w.max_action_steps:
                return "cap"
            h = leg.heading(self.p)
            if prev_heading is not None:
                self.turned += abs(math.degrees(wrap(h - prev_heading)))
            prev_heading = h
            if self.turned > w.max_turn_deg + 1e-9:
                return "turn"
            reason = self.run_leg(leg)
            if reason is not None:
                return reason
        sd = w.surface_distances(self.p)
        fresh = np.flatnonzero(self.armed & (sd <= w.reach + TOL))
        if fresh.size:
            self.entered = int(fresh[np.argmin(sd[fresh])])
            return "reach"
        return "done"

    def _first_entry(self, p, u, mask, R, inward_only: bool):
        """Smallest ``s >= 0`` where ``p + s u`` enters a circle (centre, ``R``) among ``mask``."""
        if not mask.any():
            return math.inf, -1
        f = p - self.w.object_positions
        b = f @ u
        cc = np.einsum("ij,ij->i", f, f) - R**2
        disc = b * b - cc
        s = np.full(b.shape, np.inf)
        hit = mask & (disc >= 0) & (b < 0)
        s[hit] = -b[hit] - np.sqrt(disc[hit])
        if inward_only:  # already on/inside the boundary and moving inwards: blocked at once
            s[mask & (cc <= 1e-12) & (b < -1e-12)] = 0.0
        s = np.where(s < 0, 0.0, s)
        j = int(np.argmin(s))
        return float(s[j]), j

    def run_leg(self, leg) -> str | None:
        """Drive one leg; return a stop reason, or None when the leg is finished."""
        while True:
            u, rem = leg.guide(self.p)
            if rem <= 1e-9:
                return None
            if self.path >= self.cap - 1e-12:
                return "cap"
            ell = min(rem, self.cap - self.path)
            s_e, j_e = self._first_entry(self.p, u, self.armed, self.R_reach, False)
            s_h, j_h = self._first_entry(self.p, u, ~self.armed, self.R_body, True)
            s = min(ell, s_e, s_h)
            if s > 0:
                self.p = self.p + s * u
                self.path += s
                self.heading = math.atan2(u[1], u[0])
            if s_e <= s + 1e-9:
                self.entered = j_e
                return "reach"
            if s_h <= s and s_h < ell:
                reason = self._slide(leg, j_h, u)
                if reason is not None:
                    return reason

    def _slide(self, leg, j: int, u) -> str | None:
        """Slide around object ``j`` until the leg's direction points away from it."""
        w = self.w
        c, Rb = w.object_positions[j], self.R_body[j]
        n = (self.p - c) / max(np.linalg.norm(self.p - c), 1e-12)
        tangent = np.array([-n[1], n[0]])
        dot = float(tangent @ u)
        if abs(dot) < 1e-9:
            hint = getattr(leg, "hint", None)
            sign = 1.0 if hint is None or float(tangent @ hint) >= 0 else -1.0
        else:
            sign = 1.0 if dot > 0 else -1.0
        dphi = sign * w.step_size / Rb
        others = np.ones(w.n_objects, dtype=bool)
        others[j] = False
        while True:
            u, rem = leg.guide(self.p)
            if rem <= 1e-9:
                return None
            v = self.p - c
            n = v / max(np.linalg.norm(v), 1e-12)
            if float(u @ n) >= -1e-12:
                return None
            if self.path >= self.cap - 1e-12:
                return "cap"
            ang = math.atan2(v[1], v[0]) + dphi
            q = c + Rb * np.array([math.cos(ang), math.sin(ang)])
            seg = q - self.p
            L = float(np.linalg.norm(seg))
            su = seg / L
            s_e, j_e = self._first_entry(self.p, su, self.armed, self.R_reach, False)
            if s_e <= L:
                self.p = self.p + s_e * su
                self.path += s_e
                self.heading = math.atan2(su[1], su[0])
                self.entered = j_e
                return "reach"
            m = w.robot_clearance
            if not (m <= q[0] <= w.width - m and m <= q[1] <= w.height - m):
                return "blocked"
            if np.any((w.surface_distances(q) < w.robot_clearance - 1e-9) & others & ~self.armed):
                return "blocked"
            self.p = q
            self.path += L
            self.heading = math.atan2(su[1], su[0])


def wall_following_legs(world: "OfficeWorld", pose: Pose, side: str) -> Iterator:
    """Legs of "follow ``side`` wall" from ``pose`` (an endless generator; see FollowWall)."""
    p = pose.xy
    wd = world.wall_distances(p)
    d = world.wall_offset

    def along(wall):
        n = WALL_NORMALS[wall]
        return np.array([n[1], -n[0]]) if side == "left" else np.array([-n[1], n[0]])

    def ahead(h):
        return int(np.argmax(WALL_NORMALS @ h))

    w = int(np.argmin(wd))
    near = [k for k in range(4) if wd[k] <= d + 1e-6]
    if len(near) >= 2:  # in a corner: take the wall along which this side leads out of it
        w = next(k for k in near if ahead(along(k)) not in near)
    h = along(w)
    # first leg: face the wall (zero length when already on the lane); it sets the reference
    # heading, so turning along the wall counts 90 degrees and each corner another 90
    yield GoToWall(world, w, d, hint=h)
    while True:
        nxt = ahead(h)
        x = d if 3 in (w, nxt) else world.width - d
        y = d if 0 in (w, nxt) else world.height - d
        yield GoTo((x, y), heading=math.atan2(h[1], h[0]), hint=h)
        w, h = nxt, along(nxt)
