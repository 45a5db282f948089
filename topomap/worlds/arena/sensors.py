"""Sensors of the arena: each turns a whole path into observation vectors at once.

A sensor is a component with plain typed parameters and one method,
``sense(arena, motion) -> (T, D)`` float array, given the :class:`~topomap.worlds.arena.world.Arena`
(its ``layout`` and ratinabox ``environment``) and the path's
:class:`~topomap.worlds.arena.kinematics.Motion` (positions and headings).  Readings are noise-free:
the run's noise component (:mod:`topomap.worlds.noise`) applies on top.

:class:`RangeFinder`
    ``n_beams`` range beams, spread evenly over the full circle, compass-aligned (beam 0 east)
    or egocentric (beam 0 straight ahead), each the distance to the first wall, at most
    ``max_range``: vectorised ray casting against every wall at once
    (:func:`~topomap.worlds.arena.geometry.ray_distances`).
:class:`BoundaryVectorCells`
    ratinabox's boundary-vector cells (allocentric; Barry & Burgess 2007, de Cothi & Barry 2020):
    firing rates in ``[0, 1]``.
:class:`ObjectVectorCells`
    ratinabox's object-vector cells, tuned to the layout's objects (allocentric).
:class:`PlaceCells`
    ratinabox's place cells: Gaussian bumps of firing around centres drawn on the floor
    (distances around walls, ``geodesic``, by default).
:class:`GridCells`
    ratinabox's grid cells: rectified cosine gratings in three modules of spacing 0.3, 0.5 and
    0.8 m (ratinabox's defaults).

The cells' tuning is drawn from the sensor's own ``seed``, so every walk through a world (the one
learned from and the held-out one) is seen by the same cells.
"""

from __future__ import annotations

import numpy as np

from ...core.checks import ParameterError, check_count
from .checks import positive
from .geometry import ray_distances
from .kinematics import isolated_global_rng

__all__ = ["RangeFinder", "BoundaryVectorCells", "ObjectVectorCells", "PlaceCells", "GridCells",
           "SENSORS", "make_sensor"]

FRAMES = ("compass", "egocentric")


class RangeFinder:
    """A ring of ``n_beams`` range beams (a 2-D laser scanner or sonar ring), noise-free.

    Parameters
    ----------
    n_beams : int
        Beams, at angles ``360 k / n_beams`` degrees, anticlockwise.
    max_range : float or None
        Metres; a beam meeting no wall within it reads ``max_range``.  None (the default): the
        layout's reach, the diagonal of its bounding box (:attr:`Layout.reach`), so every beam
        from the floor meets a wall (a 1 x 1 m box: 1.41 m; ``two_rooms``: 2.69 m).
    frame : str
        ``"compass"`` (beam 0 points east, whatever the heading) or ``"egocentric"`` (beam 0
        points along the heading, as a scanner fixed to the robot).
    """

    def __init__(self, n_beams: int = 12, max_range: float | None = None,
                 frame: str = "compass"):
        self.n_beams = check_count(n_beams, "n_beams")
        self.max_range = None if max_range is None else positive("max_range", max_range)
        if frame not in FRAMES:
            raise ParameterError("frame", f"must be one of {', '.join(FRAMES)}, got {frame!r}")
        self.frame = frame

    @property
    def beam_angles(self) -> np.ndarray:
        """(B,) radians of the beams relative to east (compass) or to the heading (egocentric)."""
        return 2 * np.pi * np.arange(self.n_beams) / self.n_beams

    def n_features(self, arena) -> int:
        """Readings per step: one per beam."""
        return self.n_beams

    def range_in(self, layout) -> float:
        """Metres a beam reaches in ``layout``: ``max_range``, or the layout's reach if None."""
        return layout.reach if self.max_range is None else self.max_range

    def sense(self, arena, motion) -> np.ndarray:
        """(T, n_beams) ranges in metres along the path; a ParameterError naming ``max_range``
        when a beam sees no wall within range anywhere on the path."""
        angles = self.beam_angles[None, :]
        if self.frame == "egocentric":
            angles = angles + motion.heading[:, None]
        reach = self.range_in(arena.layout)
        R = ray_distances(motion.positions, angles, arena.layout.segments, reach)
        blind = np.flatnonzero((R >= reach).all(axis=0))
        if blind.size:
            k = int(blind[0])
            raise ParameterError("max_range", f"={reach:g} m is too short: beam {k} "
                                 f"({np.degrees(self.beam_angles[k]):g} degrees, {self.frame}) "
                                 f"sees no wall within it anywhere on the path of {len(motion)} "
                                 f"steps (the layout's reach is {arena.layout.reach:.2f} m)")
        return R

    def __repr__(self) -> str:
        reach = "None" if self.max_range is None else f"{self.max_range:g}"
        return f"RangeFinder(n_beams={self.n_beams}, max_range={reach}, frame={self.frame!r})"


class _Cells:
    """What the ratinabox cell sensors share: cells built once per arena, rates in blocks."""

    name = "cells"
    _block = 4096

    def _make(self, agent):  # pragma: no cover - each sensor makes its own cells
        raise NotImplementedError

    def _cells(self, arena):
        built = getattr(self, "_built", None)
        if built is None or built[0] is not arena:
            from ratinabox.Agent import Agent

            with isolated_global_rng(self.seed):
                agent = Agent(arena.environment)
                try:
                    cells = self._make(agent)
                finally:
                    arena.environment.remove_agent(agent)
            self._built = (arena, cells)
        return self._built[1]

    def n_features(self, arena) -> int:
        """Readings per step: one per cell."""
        return self.n

    def sense(self, arena, motion) -> np.ndarray:
        """(T, n) firing rates along the path."""
        cells = self._cells(arena)
        P = motion.positions
        blocks = [cells.get_state(evaluate_at=None, pos=P[i:i + self._block]).T
                  for i in range(0, P.shape[0], self._block)]
        return np.ascontiguousarray(np.concatenate(blocks), dtype=np.float64)


