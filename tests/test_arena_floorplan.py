"""A user's floor plan from YAML or JSON: what it holds, and errors that name the entry."""

from __future__ import annotations

import json
from pathlib import Path

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


def _two_rooms_plan(door: float | None) -> dict:
    """A 2 x 1 m box cut at x = 1 by a wall; a door of width ``door`` in its middle (None: no
    door)."""
    if door is None:
        walls = [[[1, 0], [1, 1]]]
    else:
        walls = [[[1, 0], [1, 0.5 - door / 2]], [[1, 0.5 + door / 2], [1, 1]]]
    return {"boundary": [[0, 0], [2, 0], [2, 1], [0, 1]], "walls": walls}


def test_a_wall_that_cuts_the_floor_in_two_is_refused_naming_it():
    with pytest.raises(ValueError, match=r"^walls\[0\]: cuts the floor into 2 parts joined by no "
                                         r"passage MIN_PASSAGE = 0.05 m wide"):
        floorplan_from_dict(_two_rooms_plan(None))


@pytest.mark.parametrize("door, walkable", [(0.01, False), (0.04, False), (0.06, True),
                                            (0.3, True)])
def test_a_door_narrower_than_the_narrowest_passage_is_refused(door, walkable):
    """MIN_PASSAGE is 0.05 m: a 1 cm and a 4 cm door close, 6 cm and 30 cm doors pass."""
    from topomap.worlds.arena.walkable import MIN_PASSAGE

    assert MIN_PASSAGE == 0.05
    if walkable:
        floorplan_from_dict(_two_rooms_plan(door))
        return
    with pytest.raises(ValueError, match=r"^walls\[0\]: cuts the floor into 2 parts"):
        floorplan_from_dict(_two_rooms_plan(door))


def test_a_hole_that_closes_a_corridor_is_named():
    plan = {"boundary": [[0, 0], [3, 0], [3, 1], [0, 1]],
            "holes": [[[0.2, 0.2], [0.4, 0.2], [0.4, 0.4], [0.2, 0.4]],
                      [[1.4, 0.02], [1.6, 0.02], [1.6, 0.98], [1.4, 0.98]]]}
    with pytest.raises(ValueError, match=r"^holes\[1\]: cuts the floor into 2 parts .*widen the "
                                         r"passage it closes$"):
        floorplan_from_dict(plan)
    plan["holes"][1] = [[1.4, 0.1], [1.6, 0.1], [1.6, 0.9], [1.4, 0.9]]
    floorplan_from_dict(plan)  # 0.1 m passages either side


def test_a_neck_of_the_boundary_itself_is_named_boundary():
    """Two 1 x 1 m boxes joined by a 2 cm neck of the outer wall."""
    lo, hi = 0.49, 0.51
    plan = {"boundary": [[0, 0], [1, 0], [1, lo], [1.2, lo], [1.2, 0], [2.2, 0], [2.2, 1],
                         [1.2, 1], [1.2, hi], [1, hi], [1, 1], [0, 1]]}
    with pytest.raises(ValueError, match=r"^boundary: cuts the floor into 2 parts"):
        floorplan_from_dict(plan)


def test_overlapping_regions_are_refused_naming_both(tmp_path):
    plan = {"boundary": [[0, 0], [2, 0], [2, 1], [0, 1]],
            "regions": {"west": [[0, 0], [1.5, 0], [1.5, 1], [0, 1]],
                        "east": [[1, 0], [2, 0], [2, 1], [1, 1]]}}
    (tmp_path / "lab.yaml").write_text(json.dumps(plan))
    with pytest.raises(ValueError, match=r"lab.yaml: regions\['east'\]: overlaps "
                                         r"regions\['west'\] by 0.5 m\^2"):
        load_floorplan(tmp_path / "lab.yaml")
    plan["regions"]["west"] = [[0, 0], [1, 0], [1, 1], [0, 1]]  # sharing an edge is fine
    floorplan_from_dict(plan)


@pytest.mark.parametrize("plan", sorted((Path(__file__).resolve().parents[1] / "benchmarks"
                                         / "floorplans").glob("*.yaml")), ids=lambda p: p.stem)
def test_every_benchmark_floor_plan_is_walkable(plan):
    """The benchmarks' own plans pass the checks every user's plan passes."""
    load_floorplan(str(plan))


def test_alike_rooms_is_the_benchmarks_robot_floor_at_a_third_of_its_size():
    """The built-in ``alike_rooms`` is ``benchmarks/floorplans/robot_alike.yaml`` (3 m rooms)
    with every coordinate times ``ALIKE_SCALE``: the robot benchmark's plan, at 1 m rooms."""
    from topomap.worlds.arena import builtin_layout
    from topomap.worlds.arena.layouts import ALIKE_SCALE

    small = builtin_layout("alike_rooms")
    full = load_floorplan(Path(__file__).resolve().parents[1] / "benchmarks" / "floorplans"
                          / "robot_alike.yaml")
    np.testing.assert_allclose(small.boundary, full.boundary * ALIKE_SCALE)
    np.testing.assert_allclose(small.walls, full.walls * ALIKE_SCALE)
    assert len(small.holes) == len(full.holes) == 7
    for a, b in zip(small.holes, full.holes):
        np.testing.assert_allclose(a, b * ALIKE_SCALE)
    assert [n for n, _ in small.regions] == [n for n, _ in full.regions]
    for (_, a), (_, b) in zip(small.regions, full.regions):
        np.testing.assert_allclose(a, b * ALIKE_SCALE)


def test_alike_rooms_is_3_by_1_4_metres_and_not_its_own_point_reflection():
    """The floor spans 3 x 1.4 m with the corridor along its south side (y < 0.4 m); turned by
    180 degrees about the floor's centre (1.5, 0.7) the corridor's middle (1.5, 0.2) would land at
    (1.5, 1.2), north of the corridor between the two rooms, outside it -- so odometry can tell a
    walk from its point reflection."""
    from topomap.worlds.arena import builtin_layout

    plan = builtin_layout("alike_rooms")
    np.testing.assert_allclose(plan.boundary.min(0), [0, 0])
    np.testing.assert_allclose(plan.boundary.max(0), [3, 1.4])
    names = plan.region_names
    corridor = names.index("corridor")
    assert plan.region_of(np.array([[1.5, 0.2]]))[0] == corridor
    turned = 2 * np.array([1.5, 0.7]) - np.array([[1.5, 0.2]])
    assert plan.region_of(turned)[0] != corridor
    # the west room's table turned about the centre would stand where no furniture stands
    west_table = plan.holes[0].mean(0)
    turned_table = 2 * np.array([1.5, 0.7]) - west_table
    assert min(np.linalg.norm(h.mean(0) - turned_table) for h in plan.holes) > 0.1
