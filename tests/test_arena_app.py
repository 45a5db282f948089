"""The arena through the ``topomap`` command: ``env=arena`` with its sensor and action rule as
components, recorded and user paths, user floor plans, scores in metres, the figures of continuous
positions, and one-line errors that leave no outputs behind."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from topomap import TopologicalMap, Trajectory, load_trajectory, save_trajectory
from topomap.app.results import FIGURE_FILES, OUTPUT_FILES, PATH_FIGURES
from topomap.app.run.experiment import run
from topomap.app.run.outputs import own_files
from topomap.evaluation.metres import map_scores

pytest.importorskip("ratinabox")

from topomap.worlds.arena import ArenaWorld, RangeFinder  # noqa: E402

#: a short walk: a few hundred steps, a small map
SHORT = ["env=arena", "data.n_steps=300", "data.heldout_steps=150", "clusters.ns=6",
         "stop.n_states=10", "output.progress=false"]
#: a floor plan of two 1 x 1 m rooms side by side, a door in the wall between them
LAB = """\
boundary: [[0, 0], [2, 0], [2, 1], [0, 1]]
walls:
  - [[1, 0], [1, 0.35]]
  - [[1, 0.65], [1, 1]]
regions:
  left: [[0, 0], [1, 0], [1, 1], [0, 1]]
  right: [[1, 0], [2, 0], [2, 1], [1, 1]]
"""


def metrics_of(folder) -> dict:
    return json.loads((folder / "metrics.json").read_text())


def test_env_arena_runs_end_to_end_and_scores_in_metres(tmp_path, make_cfg):
    results = run(make_cfg(SHORT), tmp_path)
    for name in [*OUTPUT_FILES, *FIGURE_FILES, *PATH_FIGURES, "map.html"]:
        assert (tmp_path / name).is_file(), name
    traj = load_trajectory(tmp_path / "trajectory.npz")
    assert len(traj) == 300 and traj.places is None and traj.positions.shape == (300, 2)
    assert traj.observations.shape == (300, 12)  # the range finder's 12 beams by default
    assert ArenaWorld(layout="two_rooms").layout.inside(traj.positions).all()
    position = metrics_of(tmp_path)["position"]
    assert position == results["position"]
    assert position["regions"] == ["west", "corridor", "east"]
    assert position["heldout"].startswith("another random walk")
    assert position["heldout_steps"] == 150
    for scores in (position["map"], position["ceiling"], position["kmeans_views"],
                   position["kmeans_positions"]):
        assert scores["steps"] == 150 and scores["unplaced"] == 0
        assert 0 <= scores["median_error"] <= scores["p90_error"] <= np.hypot(2.5, 1.0)
        assert 0 <= scores["wrong_region"] <= 1


def test_the_map_entry_is_the_map_scored_on_the_held_out_walk(tmp_path, make_cfg):
    """The metres of metrics.json are those of the written map and states, on the held-out walk
    the world gives for the run's seed (its third random stream)."""
    from topomap.app.components.data import seed_streams
    from topomap.worlds.noise import GaussianNoise

    run(make_cfg(SHORT), tmp_path)
    m = TopologicalMap.load(tmp_path / "map.json")
    labels = np.loadtxt(tmp_path / "states.csv", delimiter=",", skiprows=1, dtype=int)[:, 2]
    world = ArenaWorld(layout="two_rooms")
    rng_sim, rng_noise = seed_streams(0)[2].spawn(2)
    held = world.heldout_walk(150, None, np.random.default_rng(rng_sim), after=300)
    held.observations = GaussianNoise(0.01).apply(held.observations,
                                                  np.random.default_rng(rng_noise))
    train = load_trajectory(tmp_path / "trajectory.npz")
    expected = map_scores(m, labels, train, held, world.region_of)
    assert metrics_of(tmp_path)["position"]["map"] == pytest.approx(expected)


def test_four_rooms_and_the_parts_from_the_command_line(tmp_path, make_cfg):
    cfg = make_cfg([*SHORT, "env.layout=four_rooms", "sensor=range", "sensor.n_beams=8",
                    "sensor.frame=egocentric", "actions=turns", "actions.angular_threshold=1.0"])
    run(cfg, tmp_path)
    traj = load_trajectory(tmp_path / "trajectory.npz")
    assert traj.observations.shape[1] == 8
    assert traj.action_names == ["forward", "turn_left", "turn_right", "stop"]
    assert np.all((traj.positions >= 0) & (traj.positions <= 2))
    position = metrics_of(tmp_path)["position"]
    assert position["regions"] == ["south-west", "south-east", "north-west", "north-east"]


