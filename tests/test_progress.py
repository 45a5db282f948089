"""Progress on a terminal for every long stage: BIC, the EM refinement, held-out scoring and
drawing the figures (tqdm bars on stderr; none when stderr is not a terminal or with
``output.progress=false``)."""

import sys

import numpy as np
import pytest

from topomap import MapLearner
from topomap.app.run.experiment import run
from topomap.core.phase1.clustering import BICClusters
from topomap.core.progress import reporting

SMALL = ["data.n_steps=300", "data.heldout_steps=100", "clusters=bic", "clusters.min_ns=4",
         "clusters.max_ns=8", "stop.n_states=12", "refine=em"]


def test_the_cores_loops_report_their_progress():
    from topomap.worlds.explorers import RandomExplorer
    from topomap.worlds.table.gridroom import GridRoom

    traj = GridRoom(width=4, height=4, n_symbols=3, seed=1).simulate(
        400, RandomExplorer(), np.random.default_rng(0))
    X = traj.observations + np.random.default_rng(1).normal(0, 0.05, traj.observations.shape)
    seen = []
    with reporting(lambda stage, done, total: seen.append((stage, done, total))):
        MapLearner(clusters=BICClusters(2, 5), n_states=20, refine="em", n_init=1).fit(
            X, traj.actions)
        MapLearner(n_clusters=3, n_states="auto", n_init=1).fit(X, traj.actions)
    stages = {s for s, _, _ in seen}
    assert {"BIC", "EM", "held-out scoring"} <= stages
    assert [(d, t) for s, d, t in seen if s == "BIC"] == [(0, 4), (1, 4), (2, 4), (3, 4), (4, 4)]
    for stage in stages:  # every loop ends with a last report, done == total
        assert any(d == t for s, d, t in seen if s == stage)
    MapLearner(n_clusters=3, n_states=20).fit(X, traj.actions)  # no listener: nothing reported


def terminal(monkeypatch):
    monkeypatch.setattr(sys.stderr, "isatty", lambda: True)


def test_a_run_on_a_terminal_shows_a_bar_per_stage(make_cfg, tmp_path, capsys, monkeypatch):
    terminal(monkeypatch)
    run(make_cfg(SMALL), tmp_path)
    err = capsys.readouterr().err
    for stage in ("simulating", "BIC", "splitting", "EM", "held-out scoring", "drawing figures"):
        assert f"{stage}:" in err, stage


@pytest.mark.parametrize("override", ["output.progress=false"])
def test_no_bar_when_progress_is_off(make_cfg, tmp_path, capsys, monkeypatch, override):
    terminal(monkeypatch)
    run(make_cfg([*SMALL, override]), tmp_path)
    assert "BIC" not in capsys.readouterr().err


def test_no_bar_when_stderr_is_not_a_terminal(make_cfg, tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(sys.stderr, "isatty", lambda: False)
    run(make_cfg(SMALL), tmp_path)
    assert "BIC" not in capsys.readouterr().err
