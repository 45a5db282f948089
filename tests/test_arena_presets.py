"""Every preset runs as documented; a range finder's default range fits the layout it senses, and
the checks made before a walk sense no walk of their own."""

from __future__ import annotations

import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from topomap.app.run.experiment import check_and_build

PRESETS = Path(__file__).resolve().parents[1] / "conf" / "experiment"

#: a plain 3 x 2 m box, regions its two halves
BOX = """\
boundary: [[0, 0], [3, 0], [3, 2], [0, 2]]
regions:
  west: [[0, 0], [1.5, 0], [1.5, 2], [0, 2]]
  east: [[1.5, 0], [3, 0], [3, 2], [1.5, 2]]
"""


def _arena():
    pytest.importorskip("ratinabox")
    from topomap.worlds import arena

    return arena


def test_the_default_range_reaches_across_the_layout(tmp_path):
    """A 3 x 2 m box reaches sqrt(13) = 3.61 m corner to corner; at (0.5, 1.0) the default beams
    read 2.5 m east, 1 m north, 0.5 m west, 1 m south, as by hand; none is blind."""
    arena = _arena()
    (tmp_path / "box.yaml").write_text(BOX)
    world = arena.ArenaWorld(layout=str(tmp_path / "box.yaml"), sensor=arena.RangeFinder(n_beams=4))
    assert world.layout.reach == pytest.approx(math.sqrt(13))
    motion = arena.Motion.from_samples([[0.5, 1.0], [0.5, 1.0]], 0.1)
    R = world.sensor.sense(world.arena, motion)
    assert R[0] == pytest.approx([2.5, 1.0, 0.5, 1.0])
    assert world.n_features == 4


def test_a_range_too_short_for_the_whole_walk_is_still_refused():
    arena = _arena()
    world = arena.ArenaWorld(layout="open", sensor=arena.RangeFinder(max_range=0.05))
    with pytest.raises(ValueError, match=r"max_range=0.05 m is too short: beam \d+ .* anywhere on "
                                         r"the path of 300 steps \(the layout's reach is 1.41 m\)"):
        world.simulate(300, None, np.random.default_rng(0))


@pytest.mark.parametrize("overrides", [
    ["experiment=rat_tanni"],
    ["env=arena", "env.path=tanni", "data.n_steps=4000", "data.heldout_steps=2000"],
    ["env=arena", "env.path=tanni", "sensor=range", "sensor.max_range=3", "seed=3"],
])
def test_the_checks_before_a_walk_sense_no_probe_walk(overrides, make_cfg):
    """A two-step probe of the path's start saw no wall east within 3 m and was refused; the
    memory check now takes the size of a step from the sensor, and the walk is judged whole."""
    _arena()
    check_and_build(make_cfg(overrides))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_plain_box_floor_plan_passes_the_checks_on_any_seed(seed, tmp_path, make_cfg):
    _arena()
    (tmp_path / "box.yaml").write_text(BOX)
    check_and_build(make_cfg(["env=arena", f"env.floorplan={tmp_path / 'box.yaml'}",
                              f"seed={seed}"]))


#: each preset shrunk where it is long (fewer steps, fewer sweep jobs), its own settings otherwise
SHRUNK = {
    "pricai2002": [],
    "gridroom": ["data.n_steps=3000"],
    "minigrid_empty": ["data.n_steps=3000", "clusters.ns=40", "stop.n_states=60"],
    "sweep_pricai2002": ["clusters.ns=10,20", "stop.n_states=30"],
    "arena_two_rooms": ["data.n_steps=3000", "data.heldout_steps=1000"],
    "rat_tanni": ["data.n_steps=3000", "data.heldout_steps=1000"],
    "arena_robot": ["data.n_steps=3000", "data.heldout_steps=1000"],
}


def test_every_preset_is_in_the_list_of_presets_run():
    assert sorted(SHRUNK) == sorted(p.stem for p in PRESETS.glob("*.yaml"))


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(SHRUNK))
def test_every_preset_runs_as_documented(name, tmp_path):
    """``topomap experiment=<name>``, shrunk where it is long, exits 0 and writes its map."""
    if name.startswith(("arena", "rat")):
        _arena()
    if name.startswith("minigrid"):
        pytest.importorskip("minigrid")
    env = dict(os.environ, TOPOMAP_DISABLE_PLUGIN_AUTOLOAD="1")
    folder = tmp_path / "out"
    key = "hydra.sweep.dir" if name.startswith("sweep") else "hydra.run.dir"
    proc = subprocess.run([sys.executable, "-m", "topomap", f"experiment={name}", *SHRUNK[name],
                           f"{key}={folder}", "output.progress=false"],
                          cwd=tmp_path, env=env, capture_output=True, text=True, timeout=900)
    assert proc.returncode == 0, proc.stderr[-2000:]
    maps = list(folder.rglob("map.json"))
    assert len(maps) == (2 if name.startswith("sweep") else 1)