def test_a_recorded_path_learns_its_start_and_holds_out_its_end(tmp_path, make_cfg):
    """sargolini at 10 Hz holds 5,996 steps: 300 are learned from its start, the last 200
    (5,796 to 5,995) held out."""
    run(make_cfg([*SHORT, "env.path=sargolini", "data.heldout_steps=200"]), tmp_path)
    traj = load_trajectory(tmp_path / "trajectory.npz")
    world = ArenaWorld(path="sargolini")
    assert np.allclose(traj.positions, world.walk_from(0, 300).positions)
    position = metrics_of(tmp_path)["position"]
    assert position["heldout"] == ("the last 200 steps of the path sargolini (steps 5796 to 5995 "
                                   "of 0.1 s)")
    assert position["regions"] == ["south-west", "south-east", "north-west", "north-east"]


def test_a_held_out_end_that_overlaps_the_steps_learned_is_refused(tmp_path, make_cfg):
    cfg = make_cfg([*SHORT, "env.path=sargolini", "data.n_steps=5000", "data.heldout_steps=2000"])
    with pytest.raises(ValueError, match=r"data.heldout_steps=2000 steps from the end of the path "
                                         r"sargolini overlap the 5000 steps learned from: .* at "
                                         r"most 996 are left"):
        run(cfg, tmp_path)
    assert own_files(tmp_path) == []


def test_a_user_floor_plan_and_a_user_path_through_the_command(tmp_path, make_cfg):
    """A path sampled every 0.1 s is resampled onto its own samples: the steps' positions are the
    file's rows."""
    (tmp_path / "lab.yaml").write_text(LAB)
    t = np.arange(0, 40.05, 0.1)
    xy = np.column_stack([1.0 + 0.8 * np.cos(t / 4), 0.5 + 0.3 * np.sin(t / 2)])
    np.savetxt(tmp_path / "rat.csv", np.column_stack([t, xy]), delimiter=",", header="t,x,y",
               comments="")
    out = tmp_path / "run"
    run(make_cfg([*SHORT, f"env.floorplan={tmp_path / 'lab.yaml'}",
                  f"env.path={tmp_path / 'rat.csv'}", "data.heldout_steps=100"]), out)
    traj = load_trajectory(out / "trajectory.npz")
    assert np.allclose(traj.positions, xy[:300], atol=1e-9)
    assert metrics_of(out)["position"]["regions"] == ["left", "right"]


@pytest.mark.parametrize("setting, message", [
    ("env.floorplan={dir}/bad.yaml", r"env=arena: env.floorplan=.*bad.yaml: walls\[0\]: a wall "
                                     r"needs two points"),
    ("env.path={dir}/no_times.npz", r"env=arena: env.path=.*no_times.npz: needs the arrays t and "
                                    r"pos \(or times and positions\), has pos"),
    ("env.path={dir}/flat.npz", r"env.path=.*flat.npz: the positions must have shape \(50, 2\) "
                                r"to match the 50 times, got \(50, 3\)"),
    ("sensor.max_range=0.01", r"^sensor.max_range=0.01 m is too short: beam 0 "),
])
def test_bad_arena_settings_are_one_line_and_leave_no_outputs(setting, message, tmp_path,
                                                              make_cfg):
    (tmp_path / "bad.yaml").write_text("boundary: [[0, 0], [1, 0], [1, 1], [0, 1]]\n"
                                       "walls:\n  - [[0.5, 0.5]]\n")
    np.savez(tmp_path / "no_times.npz", pos=np.full((50, 2), 0.5))
    np.savez(tmp_path / "flat.npz", t=np.arange(50.0), pos=np.full((50, 3), 0.5))
    out = tmp_path / "run"
    extra = (["sensor=range"] if setting.startswith("sensor.")
             else ["env.layout=open"] if setting.startswith("env.path") else [])
    cfg = make_cfg([*SHORT, *extra, setting.format(dir=tmp_path)])
    with pytest.raises(ValueError, match=message) as err:
        run(cfg, out)
    assert "\n" not in str(err.value)
    assert own_files(out) == []  # nothing half-written


