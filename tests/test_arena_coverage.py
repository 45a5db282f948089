"""How the walks cover a floor plan's regions: each region's share of the training and held-out
steps, on the console and in metrics.json; a held-out walk in a region training never entered
is flagged."""

from __future__ import annotations

import json
import logging

import numpy as np
import pytest

from topomap.evaluation.metres import region_coverage

#: two 1 x 1 m rooms side by side, a 0.3 m door between them
LAB = """\
boundary: [[0, 0], [2, 0], [2, 1], [0, 1]]
walls:
  - [[1, 0], [1, 0.35]]
  - [[1, 0.65], [1, 1]]
regions:
  left: [[0, 0], [1, 0], [1, 1], [0, 1]]
  right: [[1, 0], [2, 0], [2, 1], [1, 1]]
"""


def test_region_coverage_by_hand():
    """Training: 3 steps in a, 1 in b; held-out: 1 in b, 3 in c, which training never entered."""
    cover = region_coverage(["a", "b", "c"], [0, 0, 0, 1], [1, 2, 2, 2])
    assert cover["regions"] == {"a": {"training": 0.75, "heldout": 0.0},
                                "b": {"training": 0.25, "heldout": 0.25},
                                "c": {"training": 0.0, "heldout": 0.75}}
    assert cover["unvisited"] == ["c"] and cover["heldout_unvisited"] == 0.75
    assert region_coverage(["a"], [0, 0], [0])["unvisited"] == []


def test_a_held_out_walk_in_a_room_training_never_entered_is_flagged(tmp_path, make_cfg,
                                                                     caplog):
    """A path that circles in the left room for 30 s, then in the right room: the first 300
    steps are learned from, the last 100 held out -- all of them in the right room."""
    pytest.importorskip("ratinabox")
    from topomap.app.run.experiment import run

    (tmp_path / "lab.yaml").write_text(LAB)
    t = np.arange(0, 60.05, 0.1)
    cx = np.where(t < 30, 0.5, 1.5)
    xy = np.column_stack([cx + 0.3 * np.cos(t), 0.5 + 0.3 * np.sin(t)])
    np.savetxt(tmp_path / "rat.csv", np.column_stack([t, xy]), delimiter=",", header="t,x,y",
               comments="")
    out = tmp_path / "run"
    with caplog.at_level(logging.INFO, logger="topomap"):
        run(make_cfg(["env=arena", f"env.floorplan={tmp_path / 'lab.yaml'}",
                      f"env.path={tmp_path / 'rat.csv'}", "data.n_steps=300",
                      "data.heldout_steps=100", "clusters.ns=6", "stop.n_states=10",
                      "output.progress=false", "output.figures=false"]), out)
    cover = json.loads((out / "metrics.json").read_text())["position"]["coverage"]
    assert cover["regions"]["left"] == {"training": 1.0, "heldout": 0.0}
    assert cover["regions"]["right"] == {"training": 0.0, "heldout": 1.0}
    assert cover["unvisited"] == ["right"] and cover["heldout_unvisited"] == 1.0
    said = [r.getMessage() for r in caplog.records]
    assert "regions covered: training left 100%, right 0%; held-out left 0%, right 100%" in said
    assert any(m.startswith("100% of the held-out steps lie in regions the training walk never "
                            "entered (right)") for m in said)


def test_the_arena_walks_its_own_length_unless_told(make_cfg):
    """data.n_steps left out: the arena walks WALK_STEPS = 18,000 steps (30 minutes at 10 Hz),
    half of a recorded path at most, the office the paper's 2,000; a told length wins, and the
    held-out walk is as long by default."""
    pytest.importorskip("ratinabox")
    from topomap.app.run.experiment import check_and_build
    from topomap.worlds.arena.world import WALK_STEPS

    assert WALK_STEPS == 18000
    for overrides, steps, held in [(["env=arena"], 18000, 18000),
                                   (["env=arena", "env.path=sargolini"], 2998, 2998),
                                   (["env=arena", "data.n_steps=500"], 500, 500),
                                   (["env=arena", "data.heldout_steps=0"], 18000, 0),
                                   ([], 2000, 2000)]:
        parts = check_and_build(make_cfg(overrides)).parts
        assert parts.data.steps(parts.env) == steps, overrides
        assert parts.data.heldout_steps_in(parts.env) == held, overrides
    with pytest.raises(ValueError, match=r"^stop.n_states=9001 is more than half of the 18000"):
        check_and_build(make_cfg(["env=arena", "stop.n_states=9001"]))
