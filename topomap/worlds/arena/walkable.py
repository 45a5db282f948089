"""Whether a floor plan can be walked: one floor, joined by passages a walker fits through, and
regions that do not overlap.

The floor a walker's centre can reach is the floor (the boundary less its holes) shrunk by half of
:data:`MIN_PASSAGE`, less every wall grown by as much (shapely's buffers): a passage narrower than
``MIN_PASSAGE`` closes in it.  When that floor falls into parts, a walk started in one never
reaches the others, and the map of such a walk says nothing of them: the plan is refused, naming
the entry that cuts it (the first wall or hole without which the parts join, else the boundary).
"""

from __future__ import annotations

__all__ = ["check_walkable", "MIN_PASSAGE", "MIN_OVERLAP"]

#: metres: the narrowest door or corridor a plan may have.  ratinabox's random motion (its
#: defaults: wall_repel_distance 0.1 m) crossed the door in a wall across a 2 x 1 m box, in 30
#: minutes, 0-1 times through 0.01, 0.03 and 0.05 m doors, 1-6 times through 0.1 m and 7-12
#: times through the built-in layouts' 0.3 m (two or three seeds each;
#: ``benchmarks/notes/arena-walks.md``): a door of 0.05 m or less is all but closed to it.
MIN_PASSAGE = 0.05
#: square metres two regions may share (the width of a drawn line): more, and a step there
#: would count in both
MIN_OVERLAP = 1e-6


def _reachable(boundary, walls, holes):
    """The polygons of the floor a walker's centre reaches (shapely geometries), largest first."""
    import shapely

    half = MIN_PASSAGE / 2
    floor = shapely.Polygon(boundary, holes=holes or None).buffer(-half)
    if walls:
        floor = floor.difference(shapely.MultiLineString(walls).buffer(half))
    parts = [g for g in getattr(floor, "geoms", [floor]) if g.area > 0]
    return sorted(parts, key=lambda g: -g.area)


def _culprit(boundary, walls, holes, n_parts: int) -> str:
    """The first wall, else hole, without which the floor falls into fewer parts; else the
    boundary (a neck of the outer wall itself)."""
    for i in range(len(walls)):
        if len(_reachable(boundary, walls[:i] + walls[i + 1:], holes)) < n_parts:
            return f"walls[{i}]"
    for i in range(len(holes)):
        if len(_reachable(boundary, walls, holes[:i] + holes[i + 1:])) < n_parts:
            return f"holes[{i}]"
    return "boundary"


def _check_one_floor(boundary, walls, holes) -> None:
    parts = _reachable(boundary, walls, holes)
    if not parts:
        raise ValueError(f"boundary: leaves no floor a walker fits on (every passage is "
                         f"narrower than MIN_PASSAGE = {MIN_PASSAGE:g} m)")
    if len(parts) > 1:
        where = _culprit(boundary, walls, holes, len(parts))
        a, b = (p.representative_point() for p in parts[:2])
        raise ValueError(f"{where}: cuts the floor into {len(parts)} parts joined by no "
                         f"passage MIN_PASSAGE = {MIN_PASSAGE:g} m wide (one holds "
                         f"({a.x:.2f}, {a.y:.2f}), another ({b.x:.2f}, {b.y:.2f})): a walk "
                         "never reaches the others; widen the passage it closes")


def _check_regions_apart(regions) -> None:
    import shapely

    shapes = [(name, shapely.Polygon(poly)) for name, poly in regions]
    for j, (name, shape) in enumerate(shapes):
        for other, earlier in shapes[:j]:
            shared = shape.intersection(earlier).area
            if shared > MIN_OVERLAP:
                raise ValueError(f"regions[{name!r}]: overlaps regions[{other!r}] by "
                                 f"{shared:.3g} m^2: a step there would count in both; "
                                 "regions must not overlap")


def check_walkable(boundary, walls, holes, regions) -> None:
    """A one-line ValueError naming the entry when the plan cannot be walked (see the module
    docstring); ``regions`` are ``(name, corners)`` pairs."""
    _check_one_floor(boundary, list(walls), list(holes))
    _check_regions_apart(regions)