def test_the_parts_go_to_a_world_that_takes_them(make_cfg, tmp_path):
    with pytest.raises(ValueError, match="sensor=range: env=office takes no sensor; env=arena "
                                         "does"):
        run(make_cfg(["sensor=range", "data.n_steps=50", "output.progress=false"]), tmp_path)
    with pytest.raises(ValueError, match="sensor.n_beams belongs to sensor=range, and no sensor is "
                                         "chosen; add sensor=range"):
        make_cfg(["env=arena", "sensor.n_beams=24"])


def test_the_arena_cannot_be_mapped_while_exploring(make_cfg, tmp_path):
    with pytest.raises(ValueError, match="moves by itself"):
        run(make_cfg([*SHORT, "data.update_every=100"]), tmp_path)


# ---------------------------------------------------------------------------- a sensor plugin
PLUGIN = '''
import numpy as np
from topomap import Component
from topomap.app.compose.hookspecs import hookimpl


class Compass:
    """A sensor that reads the heading: its cosine and its sine, times gain."""

    def __init__(self, gain: float = 1.0):
        self.gain = gain

    def sense(self, arena, motion):
        return self.gain * np.column_stack([np.cos(motion.heading), np.sin(motion.heading)])


@hookimpl
def topomap_register_components():
    return [Component("sensor", "heading", Compass, description="the heading, as a compass")]
'''


def test_a_plugin_registers_a_sensor(tmp_path, make_cfg):
    (tmp_path / "heading_sensor.py").write_text(PLUGIN)
    plugin = str(tmp_path / "heading_sensor.py")
    cfg = make_cfg([*SHORT, f"plugins=[{plugin}]", "sensor=heading", "sensor.gain=2.0",
                    "noise=none"])
    run(cfg, tmp_path / "run")
    traj = load_trajectory(tmp_path / "run" / "trajectory.npz")
    assert traj.observations.shape == (300, 2)
    assert np.allclose(np.hypot(*traj.observations.T), 2.0)  # a unit vector, times the gain


# ---------------------------------------------------------------------------- recordings
def _arena_walks(tmp_path):
    """Two walks of the open box with positions and no places, saved as recordings."""
    world = ArenaWorld(layout="open", sensor=RangeFinder(n_beams=8, max_range=2.0))
    for name, seed in (("train", 0), ("held", 1)):
        save_trajectory(world.simulate(400 if name == "train" else 200, None,
                                       np.random.default_rng(seed)), tmp_path / f"{name}.npz")


def test_a_recording_with_positions_is_scored_in_metres_and_drawn(tmp_path, make_cfg):
    _arena_walks(tmp_path)
    out = tmp_path / "run"
    run(make_cfg(["data=file", f"data.path={tmp_path / 'train.npz'}",
                  f"data.heldout_path={tmp_path / 'held.npz'}", "clusters.ns=6",
                  "stop.n_states=10", "output.progress=false"]), out)
    position = metrics_of(out)["position"]
    assert position["regions"] is None and position["heldout"] == "the held-out recording"
    assert position["map"]["wrong_region"] is None and position["map"]["steps"] == 200
    m = TopologicalMap.load(out / "map.json")
    labels = np.loadtxt(out / "states.csv", delimiter=",", skiprows=1, dtype=int)[:, 2]
    expected = map_scores(m, labels, load_trajectory(tmp_path / "train.npz"),
                          load_trajectory(tmp_path / "held.npz"))
    assert position["map"] == pytest.approx(expected)
    for name in ["fig_states.png", "fig_map.png", "fig_path.png", "map.html"]:
        assert (out / name).is_file(), name


def test_a_bag_with_a_position_topic_is_scored_in_metres(tmp_path, make_cfg):
    pytest.importorskip("rosbags")
    from topomap import write_rosbag

    _arena_walks(tmp_path)
    bags = {name: write_rosbag(load_trajectory(tmp_path / f"{name}.npz"), tmp_path / f"{name}.bag")
            for name in ("train", "held")}
    out = tmp_path / "run"
    results = run(make_cfg(["data=rosbag", f"data.path={bags['train']}",
                            f"data.heldout_path={bags['held']}", "data.observation_topic=/scan",
                            "data.action_topic=/action", "data.position_topic=/pose",
                            "clusters.ns=6", "stop.n_states=10", "output.progress=false"]), out)
    position = results["position"]
    assert position["map"]["steps"] == 200 and position["regions"] is None
    assert (out / "fig_path.png").is_file() and (out / "fig_map.png").is_file()


