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