class BoundaryVectorCells(_Cells):
    """ratinabox's boundary-vector cells (allocentric), ``n`` of them, tuning drawn from ``seed``.

    Parameters
    ----------
    n : int
        Cells (features).
    seed : int
        Seeds the cells' preferred distances and directions.
    dtheta : float
        Degrees between the directions ratinabox integrates a cell's response over (smaller is
        finer and slower).
    """

    def __init__(self, n: int = 16, seed: int = 0, dtheta: float = 2.0):
        self.n = check_count(n, "n")
        self.seed = int(seed)
        self.dtheta = positive("dtheta", dtheta)

    def _make(self, agent):
        from ratinabox.Neurons import BoundaryVectorCells as BVCs

        self._block = max(1, (1 << 20) // (int(360 / self.dtheta) * len(agent.Environment.walls)))
        return BVCs(agent, params={"n": self.n, "dtheta": self.dtheta})

    def __repr__(self) -> str:
        return f"BoundaryVectorCells(n={self.n}, seed={self.seed}, dtheta={self.dtheta:g})"


class ObjectVectorCells(_Cells):
    """ratinabox's object-vector cells (allocentric), ``n`` of them, tuned to the layout's objects.

    Parameters
    ----------
    n : int
        Cells (features).
    seed : int
        Seeds the cells' preferred distances, directions and object types.
    walls_occlude : bool
        An object behind a wall is not seen.
    """

    def __init__(self, n: int = 16, seed: int = 0, walls_occlude: bool = True):
        self.n = check_count(n, "n")
        self.seed = int(seed)
        self.walls_occlude = bool(walls_occlude)

    def _make(self, agent):
        from ratinabox.Neurons import ObjectVectorCells as OVCs

        if agent.Environment.objects["objects"].shape[0] == 0:
            raise ParameterError("objects", "are needed by object-vector cells, but the layout "
                                            "has none (give a floor plan with objects)")
        return OVCs(agent, params={"n": self.n, "walls_occlude": self.walls_occlude})

    def __repr__(self) -> str:
        return (f"ObjectVectorCells(n={self.n}, seed={self.seed}, "
                f"walls_occlude={self.walls_occlude})")


class PlaceCells(_Cells):
    """ratinabox's place cells, ``n`` of them, centres drawn from ``seed`` on the floor.

    Parameters
    ----------
    n : int
        Cells (features).
    seed : int
        Seeds the cells' centres.
    widths : float
        Metres: the width (standard deviation) of each cell's Gaussian field.
    wall_geometry : str
        How a field reaches around walls: ``"geodesic"`` (the shortest way round),
        ``"line_of_sight"`` (not past a wall) or ``"euclidean"`` (through walls).
    """

    GEOMETRIES = ("geodesic", "line_of_sight", "euclidean")

    def __init__(self, n: int = 16, seed: int = 0, widths: float = 0.2,
                 wall_geometry: str = "geodesic"):
        self.n = check_count(n, "n")
        self.seed = int(seed)
        self.widths = positive("widths", widths)
        if wall_geometry not in self.GEOMETRIES:
            raise ParameterError("wall_geometry", f"must be one of {', '.join(self.GEOMETRIES)}"
                                                  f", got {wall_geometry!r}")
        self.wall_geometry = wall_geometry

    def _make(self, agent):
        from ratinabox.Neurons import PlaceCells as PCs

        return PCs(agent, params={"n": self.n, "widths": self.widths,
                                  "wall_geometry": self.wall_geometry})

    def __repr__(self) -> str:
        return (f"PlaceCells(n={self.n}, seed={self.seed}, widths={self.widths:g}, "
                f"wall_geometry={self.wall_geometry!r})")


class GridCells(_Cells):
    """ratinabox's grid cells, ``n`` of them, phases drawn from ``seed``: rectified cosine
    gratings, spread over three modules of spacing 0.3, 0.5 and 0.8 m and orientation 0, 0.1 and
    0.2 rad (ratinabox's defaults).

    Parameters
    ----------
    n : int
        Cells (features).
    seed : int
        Seeds the cells' modules and phases.
    """

    def __init__(self, n: int = 30, seed: int = 0):
        self.n = check_count(n, "n")
        self.seed = int(seed)

    def _make(self, agent):
        from ratinabox.Neurons import GridCells as GCs

        return GCs(agent, params={"n": self.n})

    def __repr__(self) -> str:
        return f"GridCells(n={self.n}, seed={self.seed})"


#: the sensors by name (a world given a name builds the sensor with its defaults)
SENSORS = {"range": RangeFinder, "bvc": BoundaryVectorCells, "ovc": ObjectVectorCells,
           "place_cells": PlaceCells, "grid_cells": GridCells}


def make_sensor(sensor):
    """``sensor`` if it is a sensor, else the sensor named ``sensor`` with its defaults."""
    if isinstance(sensor, str):
        if sensor not in SENSORS:
            raise ParameterError("sensor", f"must be one of {', '.join(SENSORS)} or a sensor "
                                           f"object, got {sensor!r}")
        return SENSORS[sensor]()
    if not callable(getattr(sensor, "sense", None)):
        raise ParameterError("sensor", f"must have a sense(arena, motion) method, got {sensor!r}")
    return sensor