def test_a_recording_without_positions_still_gets_its_map_figure(tmp_path, make_cfg):
    _arena_walks(tmp_path)
    traj = load_trajectory(tmp_path / "train.npz")
    save_trajectory(Trajectory(observations=traj.observations, actions=traj.actions,
                               action_names=traj.action_names), tmp_path / "blind.npz")
    out = tmp_path / "run"
    results = run(make_cfg(["data=file", f"data.path={tmp_path / 'blind.npz'}", "clusters.ns=6",
                            "stop.n_states=10", "output.progress=false"]), out)
    assert "position" not in results
    assert (out / "fig_map.png").is_file() and (out / "fig_entropy.png").is_file()
    assert not (out / "fig_states.png").exists() and not (out / "fig_path.png").exists()


# ---------------------------------------------------------------------------- the command
def topomap(args, cwd, blocked=()):
    """``topomap <args>`` in a fresh process, with the modules ``blocked`` made unimportable."""
    code = ("import sys\n"
            f"for name in {list(blocked)!r}: sys.modules[name] = None\n"
            f"sys.argv = ['topomap', *{list(args)!r}]\n"
            "from topomap.app.cli import main\nmain()\n")
    return subprocess.run([sys.executable, "-c", code], cwd=cwd, capture_output=True, text=True,
                          timeout=600)


@pytest.mark.slow
def test_without_ratinabox_the_command_says_how_to_install(tmp_path):
    listed = topomap(["--list-plugins"], tmp_path, blocked=["ratinabox"])
    assert listed.returncode == 0, listed.stderr
    assert "arena" in listed.stdout and "range" in listed.stdout
    r = topomap(["env=arena", "env.layout=four_rooms"], tmp_path, blocked=["ratinabox"])
    assert r.returncode == 1
    (line,) = r.stderr.strip().splitlines()[-1:]
    assert line.startswith("topomap: error: env=arena: the arena world needs the optional "
                           "ratinabox package") and 'pip install "topomap[arena]"' in line
    assert len([x for x in r.stderr.splitlines() if x.startswith("topomap")]) == 1
    assert not (tmp_path / "outputs").exists()  # refused before its run folder was made


@pytest.mark.slow
def test_the_summary_line_and_a_sweep_compare_the_metres(tmp_path):
    r = topomap([*SHORT, "hydra.run.dir=one"], tmp_path)
    assert r.returncode == 0, r.stderr
    assert "localisation error (median / p90)" in r.stdout and "ceiling" in r.stdout
    assert "K-means on views" in r.stdout
    r = topomap(["-m", *SHORT, "env.layout=two_rooms,four_rooms",
                 "hydra.sweep.dir=sweep"], tmp_path)
    assert r.returncode == 0, r.stderr
    rows = (tmp_path / "sweep" / "summary.csv").read_text().splitlines()
    header = rows[0].split(",")
    for column in ("pos_error", "pos_error_p90", "wrong_region", "ceiling_error", "views_error"):
        cells = [row.split(",")[header.index(column)] for row in rows[1:]]
        assert len(cells) == 2 and all(float(c) >= 0 for c in cells), column
    assert "median localisation error, held-out [m]" in r.stdout  # the report shows the metres


def test_a_robot_mode_run_writes_the_cells_it_places_walks_on(tmp_path, make_cfg):
    """learner.motion.mode=robot: the run adds robot_map.npz, whose places are the map's states
    and on which a walk is placed by its own odometry."""
    from topomap.core.motion.robot_fit import predict_robot
    from topomap.core.motion.robot_io import load_robot_map

    run(make_cfg(["experiment=arena_robot", "learner.motion.mode=robot", "data.n_steps=3000",
                  "data.heldout_steps=300", "output.figures=false", "output.progress=false"]),
        tmp_path)
    cells = load_robot_map(tmp_path / "robot_map.npz")
    m = TopologicalMap.load(tmp_path / "map.json")
    assert m.info["motion_info"]["chosen"] == "robot"
    assert set(np.unique(cells.place)) <= set(range(m.n_states))
    walk = load_trajectory(tmp_path / "trajectory.npz")
    places = predict_robot(cells, walk.observations[:500], None, walk.odometry[:500])
    assert places.shape == (500,) and places.max() < m.n_states
    assert (tmp_path / "robot_map.npz") in own_files(tmp_path)
