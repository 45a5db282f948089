"""A user's floor plan from YAML or JSON: what it holds, and errors that name the entry."""

from __future__ import annotations

import json

import numpy as np
import pytest

pytest.importorskip("ratinabox")

from topomap.worlds.arena import ArenaWorld, floorplan_from_dict, load_floorplan  # noqa: E402

PLAN = """\
boundary: [[0, 0], [3, 0], [3, 2], [0, 2]]
walls:
  - [[1.5, 0], [1.5, 0.8]]
  - [[1.5, 1.2], [1.5, 2]]
holes:
  - [[2.2, 0.8], [2.6, 0.8], [2.6, 1.2], [2.2, 1.2]]
objects:
  - [0.5, 0.5]
  - [2.5, 1.7, 1]
regions:
  west: [[0, 0], [1.5, 0], [1.5, 2], [0, 2]]
  east: [[1.5, 0], [3, 0], [3, 2], [1.5, 2]]
"""


def test_a_yaml_floor_plan_is_read_and_walked(tmp_path):
    (tmp_path / "lab.yaml").write_text(PLAN)
    plan = load_floorplan(tmp_path / "lab.yaml")
    assert plan.name == "lab" and plan.region_names == ["west", "east"]
    assert plan.segments.shape == (4 + 2 + 4, 2, 2)
    assert plan.objects.tolist() == [[0.5, 0.5], [2.5, 1.7]] and plan.object_types.tolist() == [0, 1]
    assert plan.region_of([[0.2, 0.2], [2.9, 1.9]]).tolist() == [0, 1]
    assert not plan.inside([[2.4, 1.0]])[0]  # in the hole
    traj = ArenaWorld(layout=str(tmp_path / "lab.yaml")).simulate(200, None,
                                                                  np.random.default_rng(0))
    assert plan.inside(traj.positions).all()


def test_json_holds_the_same_plan(tmp_path):
    import yaml

    (tmp_path / "lab.json").write_text(json.dumps(yaml.safe_load(PLAN)))
    plan = load_floorplan(tmp_path / "lab.json")
    assert plan.walls.tolist() == [[[1.5, 0], [1.5, 0.8]], [[1.5, 1.2], [1.5, 2]]]


BOX = [[0, 0], [2, 0], [2, 1], [0, 1]]


@pytest.mark.parametrize("plan, message", [
    ({"boundary": BOX, "walls": [[[0, 0], [1, 1]], [[1, 0], [1, 1]], [[1, 0]]]},
     "walls[2]: a wall needs two points [[x0, y0], [x1, y1]], got [[1, 0]]"),
    ({"boundary": BOX, "walls": [[[0, 0], [0, "a"]]]},
     "walls[0]: a wall needs two points [[x0, y0], [x1, y1]], got [0, 'a']"),
    ({"boundary": BOX, "walls": [[[0.5, 0.5], [0.5, 0.5]]]},
     "walls[0]: a wall needs two different points"),
    ({"boundary": BOX, "walls": [[[0.5, 0.5], [3, 0.5]]]},
     "walls[0]: the wall's end [3.0, 0.5] lies outside the floor"),
    ({"walls": []}, "boundary: missing"),
    ({"boundary": [[0, 0], [1, 0]]}, "boundary: the boundary needs at least 3 corners"),
    ({"boundary": [[0, 0], [1, 1], [1, 0], [0, 1]]}, "boundary: the boundary must be a simple "
                                                      "polygon"),
    ({"boundary": [[0, 0], [1, 0], [1, None]]}, "boundary[2]: a corner is a point [x, y]"),
    ({"boundary": BOX, "holes": [[[0.2, 0.2], [0.4, 0.2]]]}, "holes[0]: a hole needs at least 3"),
    ({"boundary": BOX, "holes": [[[1.5, 0.5], [2.5, 0.5], [2.5, 0.8]]]},
     "holes[0]: a hole must lie inside the boundary"),
    ({"boundary": BOX, "objects": [[0.5, 0.5], [5, 5]]},
     "objects[1]: the object [5, 5] lies outside the floor"),
    ({"boundary": BOX, "objects": [[0.5, 0.5, -1]]}, "objects[0]: an object is a point [x, y] or "
                                                     "[x, y, type]"),
    ({"boundary": BOX, "regions": [[0, 0]]}, "regions: must be a mapping of names to polygons"),
    ({"boundary": BOX, "regions": {"a": [[0, 0], [1, 0]]}}, "regions['a']: a region needs at "
                                                            "least 3 corners"),
    ({"boundary": BOX, "door": 1}, "door: unknown key; a floor plan has the keys boundary"),
    ({"boundary": BOX, "walls": {"a": 1}}, "walls: must be a list"),
    ([1, 2], "a floor plan must be a mapping"),
])
def test_each_error_names_the_entry(plan, message):
    with pytest.raises(ValueError) as err:
        floorplan_from_dict(plan)
    assert str(err.value).startswith(message) and "\n" not in str(err.value)


def test_file_errors_name_the_file(tmp_path):
    (tmp_path / "bad.yaml").write_text("boundary: [[0, 0], [1, 0]\n")
    with pytest.raises(ValueError, match=r"floor plan .*bad.yaml could not be read"):
        load_floorplan(tmp_path / "bad.yaml")
    (tmp_path / "short.yaml").write_text("boundary: [[0, 0], [1, 0]]\n")
    with pytest.raises(ValueError, match=r"floor plan .*short.yaml: boundary: the boundary needs"):
        load_floorplan(tmp_path / "short.yaml")
    with pytest.raises(ValueError, match="does not exist"):
        load_floorplan(tmp_path / "none.json")
