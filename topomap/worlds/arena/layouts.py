"""Floor plans of the arena: a boundary polygon, walls, holes, objects and named regions.

Five are built in (metres; every door 0.3 m wide):

``open``
    a 1 x 1 m box (ratinabox's default); its regions are its four quadrants.
``two_rooms``
    two alike 1 x 1 m rooms joined by a corridor 0.5 m long between the middles of their facing
    walls (2.5 x 1 m in all); regions ``west``, ``corridor``, ``east``.
``four_rooms``
    a 2 x 2 m box cut into four 1 x 1 m rooms by a cross of walls with a door in the middle of
    each of the cross's four arms; regions ``south-west``, ``south-east``, ``north-west``,
    ``north-east``.
``corridor``
    a corridor 2 x 0.4 m with two 1 x 1 m rooms off each side, each through a door in the middle
    of its wall (2 x 2.4 m in all); regions the four rooms and ``corridor``.
``alike_rooms``
    two alike furnished 1 x 1 m rooms north of a corridor 3 x 0.4 m, their furniture set out a
    little differently (3 x 1.4 m in all; a robot's floor at a third of its size, not its own
    point reflection); regions ``corridor``, ``west``, ``east``.

A user's floor plan is read from a file by :func:`topomap.worlds.arena.floorplan.load_floorplan`.
The regions are what the wrong-region score counts (:mod:`topomap.evaluation.metres`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .geometry import inside_polygon, nearest_on_segments, polygon_edges, segment_distances

__all__ = ["Layout", "LAYOUTS", "builtin_layout", "open_box", "DOOR", "ALIKE_SCALE"]

#: width of every door and corridor of the built-in layouts (metres)
DOOR = 0.3


def _points(values, shape_tail) -> np.ndarray:
    return np.asarray(values, dtype=np.float64).reshape((-1, *shape_tail))


@dataclass(frozen=True, eq=False)
class Layout:
    """A floor plan (metres).

    Attributes
    ----------
    name : str
    boundary : (B, 2) float -- the corners of the outer wall, in order (a simple polygon)
    walls : (W, 2, 2) float -- free-standing walls, each from one point to another
    holes : tuple of (H, 2) float -- polygons inside the boundary that cannot be entered
    objects : (O, 2) float -- points that object-vector cells respond to (walls pass through them)
    object_types : (O,) int -- the type of each object
    regions : tuple of (name, (R, 2) polygon) -- the rooms, for the wrong-region score
    """

    name: str
    boundary: np.ndarray
    walls: np.ndarray = field(default_factory=lambda: np.zeros((0, 2, 2)))
    holes: tuple = ()
    objects: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    object_types: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    regions: tuple = ()

    def __post_init__(self):
        object.__setattr__(self, "boundary", _points(self.boundary, (2,)))
        object.__setattr__(self, "walls", _points(self.walls, (2, 2)))
        object.__setattr__(self, "holes", tuple(_points(h, (2,)) for h in self.holes))
        object.__setattr__(self, "objects", _points(self.objects, (2,)))
        object.__setattr__(self, "object_types", np.asarray(self.object_types, dtype=np.int64))
        object.__setattr__(self, "regions", tuple((str(n), _points(p, (2,)))
                                                  for n, p in self.regions))

    @classmethod
    def from_environment(cls, environment, name: str = "environment") -> "Layout":
        """The floor plan of a ratinabox ``Environment`` (2-D, solid boundary): its boundary,
        walls, holes and objects; no regions."""
        from ...core.checks import ParameterError

        if environment.dimensionality != "2D" or environment.boundary_conditions != "solid":
            raise ParameterError("layout", f"must be a 2D ratinabox Environment with solid "
                                           f"boundaries, got {environment.dimensionality} "
                                           f"{environment.boundary_conditions}")
        walls = environment.params.get("walls") or np.zeros((0, 2, 2))
        objects = environment.objects
        return cls(name, environment.boundary, walls=walls,
                   holes=tuple(environment.holes or ()), objects=objects["objects"],
                   object_types=objects["object_types"])

    @property
    def segments(self) -> np.ndarray:
        """Everything that blocks a beam: the boundary's edges, the walls, the holes' edges."""
        parts = [polygon_edges(self.boundary), self.walls]
        parts += [polygon_edges(h) for h in self.holes]
        return np.concatenate(parts)

    @property
    def region_names(self) -> list[str]:
        return [name for name, _ in self.regions]

    @property
    def extent(self) -> tuple[float, float, float, float]:
        """``(x_min, x_max, y_min, y_max)`` of the boundary."""
        (x0, y0), (x1, y1) = self.boundary.min(axis=0), self.boundary.max(axis=0)
        return float(x0), float(x1), float(y0), float(y1)

    @property
    def reach(self) -> float:
        """Metres: the diagonal of the boundary's bounding box, the longest straight line on the
        floor plan (a beam this long from anywhere on the floor meets a wall)."""
        x0, x1, y0, y1 = self.extent
        return float(np.hypot(x1 - x0, y1 - y0))

    def inside(self, points) -> np.ndarray:
        """Which points lie on the floor: inside the boundary and outside every hole."""
        mask = inside_polygon(points, self.boundary)
        for hole in self.holes:
            mask &= ~inside_polygon(points, hole)
        return mask

    def region_of(self, points) -> np.ndarray:
        """The region of each point, ``(T,)`` int: the first region holding it, else the region
        nearest to it (a point on the line between two rooms, in a doorway)."""
        if not self.regions:
            raise ValueError(f"the layout {self.name!r} has no regions")
        P = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        labels = np.full(P.shape[0], -1, dtype=np.int64)
        for k, (_, polygon) in enumerate(self.regions):
            labels[(labels < 0) & inside_polygon(P, polygon)] = k
        rest = np.flatnonzero(labels < 0)
        if rest.size:
            dist = np.column_stack([segment_distances(P[rest], polygon_edges(poly))
                                    for _, poly in self.regions])
            labels[rest] = dist.argmin(axis=1)
        return labels

    def move_inside(self, points, tolerance: float):
        """Points moved onto the floor when they lie off it by at most ``tolerance`` metres.

        Returns ``(points, moved, worst)``: the points (a copy), which were moved, and the index
        of the point farthest off the floor with its distance, ``(index, metres)`` (None when all
        lie on the floor).  A point is moved to 1 mm past the nearest wall; one off by more than
        ``tolerance`` is left where it is (the caller reports it).
        """
        P = np.array(points, dtype=np.float64)
        off = np.flatnonzero(~self.inside(P))
        if off.size == 0:
            return P, np.zeros(P.shape[0], dtype=bool), None
        foot, dist = nearest_on_segments(P[off], self.segments)
        worst = (int(off[dist.argmax()]), float(dist.max()))
        near = dist <= tolerance
        step = foot - P[off]
        unit = step / np.maximum(np.hypot(step[:, 0], step[:, 1]), 1e-12)[:, None]
        P[off[near]] = (foot + 1e-3 * unit)[near]
        moved = np.zeros(P.shape[0], dtype=bool)
        moved[off[near]] = True
        return P, moved, worst

    def environment_params(self) -> dict:
        """The ``params`` of a ratinabox ``Environment`` with this floor plan (objects are added
        afterwards, with their types)."""
        return {"boundary": self.boundary.tolist(), "walls": self.walls.tolist(),
                "holes": [h.tolist() for h in self.holes]}


def _box(x0, y0, x1, y1) -> list:
    return [[x0, y0], [x1, y0], [x1, y1], [x0, y1]]


def _wall(start, end, doors=()) -> list:
    """The pieces of a straight wall from ``start`` to ``end`` left between door gaps, each gap a
    ``(centre, width)`` along the wall measured from ``start``."""
    start, end = np.asarray(start, float), np.asarray(end, float)
    length = float(np.hypot(*(end - start)))
    cuts = [0.0]
    for centre, width in sorted(doors):
        cuts += [centre - width / 2, centre + width / 2]
    cuts.append(length)
    unit = (end - start) / length
    return [[(start + a * unit).tolist(), (start + b * unit).tolist()]
            for a, b in zip(cuts[::2], cuts[1::2]) if b > a]


def open_box(width: float = 1.0, height: float = 1.0, name: str = "open") -> Layout:
    """A ``width x height`` box; its regions are its four quadrants."""
    w2, h2 = width / 2, height / 2
    regions = [("south-west", _box(0, 0, w2, h2)), ("south-east", _box(w2, 0, width, h2)),
               ("north-west", _box(0, h2, w2, height)), ("north-east", _box(w2, h2, width, height))]
    return Layout(name, _box(0, 0, width, height), regions=regions)


def _two_rooms() -> Layout:
    lo, hi = 0.5 - DOOR / 2, 0.5 + DOOR / 2
    boundary = [[0, 0], [1, 0], [1, lo], [1.5, lo], [1.5, 0], [2.5, 0], [2.5, 1], [1.5, 1],
                [1.5, hi], [1, hi], [1, 1], [0, 1]]
    regions = [("west", _box(0, 0, 1, 1)), ("corridor", _box(1, lo, 1.5, hi)),
               ("east", _box(1.5, 0, 2.5, 1))]
    return Layout("two_rooms", boundary, regions=regions)


def _four_rooms() -> Layout:
    doors = [(0.5, DOOR), (1.5, DOOR)]
    walls = _wall([1, 0], [1, 2], doors) + _wall([0, 1], [2, 1], doors)
    regions = [("south-west", _box(0, 0, 1, 1)), ("south-east", _box(1, 0, 2, 1)),
               ("north-west", _box(0, 1, 1, 2)), ("north-east", _box(1, 1, 2, 2))]
    return Layout("four_rooms", _box(0, 0, 2, 2), walls=walls, regions=regions)


def _corridor() -> Layout:
    doors = [(0.5, DOOR), (1.5, DOOR)]
    walls = (_wall([0, 1], [2, 1], doors) + _wall([0, 1.4], [2, 1.4], doors)
             + _wall([1, 0], [1, 1]) + _wall([1, 1.4], [1, 2.4]))
    regions = [("south-west", _box(0, 0, 1, 1)), ("south-east", _box(1, 0, 2, 1)),
               ("corridor", _box(0, 1, 2, 1.4)),
               ("north-west", _box(0, 1.4, 1, 2.4)), ("north-east", _box(1, 1.4, 2, 2.4))]
    return Layout("corridor", _box(0, 0, 2, 2.4), walls=walls, regions=regions)


#: :func:`_alike_rooms` against the robot's floor it is drawn from (3 m rooms off a 9 m corridor,
#: ``benchmarks/floorplans/robot_alike.yaml``): 1 m rooms, as the other built-in layouts, which a
#: robot at 0.1 m/s covers in 30 minutes (at full size 30 minutes leave a new walk 30 % of its
#: steps in the wrong room even by K-means on the true positions, ``benchmarks/notes/robots.md``)
ALIKE_SCALE = 1 / 3


def _alike_rooms() -> Layout:
    """Two alike furnished rooms (1 x 1 m, a 0.3 m door each) north of a 3 x 0.4 m corridor, the
    same table, shelf and bin in each set out a little differently -- the east room's table 0.13
    m farther east, its bin in the other corner, its door 0.1 m farther west -- and a cabinet at
    the corridor's east end.  A scan in the robot's own frame tells the rooms apart only where it
    sees those differences; the plan is not its own point reflection, so odometry can."""
    full = {
        "boundary": [[0, 0], [9, 0], [9, 1.2], [8, 1.2], [8, 4.2], [5, 4.2], [5, 1.2], [3.5, 1.2],
                     [3.5, 4.2], [0.5, 4.2], [0.5, 1.2], [0, 1.2]],
        "walls": [[[0.5, 1.2], [1.6, 1.2]], [[2.5, 1.2], [3.5, 1.2]], [[5.0, 1.2], [5.8, 1.2]],
                  [[6.7, 1.2], [8.0, 1.2]]],
        "holes": [_box(1.0, 2.6, 2.0, 3.2), _box(3.0, 2.0, 3.3, 3.6),    # west: table, shelf,
                  _box(1.4, 3.7, 1.7, 4.0),                               # bin
                  _box(5.9, 2.6, 6.9, 3.2), _box(7.5, 2.0, 7.8, 3.6),    # east: table, shelf,
                  _box(5.2, 3.7, 5.5, 4.0),                               # bin
                  _box(8.2, 0.15, 8.7, 0.45)],                            # corridor: cabinet
        "regions": [("corridor", _box(0, 0, 9, 1.2)), ("west", _box(0.5, 1.2, 3.5, 4.2)),
                    ("east", _box(5, 1.2, 8, 4.2))]}
    k = ALIKE_SCALE
    return Layout("alike_rooms", np.asarray(full["boundary"], float) * k,
                  walls=np.asarray(full["walls"], float) * k,
                  holes=tuple(np.asarray(h, float) * k for h in full["holes"]),
                  regions=tuple((n, np.asarray(p, float) * k) for n, p in full["regions"]))


#: the built-in layouts by name
LAYOUTS = {"open": open_box, "two_rooms": _two_rooms, "four_rooms": _four_rooms,
           "corridor": _corridor, "alike_rooms": _alike_rooms}


def builtin_layout(name: str) -> Layout:
    """The built-in layout ``name``, or a ValueError naming ``layout`` and the choices."""
    if name not in LAYOUTS:
        raise ValueError(f"layout {name!r} is neither a built-in layout ({', '.join(LAYOUTS)}) "
                         "nor a floor-plan file (.yaml, .yml or .json)")
    return LAYOUTS[name]()
