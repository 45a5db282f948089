"""A run that cannot meet what it was told says so: a state count the split cannot reach is a
warning with the reason, a cluster count too close to the number of steps is refused or warned."""

import logging

import numpy as np
import pytest

from topomap.app.run.checks import STEPS_PER_SYMBOL
from topomap.app.run.experiment import run

SMALL_STEPS = 300
SMALL = [f"data.n_steps={SMALL_STEPS}", "data.heldout_steps=0", "output.progress=false",
         "output.figures=false"]


def warnings_of(caplog) -> list[str]:
    return [r.getMessage() for r in caplog.records
            if r.name == "topomap" and r.levelno == logging.WARNING]


def test_a_state_count_the_split_cannot_reach_is_a_warning_with_the_reason(make_cfg, tmp_path,
                                                                           caplog):
    caplog.set_level(logging.INFO, logger="topomap")
    """A walk around a cycle of three views with one action: no state is aliased, so the split
    cannot go past the three symbols, whatever the told count."""
    import numpy as np

    from topomap import Trajectory, save_trajectory

    cycle = save_trajectory(Trajectory(observations=np.tile(np.eye(3), (100, 1)),
                                       actions=np.zeros(300, dtype=int)), tmp_path / "cycle.npz")
    results = run(make_cfg(["data=file", f"data.path={cycle}", "output.progress=false",
                            "output.figures=false", "clusters.ns=3", "stop.n_states=10"]),
                  tmp_path / "out")
    assert results["n_states"]["final"] == 3 and results["stop_reason"] == "no state can be split"
    assert warnings_of(caplog) == ["stop.n_states=10 not reached: the split stopped at 3 states "
                                   "(no state can be split)"]


def test_a_reached_state_count_is_not_warned_about(make_cfg, tmp_path, caplog):
    caplog.set_level(logging.INFO, logger="topomap")
    run(make_cfg([*SMALL, "clusters.ns=8", "stop.n_states=12"]), tmp_path)
    assert warnings_of(caplog) == []


def test_more_clusters_than_half_the_steps_are_refused(make_cfg, tmp_path):
    cfg = make_cfg([*SMALL, "clusters.ns=200", "stop=min_gain"])
    with pytest.raises(ValueError, match=r"^clusters.ns=200 is more than half of the \d+ steps "
                                         r"to cluster.*give at most clusters.ns=\d+"):
        run(cfg, tmp_path / "out")
    assert not (tmp_path / "out").exists()


def test_few_steps_per_cluster_are_warned_about(make_cfg, tmp_path, caplog):
    caplog.set_level(logging.INFO, logger="topomap")
    run(make_cfg([*SMALL, "clusters.ns=40", "stop.n_states=45"]), tmp_path)
    (line,) = [w for w in warnings_of(caplog) if w.startswith("clusters.ns=40")]
    steps = int(line.split("(")[1].split()[0])  # the steps to cluster, as the warning counts them
    assert steps < 40 * STEPS_PER_SYMBOL
    assert f"leaves {steps / 40:.1f} steps per symbol on average" in line, line


def test_a_state_count_below_what_bic_can_choose_is_refused_before_bic(make_cfg, tmp_path,
                                                                       monkeypatch):
    from topomap.core.phase1.clustering import BICClusters

    def no_bic(self, Z, random_state):
        raise AssertionError("BIC ran before the check")

    monkeypatch.setattr(BICClusters, "choose", no_bic)
    with pytest.raises(ValueError) as err:
        run(make_cfg(["clusters=bic", "clusters.min_ns=30", "output.progress=false"]),
            tmp_path / "out")
    assert str(err.value).startswith("stop.n_states=30 is below the 32 states")
    assert not (tmp_path / "out").exists()


def test_bic_searches_only_the_counts_the_told_size_leaves_room_for():
    # the office has 2 GDS: 30 states told leave room for 28 clusters; BIC over 5..40 picks 34
    # on the default walk, so searched up to 28 it picks at most 28, and the run reaches 30
    from topomap import MapLearner
    from topomap.core.phase1.clustering import BICClusters
    from topomap.worlds import GaussianNoise, OfficeWorld, RandomExplorer

    rng = np.random.default_rng(0)
    traj = OfficeWorld().simulate(600, RandomExplorer(), rng)
    traj.observations = GaussianNoise(0.01).apply(traj.observations, rng)
    policy = BICClusters(min_ns=20, max_ns=34)
    learner = MapLearner(n_states=30, clusters=policy).fit_trajectory(traj)
    assert max(learner.cluster_choice_["bic"]) == 28
    assert learner.n_clusters_ <= 28 and learner.map_.n_states == 30
    assert learner.map_.info["clusters"] == repr(policy) == "BICClusters(min_ns=20, max_ns=34, step=1)"


def test_a_state_count_that_leaves_bic_room_runs(make_cfg, tmp_path):
    results = run(make_cfg([*SMALL, "clusters=bic", "clusters.max_ns=12",
                            "stop.n_states=14"]), tmp_path)
    assert results["n_states"]["phase1"] <= 14 == results["n_states"]["final"]
