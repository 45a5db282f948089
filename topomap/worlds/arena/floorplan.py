"""A user's floor plan, read from a small YAML or JSON file into a :class:`Layout`.

The file holds a mapping with these keys (metres; only ``boundary`` is required)::

    boundary: [[0, 0], [3, 0], [3, 2], [0, 2]]     # the outer wall's corners, in order
    walls:                                          # free-standing walls, two points each
      - [[1.5, 0], [1.5, 0.8]]
      - [[1.5, 1.2], [1.5, 2]]
    holes:                                          # polygons that cannot be entered
      - [[2.2, 0.8], [2.6, 0.8], [2.6, 1.2], [2.2, 1.2]]
    objects:                                        # [x, y] or [x, y, type] (type 0 if left out)
      - [0.5, 0.5]
      - [2.5, 1.7, 1]
    regions:                                        # named polygons, for the wrong-region score
      west: [[0, 0], [1.5, 0], [1.5, 2], [0, 2]]
      east: [[1.5, 0], [3, 0], [3, 2], [1.5, 2]]

Every problem is a one-line ValueError naming the file and the entry, e.g.
``walls[2]: a wall needs two points [[x0, y0], [x1, y1]]``.  A plan must also be walkable
(:mod:`.walkable`): one floor, every part of it reached through passages at least
:data:`~.walkable.MIN_PASSAGE` wide, and regions that do not overlap.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from .geometry import inside_polygon
from .layouts import Layout
from .walkable import check_walkable

__all__ = ["load_floorplan", "floorplan_from_dict", "FLOORPLAN_SUFFIXES"]

FLOORPLAN_SUFFIXES = (".yaml", ".yml", ".json")
_KEYS = ("boundary", "walls", "holes", "objects", "regions")


def _number(value) -> bool:
    return (isinstance(value, (int, float)) and not isinstance(value, bool)
            and math.isfinite(value))


def _point(value, where: str, what: str) -> list:
    if not (isinstance(value, (list, tuple)) and len(value) == 2 and all(map(_number, value))):
        raise ValueError(f"{where}: {what}, got {value!r}")
    return [float(v) for v in value]


def _polygon(value, where: str, what: str) -> list:
    """A simple polygon of at least 3 distinct corners, else a ValueError at ``where``."""
    import shapely

    if not isinstance(value, (list, tuple)) or len(value) < 3:
        raise ValueError(f"{where}: {what} needs at least 3 corners [[x, y], ...], got {value!r}")
    corners = [_point(c, f"{where}[{i}]", "a corner is a point [x, y]")
               for i, c in enumerate(value)]
    polygon = shapely.Polygon(corners)
    if not polygon.is_valid or polygon.area <= 0:
        raise ValueError(f"{where}: {what} must be a simple polygon (its edges may not cross "
                         f"and it must enclose an area), got {value!r}")
    return corners


def _list(data: dict, key: str) -> list:
    value = data.get(key, [])
    if not isinstance(value, list):
        raise ValueError(f"{key}: must be a list, got {value!r}")
    return value


def _on_floor(points, boundary, holes, where: str, what: str) -> None:
    """A ValueError at ``where`` when a point lies outside the boundary or inside a hole."""
    import shapely

    floor = shapely.Polygon(boundary, holes=holes or None)
    for p in points:
        if not floor.covers(shapely.Point(p)):
            raise ValueError(f"{where}: {what} {p} lies outside the floor (outside the boundary "
                             "or inside a hole)")


def _walls(data: dict, boundary, holes) -> list:
    walls = []
    for i, wall in enumerate(_list(data, "walls")):
        where, need = f"walls[{i}]", "a wall needs two points [[x0, y0], [x1, y1]]"
        if not isinstance(wall, (list, tuple)) or len(wall) != 2:
            raise ValueError(f"{where}: {need}, got {wall!r}")
        a, b = (_point(p, where, need) for p in wall)
        if a == b:
            raise ValueError(f"{where}: a wall needs two different points, got {wall!r}")
        _on_floor([a, b], boundary, holes, where, "the wall's end")
        walls.append([a, b])
    return walls


def _objects(data: dict, boundary, holes) -> tuple[list, list]:
    points, types = [], []
    for i, obj in enumerate(_list(data, "objects")):
        where = f"objects[{i}]"
        ok = (isinstance(obj, (list, tuple)) and len(obj) in (2, 3) and all(map(_number, obj[:2]))
              and (len(obj) == 2 or (isinstance(obj[2], int) and obj[2] >= 0)))
        if not ok:
            raise ValueError(f"{where}: an object is a point [x, y] or [x, y, type] with a type "
                             f">= 0, got {obj!r}")
        _on_floor([obj[:2]], boundary, holes, where, "the object")
        points.append([float(obj[0]), float(obj[1])])
        types.append(int(obj[2]) if len(obj) == 3 else 0)
    return points, types


def _regions(data: dict) -> list:
    regions = data.get("regions", {})
    if not isinstance(regions, dict):
        raise ValueError(f"regions: must be a mapping of names to polygons, got {regions!r}")
    return [(str(name), _polygon(poly, f"regions[{name!r}]", "a region"))
            for name, poly in regions.items()]


def floorplan_from_dict(data, name: str = "floor plan") -> Layout:
    """A :class:`Layout` from the mapping of a floor-plan file (see the module docstring)."""
    if not isinstance(data, dict):
        raise ValueError(f"a floor plan must be a mapping with the keys {', '.join(_KEYS)}, "
                         f"got {type(data).__name__}")
    unknown = [str(k) for k in data if k not in _KEYS]
    if unknown:
        raise ValueError(f"{unknown[0]}: unknown key; a floor plan has the keys "
                         f"{', '.join(_KEYS)}")
    if "boundary" not in data:
        raise ValueError("boundary: missing; a floor plan needs the outer wall's corners "
                         "[[x, y], ...]")
    boundary = _polygon(data["boundary"], "boundary", "the boundary")
    holes = [_polygon(h, f"holes[{i}]", "a hole") for i, h in enumerate(_list(data, "holes"))]
    for i, hole in enumerate(holes):
        if not inside_polygon(hole, boundary).all():
            raise ValueError(f"holes[{i}]: a hole must lie inside the boundary")
    walls = _walls(data, boundary, holes)
    points, types = _objects(data, boundary, holes)
    regions = _regions(data)
    check_walkable(boundary, walls, holes, regions)
    return Layout(name, boundary, walls=walls or np.zeros((0, 2, 2)), holes=tuple(holes),
                  objects=points or np.zeros((0, 2)), object_types=types,
                  regions=tuple(regions))


def load_floorplan(path) -> Layout:
    """Read a floor plan from a ``.yaml``/``.yml`` or ``.json`` file into a :class:`Layout`
    named after the file; every problem is a one-line ValueError naming the file."""
    path = Path(path)
    if path.suffix.lower() not in FLOORPLAN_SUFFIXES:
        raise ValueError(f"floor plan {path} must end in .yaml, .yml or .json")
    if not path.is_file():
        raise ValueError(f"floor plan {path} does not exist")
    try:
        text = path.read_text()
        if path.suffix.lower() == ".json":
            data = json.loads(text)
        else:
            import yaml

            data = yaml.safe_load(text)
    except Exception as exc:  # OSError, UnicodeDecodeError, json/yaml syntax errors
        raise ValueError(f"floor plan {path} could not be read: "
                         f"{' '.join(str(exc).split())}") from None
    try:
        return floorplan_from_dict(data, name=path.stem)
    except ValueError as exc:
        raise ValueError(f"floor plan {path}: {exc}") from None
