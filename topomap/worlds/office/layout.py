"""Office rooms: the paper's fixed room and random rooms drawn from a seed."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .geometry import corner_points, surface_gaps

__all__ = ["OfficeLayout", "paper_layout", "random_layout"]


@dataclass
class OfficeLayout:
    """Objects of an office room.

    Attributes
    ----------
    width, height : float
        Room size.
    type_names : list of str
        One name per object type; the observation has one entry per type.
    types : (n,) int array
        Type of each object.
    centers : (n, 2) float array
        Object centres.
    radii : (n,) float array
        Object radii (physical size).
    gds : list of int
        Objects that are globally distinctive states, in GDS id order.
    """

    width: float
    height: float
    type_names: list[str]
    types: np.ndarray
    centers: np.ndarray
    radii: np.ndarray
    gds: list[int] = field(default_factory=list)

    def __post_init__(self):
        self.width, self.height = float(self.width), float(self.height)
        if not (math.isfinite(self.width) and self.width > 0):
            raise ValueError(f"width must be a positive number, got {self.width}")
        if not (math.isfinite(self.height) and self.height > 0):
            raise ValueError(f"height must be a positive number, got {self.height}")
        self.type_names = [str(t) for t in self.type_names]
        if not self.type_names:
            raise ValueError("type_names must name at least one type")
        self.types = np.asarray(self.types, dtype=np.int64).reshape(-1)
        self.centers = np.asarray(self.centers, dtype=np.float64).reshape(-1, 2)
        self.radii = np.asarray(self.radii, dtype=np.float64).reshape(-1)
        n = self.types.size
        if n == 0:
            raise ValueError("a layout needs at least one object")
        if self.centers.shape[0] != n or self.radii.size != n:
            raise ValueError(
                f"types ({n}), centers ({self.centers.shape[0]}) and radii ({self.radii.size}) "
                "must describe the same number of objects"
            )
        if self.types.min() < 0 or self.types.max() >= len(self.type_names):
            raise ValueError(f"types must lie in [0, {len(self.type_names)})")
        if not np.all(self.radii > 0):
            raise ValueError("radii must be positive")
        lo = self.centers - self.radii[:, None]
        hi = self.centers + self.radii[:, None]
        if np.any(lo < -1e-9) or np.any(hi[:, 0] > self.width + 1e-9) or np.any(hi[:, 1] > self.height + 1e-9):
            raise ValueError("every object must lie inside the room")
        gap = surface_gaps(self.centers, self.radii)
        if np.any(gap < -1e-9):
            i, j = np.unravel_index(int(np.argmin(gap)), gap.shape)
            raise ValueError(f"objects {i} and {j} overlap")
        self.gds = [int(g) for g in self.gds]
        if len(set(self.gds)) != len(self.gds) or any(g < 0 or g >= n for g in self.gds):
            raise ValueError(f"gds must list distinct object indices in [0, {n})")

    @property
    def n_objects(self) -> int:
        return int(self.types.size)

    @property
    def n_types(self) -> int:
        return len(self.type_names)


# name, radius (m), and whether it is a segment of a wall
_PAPER_TYPES = [
    ("red wall", 0.5, True),
    ("blue wall", 0.5, True),
    ("green wall", 0.5, True),
    ("yellow wall", 0.5, True),
    ("white wall", 0.5, True),
    ("blue desk", 0.7, False),
    ("gray table", 0.6, False),
    ("green table", 0.6, False),
    ("blue table", 0.6, False),
    ("long gray table", 1.0, False),
    ("computer", 0.35, False),
    ("green chair", 0.35, False),
    ("gray chair", 0.35, False),
    ("red chair", 0.35, False),
    ("blue chair", 0.35, False),
]

# (type name, x, y) in a 20 m x 14 m room
_PAPER_OBJECTS = [
    ("red wall", 4.0, 0.5),
    ("yellow wall", 7.5, 0.5),
    ("blue wall", 15.0, 0.5),
    ("green wall", 19.5, 5.0),
    ("red wall", 19.5, 10.0),
    ("blue wall", 15.0, 13.5),
    ("green wall", 8.0, 13.5),
    ("red wall", 5.0, 13.5),
    ("white wall", 0.5, 9.5),
    ("yellow wall", 0.5, 4.5),
    ("blue desk", 4.0, 4.0),
    ("computer", 6.2, 4.0),
    ("green chair", 4.0, 6.2),
    ("blue desk", 16.0, 10.0),
    ("computer", 13.8, 10.0),
    ("green chair", 16.0, 7.8),
    ("long gray table", 10.0, 7.0),
    ("gray chair", 7.6, 7.0),
    ("gray chair", 12.4, 7.0),
    ("blue table", 13.5, 3.5),
    ("blue table", 16.5, 3.5),
    ("green table", 4.0, 10.0),
    ("red chair", 6.2, 10.0),
    ("blue chair", 10.0, 11.2),
    ("gray table", 10.0, 2.8),
]
_PAPER_GDS = [23, 24]  # GDS1 = the blue chair, GDS2 = the gray table


def paper_layout() -> OfficeLayout:
    """The fixed 20 m x 14 m room with 25 objects of 15 types and 2 GDS (after the paper's Fig. 4).

    Ten coloured wall segments (5 colours) line the walls; two desk groups (blue desk, computer,
    green chair) sit in opposite corners of the room, a long gray table with two gray chairs in the
    middle, two blue tables bottom right, a green table and a red chair top left.  The GDS are the
    blue chair (GDS1, top centre) and the gray table (GDS2, bottom centre), each at least 2 m from
    every other object.
    """
    names = [t[0] for t in _PAPER_TYPES]
    radius = {t[0]: t[1] for t in _PAPER_TYPES}
    types = [names.index(o[0]) for o in _PAPER_OBJECTS]
    centers = [(o[1], o[2]) for o in _PAPER_OBJECTS]
    radii = [radius[o[0]] for o in _PAPER_OBJECTS]
    return OfficeLayout(20.0, 14.0, names, types, centers, radii, list(_PAPER_GDS))


_COLOURS = ["red", "blue", "green", "gray", "yellow", "white", "black", "brown", "orange", "purple"]
# kind, radius, on a wall
_KINDS = [
    ("wall", 0.5, True),
    ("desk", 0.7, False),
    ("table", 0.6, False),
    ("chair", 0.35, False),
    ("computer", 0.35, False),
    ("shelf", 0.45, True),
    ("plant", 0.3, False),
    ("cabinet", 0.5, False),
]


def _draw_types(rng: np.random.Generator, n_types: int):
    """Names, radii and wall flags of ``n_types`` random object types ("<colour> <kind>")."""
    combos = [(c, k) for k in range(len(_KINDS)) for c in _COLOURS]
    order = rng.permutation(len(combos))
    names, radius, on_wall = [], [], []
    for k in range(n_types):
        if k < len(combos):
            colour, kind = combos[order[k]]
            name = f"{colour} {_KINDS[kind][0]}"
        else:
            kind = int(rng.integers(len(_KINDS)))
            name = f"type {k}"
        names.append(name)
        radius.append(_KINDS[kind][1])
        on_wall.append(_KINDS[kind][2])
    return names, radius, on_wall


@dataclass
class _Room:
    """What placing objects in a random room needs to know."""

    width: float
    height: float
    reach: float
    wall_offset: float
    interior_wall_gap: float
    min_gap: float
    gds: list

    def candidate(self, rng: np.random.Generator, r: float, on_wall: bool):
        """A random centre for an object of radius ``r`` (None if it cannot fit this way)."""
        if on_wall:
            wall = int(rng.integers(4))
            length = self.width if wall in (0, 2) else self.height
            margin = self.wall_offset + self.reach + 1.5 + r
            if length - 2 * margin <= 0:
                return None
            s = rng.uniform(margin, length - margin)
            return np.asarray({0: (s, r), 1: (self.width - r, s), 2: (s, self.height - r),
                               3: (r, s)}[wall])
        lo = self.interior_wall_gap + r
        if self.width - 2 * lo <= 0 or self.height - 2 * lo <= 0:
            return None
        return np.asarray((rng.uniform(lo, self.width - lo), rng.uniform(lo, self.height - lo)))

    def fits(self, i: int, c: np.ndarray, r: float, centers, radii, placed) -> bool:
        """Whether object ``i`` at ``c`` keeps its gaps to the corners and the placed objects."""
        corners = corner_points(self.width, self.height, self.wall_offset)
        if np.any(np.hypot(*(corners - c).T) - r <= self.reach + 0.1):
            return False
        gds_gap = 2.0 * self.reach + 0.2
        for j in placed:
            gap = math.hypot(*(centers[j] - c)) - radii[j] - r
            if gap < (gds_gap if (i in self.gds or j in self.gds) else self.min_gap):
                return False
        return True

    def place(self, rng, order, radii, on_wall):
        """Centres of all objects in ``order``, or None when one of them found no free spot."""
        centers = np.zeros((radii.size, 2))
        placed: list[int] = []
        for i in order:
            for _try in range(400):
                c = self.candidate(rng, radii[i], on_wall[i])
                if c is not None and self.fits(i, c, radii[i], centers, radii, placed):
                    centers[i] = c
                    placed.append(i)
                    break
            else:
                return None
        return centers


def random_layout(
    rng: np.random.Generator,
    n_objects: int = 25,
    n_types: int = 15,
    n_gds: int = 2,
    width: float = 20.0,
    height: float = 14.0,
    *,
    reach: float = 1.0,
    wall_offset: float = 1.5,
    interior_wall_gap: float = 2.0,
    min_gap: float = 1.0,
    max_tries: int = 20,
) -> OfficeLayout:
    """Draw a room with ``n_objects`` objects of ``n_types`` types and ``n_gds`` GDS objects.

    Every type is used at least once.  Type names combine a colour and a kind ("blue desk");
    wall-mounted kinds ("wall", "shelf") touch a wall at least ``wall_offset + reach + 1.5`` from a
    corner; the other objects keep ``interior_wall_gap`` to the walls.  Object surfaces are at least
    ``min_gap`` apart, GDS objects at least ``2 * reach + 0.2`` from every other object, and no
    object is within reach of a corner place, so every object can be approached and GDS labels are
    unambiguous.  The settings from ``reach`` on are keyword-only.

    Raises
    ------
    ValueError
        If the objects do not fit into the room.
    """
    type_names, type_radius, type_wall = _draw_types(rng, n_types)
    types = np.concatenate([np.arange(n_types), rng.integers(0, n_types, n_objects - n_types)])
    types = rng.permutation(types)
    gds = sorted(rng.choice(n_objects, size=n_gds, replace=False).tolist()) if n_gds else []
    # place GDS objects first: they need the widest free space
    order = gds + [i for i in range(n_objects) if i not in set(gds)]
    room = _Room(width, height, reach, wall_offset, interior_wall_gap, min_gap, gds)
    radii = np.array([type_radius[t] for t in types], dtype=np.float64)
    on_wall = [type_wall[t] for t in types]
    for _attempt in range(max_tries):
        centers = room.place(rng, order, radii, on_wall)
        if centers is not None:
            return OfficeLayout(width, height, type_names, types, centers, radii, gds)
    raise ValueError(
        f"could not place n_objects={n_objects} objects in a {width} x {height} room; "
        "use a bigger room (width, height) or fewer objects"
    )
