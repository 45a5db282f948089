"""Sweeps (``topomap -m``): shared trajectories, held-out score, the sweep report, launchers."""

import csv
import json
import math
import re
import subprocess
import sys
from itertools import product
from pathlib import Path

import numpy as np
import pytest
from omegaconf import OmegaConf

from topomap import TopologicalMap, load_trajectory
from topomap.app.run.data import trajectory_key
from topomap.app.run.data import load_data
from topomap.app.run.experiment import run
from topomap.app.compose.registry import Registry
from topomap.app.report.callback import SweepReport
from topomap.app.report.cli import main as report_main
from topomap.app.report.summary import write_report
from topomap.app.results import METRICS
from topomap.app.run.job import run_job

PNG = b"\x89PNG\r\n\x1a\n"
SMALL = ["data.n_steps=200", "data.heldout_steps=150", "output.figures=false",
         "output.progress=false"]
# ns + 2 GDS states after phase 1: (ns=8, n_states=9) cannot run, the other three can
SWEEP = [*SMALL, "clusters.ns=6,8", "stop.n_states=9,12"]
GRID = [(ns, n) for ns, n in product((6, 8), (9, 12))]




def cli(args, cwd):
    proc = subprocess.Popen([sys.executable, "-m", "topomap", *args], cwd=cwd, text=True,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    out, err = proc.communicate(timeout=300)
    return subprocess.CompletedProcess(proc.args, proc.returncode, out, err), proc.pid


def the_sweep_dir(cwd) -> Path:
    (d,) = (Path(cwd) / "outputs" / "sweeps").glob("*/*")
    return d


def read_summary(sweep_dir):
    with open(sweep_dir / "summary.csv", newline="") as fh:
        return list(csv.DictReader(fh))


def by_setting(rows):
    return {(int(r["clusters.ns"]), int(r["stop.n_states"])): r for r in rows}


def status(job_dir):
    return json.loads((job_dir / "status.json").read_text())


@pytest.fixture(scope="module")
def basic(tmp_path_factory):
    cwd = tmp_path_factory.mktemp("basic")
    result, pid = cli(["-m", *SWEEP], cwd)
    assert result.returncode == 0, result.stderr
    return result, pid, the_sweep_dir(cwd)


# ---------------------------------------------------------------- the basic launcher
@pytest.mark.slow
def test_sweep_report_has_one_row_per_job_with_its_metrics(basic):
    result, pid, sweep = basic
    assert sweep.parents[1].name == "sweeps" and sweep.parents[2].name == "outputs"
    assert re.fullmatch(r"\d\d-\d\d-\d\d-\d{6}", sweep.name)  # sub-second time stamp
    rows = read_summary(sweep)
    assert len(rows) == 4
    header = list(rows[0])
    assert header[:4] == ["job", "clusters.ns", "stop.n_states", "status"]
    assert "data.n_steps" not in header  # given once, not swept
    assert set(METRICS) <= set(header) and {"error", "output_dir"} <= set(header)
    table = by_setting(rows)
    assert sorted(table) == GRID
    for (ns, n), row in table.items():
        job = sweep / row["output_dir"]
        assert status(job)["pid"] == pid  # the basic launcher runs every job in its own process
        if (ns, n) == (8, 9):
            assert row["status"] == "failed" and status(job)["status"] == "failed"
            assert "stop.n_states=9 is below the 10 states" in row["error"]
            assert row["ari"] == row["heldout_loglik"] == "" and not (job / "map.json").exists()
            continue
        m = json.loads((job / "metrics.json").read_text())
        assert row["status"] == "completed" and row["error"] == ""
        assert int(row["n_states"]) == m["n_states"]["final"] == n
        for col in ("ari", "nmi", "purity"):
            assert float(row[col]) == m["ground_truth"]["final"][col]
        assert float(row["ari_phase1"]) == m["ground_truth"]["phase1"]["ari"]
        for col in ("H_o", "H_u", "H_x"):
            assert float(row[col]) == m["entropies"]["final"][col]
        assert float(row["heldout_loglik"]) == m["heldout_loglik"]
        assert math.isfinite(m["heldout_loglik"]) and m["heldout_steps"] == 150
        assert float(row["fit_time"]) == pytest.approx(m["timings"]["phase1"] + m["timings"]["phase2"])
    assert "sweep of 4 jobs, 3 completed, 1 failed" in result.stdout
    fig = sweep / "summary_ari.png"
    assert fig.read_bytes()[:8] == PNG
    import matplotlib.image

    h, w = matplotlib.image.imread(fig).shape[:2]
    assert h > 100 and w > 100


@pytest.mark.slow
def test_sweep_jobs_learn_from_one_shared_trajectory(basic, tmp_path, make_cfg):
    _, _, sweep = basic
    cache = sweep / ".cache"
    (train,) = cache.glob("trajectory-*.npz")
    (held,) = cache.glob("heldout-*.npz")
    cached = load_trajectory(train)
    rows = by_setting(read_summary(sweep))
    for setting, row in rows.items():
        if row["status"] != "completed":
            continue
        traj = load_trajectory(sweep / row["output_dir"] / "trajectory.npz")
        assert np.array_equal(traj.observations, cached.observations)
        assert np.array_equal(traj.actions, cached.actions)
    held_traj = load_trajectory(held)
    assert len(held_traj) == 150 and not np.array_equal(held_traj.observations[:150],
                                                        cached.observations[:150])
    # a single run simulates afresh: the same trajectory and the same map, byte for byte
    cfg = make_cfg([*SMALL, "clusters.ns=6", "stop.n_states=12"])
    results = run(cfg, tmp_path / "single")
    job = sweep / rows[6, 12]["output_dir"]
    assert (tmp_path / "single" / "map.json").read_bytes() == (job / "map.json").read_bytes()
    assert results["heldout_loglik"] == json.loads((job / "metrics.json").read_text())["heldout_loglik"]


# ---------------------------------------------------------------- other launchers
@pytest.mark.slow
def test_joblib_two_workers_give_the_same_report_and_maps(basic, tmp_path):
    pytest.importorskip("hydra_plugins.hydra_joblib_launcher")
    _, _, sweep0 = basic
    result, pid = cli(["-m", *SWEEP, "hydra/launcher=joblib", "hydra.launcher.n_jobs=2"], tmp_path)
    assert result.returncode == 0, result.stderr
    assert "Joblib.Parallel(n_jobs=2" in result.stdout + result.stderr
    sweep = the_sweep_dir(tmp_path)
    rows, rows0 = by_setting(read_summary(sweep)), by_setting(read_summary(sweep0))
    assert sorted(rows) == GRID
    same = ["status", "n_states", "ari", "nmi", "purity", "compound_states", "H_u", "H_x",
            "heldout_loglik", "error"]
    pids = set()
    for setting, row in rows.items():
        assert [row[c] for c in same] == [rows0[setting][c] for c in same], setting
        job, job0 = sweep / row["output_dir"], sweep0 / rows0[setting]["output_dir"]
        pids.add(status(job)["pid"])
        if row["status"] == "completed":
            assert (job / "map.json").read_bytes() == (job0 / "map.json").read_bytes()
    assert rows[8, 9]["status"] == "failed" and "is below the 10 states" in rows[8, 9]["error"]
    assert pid not in pids and 1 <= len(pids) <= 2  # jobs ran in (at most 2) worker processes
    assert len(list((sweep / ".cache").glob("trajectory-*.npz"))) == 1
    assert (sweep / "summary_ari.png").read_bytes()[:8] == PNG


@pytest.mark.slow
def test_submitit_local_gives_the_same_maps_and_a_line_for_one_swept_key(basic, tmp_path):
    pytest.importorskip("hydra_plugins.hydra_submitit_launcher")
    _, _, sweep0 = basic
    result, pid = cli(["-m", *SMALL, "clusters.ns=8", "stop.n_states=9,12",
                       "hydra/launcher=submitit_local"], tmp_path)
    assert result.returncode == 0, result.stderr
    sweep = the_sweep_dir(tmp_path)
    assert (sweep / ".submitit").is_dir()
    rows = read_summary(sweep)
    assert [r["stop.n_states"] for r in rows] == ["9", "12"] and "clusters.ns" not in rows[0]
    failed, done = rows
    assert failed["status"] == "failed" and "is below the 10 states" in failed["error"]
    assert done["status"] == "completed" and int(done["n_states"]) == 12
    job0 = sweep0 / by_setting(read_summary(sweep0))[8, 12]["output_dir"]
    job = sweep / done["output_dir"]
    assert (job / "map.json").read_bytes() == (job0 / "map.json").read_bytes()
    assert status(job)["pid"] != pid
    assert (sweep / "summary_ari.png").read_bytes()[:8] == PNG


@pytest.mark.slow
def test_ray_runs_two_jobs_on_a_local_cluster_logged_to_one_mlflow_experiment(basic, tmp_path):
    pytest.importorskip("hydra_plugins.hydra_ray_launcher")
    pytest.importorskip("mlflow")
    from mlflow.tracking import MlflowClient

    _, _, sweep0 = basic
    result, pid = cli(["-m", *SMALL, "clusters.ns=6,8", "stop.n_states=12",
                       "hydra/launcher=ray",
                       "logger=mlflow", "logger.experiment=ray_sweep"], tmp_path)
    assert result.returncode == 0, result.stderr
    assert "Started a local Ray instance" in result.stdout + result.stderr
    sweep = the_sweep_dir(tmp_path)
    rows = {(int(r["clusters.ns"]), 12): r for r in read_summary(sweep)}  # ns alone is swept
    rows0 = by_setting(read_summary(sweep0))
    assert sorted(rows) == [(6, 12), (8, 12)]
    for setting, row in rows.items():
        assert row["status"] == "completed" and row["ari"] == rows0[setting]["ari"]
        job, job0 = sweep / row["output_dir"], sweep0 / rows0[setting]["output_dir"]
        assert (job / "map.json").read_bytes() == (job0 / "map.json").read_bytes()
        assert status(job)["pid"] != pid  # a Ray worker ran it
    client = MlflowClient(tracking_uri=f"sqlite:///{tmp_path / 'outputs' / 'mlflow.db'}")
    every = client.search_runs([client.get_experiment_by_name("ray_sweep").experiment_id])
    (parent,) = [r for r in every if "mlflow.parentRunId" not in r.data.tags]  # the sweep's
    runs = [r for r in every if r is not parent]
    assert {r.data.tags["mlflow.parentRunId"] for r in runs} == {parent.info.run_id}
    assert "summary.csv" in {a.path for a in client.list_artifacts(parent.info.run_id)}
    assert sorted(r.data.params["clusters.ns"] for r in runs) == ["6", "8"]
    assert {r.data.tags["topomap.sweep_dir"] for r in every} == {str(sweep.resolve())}
    assert sorted(r.info.run_name for r in runs) == [f"{sweep.name}/0", f"{sweep.name}/1"]


# ---------------------------------------------------------------- an Optuna search
@pytest.mark.slow
def test_optuna_search_maximises_the_objective_and_is_reported(tmp_path):
    pytest.importorskip("hydra_plugins.hydra_optuna_sweeper")
    args = ["-m", *SMALL, "hydra/sweeper=optuna", "hydra.sweeper.n_trials=6",
            "clusters.ns=int(interval(4,10))", "stop.n_states=int(interval(8,16))"]
    result, _ = cli(args, tmp_path)
    assert result.returncode == 0, result.stderr
    sweep = the_sweep_dir(tmp_path)
    rows = read_summary(sweep)
    assert len(rows) == 6 and list(rows[0])[1:3] == ["clusters.ns", "stop.n_states"]
    done = [r for r in rows if r["status"] == "completed"]
    assert done and all(r["status"] == "failed" and "is below the" in r["error"]
                        for r in rows if r not in done)
    for r in rows:
        assert 4 <= int(r["clusters.ns"]) <= 10 and 8 <= int(r["stop.n_states"]) <= 16
    best = max(done, key=lambda r: float(r["heldout_loglik"]))
    found = OmegaConf.load(sweep / "optimization_results.yaml")
    assert found.best_value == float(best["heldout_loglik"])  # maximised, not minimised
    assert found.best_params == {"clusters.ns": int(best["clusters.ns"]),
                                 "stop.n_states": int(best["stop.n_states"])}
    assert (sweep / "summary_heldout_loglik.png").read_bytes()[:8] == PNG
    assert f"best heldout_loglik: {float(best['heldout_loglik']):.4g}" in result.stdout
    (tmp_path / "again").mkdir()
    again, _ = cli(args, tmp_path / "again")  # the sampler follows the seed: the same trials
    assert again.returncode == 0, again.stderr
    rows_again = read_summary(the_sweep_dir(tmp_path / "again"))
    assert [(r["clusters.ns"], r["stop.n_states"], r["heldout_loglik"]) for r in rows_again] == \
        [(r["clusters.ns"], r["stop.n_states"], r["heldout_loglik"]) for r in rows]


def test_optuna_presets_maximise_and_the_paper_preset_searches_its_knobs(make_cfg):
    pytest.importorskip("hydra_plugins.hydra_optuna_sweeper")
    plain = make_cfg(["hydra/sweeper=optuna"], hydra=True).hydra.sweeper
    assert plain.direction == "maximize" and plain.sampler.seed == 0
    assert plain._target_.endswith("optuna_sweeper.OptunaSweeper")
    paper = make_cfg(["hydra/sweeper=optuna_pricai2002", "seed=3"], hydra=True)
    assert paper.hydra.sweeper.direction == "maximize" and paper.hydra.sweeper.n_trials == 30
    assert dict(paper.hydra.sweeper.params) == {"clusters.ns": "int(interval(10, 40))",
                                                "stop.n_states": "int(interval(20, 80))"}
    assert paper.hydra.sweeper.sampler.seed == 3
    assert paper.objective.value == "heldout_loglik"
    assert make_cfg(["objective=ari"]).objective.value == "ari"


def test_a_search_the_wrong_way_stops_before_its_first_job():
    from topomap.app.compose.config_checks import check_search_direction

    report = SweepReport()
    for objective in ("heldout_loglik", "ari"):
        config = OmegaConf.create({"objective": objective,
                                   "hydra": {"sweeper": {"direction": "minimize"}}})
        with pytest.raises(ValueError, match=f"^hydra.sweeper.direction=minimize, but "
                                             f"objective={objective} is better when larger"):
            check_search_direction(config)
        config.hydra.sweeper.direction = "maximize"
        check_search_direction(config)  # goes on
        assert report.metric_of(config) == objective
    grid = OmegaConf.create({"objective": "ari", "hydra": {"sweeper": {"params": None}}})
    check_search_direction(grid)
    assert report.metric_of(grid) == "ari" and SweepReport("nmi").metric_of(grid) == "nmi"


def test_ray_cluster_preset_joins_a_running_cluster(make_cfg):
    pytest.importorskip("hydra_plugins.hydra_ray_launcher")
    launcher = make_cfg(["hydra/launcher=ray_cluster"], hydra=True).hydra.launcher
    assert launcher._target_.endswith("ray_launcher.RayLauncher")
    assert launcher.ray.init == {"address": "auto", "object_store_memory": None}
    other = make_cfg(["hydra/launcher=ray_cluster", "hydra.launcher.ray.init.address=10.0.0.1:6379"],
                     hydra=True)
    assert other.hydra.launcher.ray.init.address == "10.0.0.1:6379"


def test_the_objective_needs_its_data_and_names_the_keys(tmp_path, make_cfg):
    from topomap.app.run.evaluate import objective_value

    cfg = make_cfg([*SMALL, "data.heldout_steps=0"])
    with pytest.raises(ValueError, match="objective=heldout_loglik needs held-out data: "
                                         "data.heldout_steps > 0"):
        run(cfg, tmp_path / "a", needs_objective=True)
    assert not (tmp_path / "a").exists()
    results = run(cfg, tmp_path / "b")  # a single run does without
    assert results["objective"] == {"name": "heldout_loglik", "value": None}
    results = run(make_cfg([*SMALL, "objective=ari"]), tmp_path / "c", needs_objective=True)
    assert results["objective"]["value"] == results["ground_truth"]["final"]["ari"]
    assert objective_value(results, "heldout_loglik") == results["heldout_loglik"]
    with pytest.raises(ValueError, match=r"^objective=nll is not one of heldout_loglik, ari$"):
        make_cfg(["objective=nll"])


# ---------------------------------------------------------------- the report on its own
def test_report_lists_crashed_and_unfinished_jobs(tmp_path, monkeypatch, make_cfg):
    def job_dir(num, overrides):
        d = tmp_path / str(num)
        (d / ".hydra").mkdir(parents=True)
        (d / ".hydra" / "overrides.yaml").write_text(OmegaConf.to_yaml(overrides))
        return d

    cfg = make_cfg([*SMALL, "clusters.ns=6", "stop.n_states=10"])
    assert run_job(cfg, job_dir(0, ["stop.n_states=10"]), sweep_dir=tmp_path) is not None

    def crash(*args, **kwargs):
        raise RuntimeError("disk on fire")

    monkeypatch.setattr("topomap.app.run.job.run", crash)
    assert run_job(cfg, job_dir(1, ["stop.n_states=11"]), sweep_dir=tmp_path) is None
    st = status(tmp_path / "1")
    assert st["status"] == "failed" and st["error"] == "RuntimeError: disk on fire"
    assert "Traceback" in st["traceback"]
    job_dir(2, ["stop.n_states=12"])  # started, never finished
    report = write_report(tmp_path, metric="nmi")
    assert report.keys == ["stop.n_states"]
    assert [(r["stop.n_states"], r["status"]) for r in report.rows] == [
        ("10", "completed"), ("11", "failed"), ("12", "incomplete")]
    assert report.rows[1]["error"] == "RuntimeError: disk on fire"
    assert report.best["job"] == 0 and report.figure.name == "summary_nmi.png"
    m = json.loads((tmp_path / "0" / "metrics.json").read_text())
    assert report.rows[0]["nmi"] == m["ground_truth"]["final"]["nmi"]


@pytest.mark.slow
def test_report_callback_options_and_command(basic, capsys):
    _, _, sweep = basic
    config = OmegaConf.create({"hydra": {"sweep": {"dir": str(sweep)},
                                         "overrides": {"task": SWEEP}}})
    with pytest.raises(SystemExit, match="1 of 4 jobs did not complete"):
        SweepReport(strict=True).on_multirun_end(config=config)
    SweepReport(metric="heldout_loglik").on_multirun_end(config=config)  # no exit
    assert (sweep / "summary_heldout_loglik.png").read_bytes()[:8] == PNG
    with pytest.raises(ValueError, match="not a summary column"):
        SweepReport(metric="accuracy")
    assert report_main([str(sweep), "--metric", "purity"]) == 0
    assert "best purity" in capsys.readouterr().out
    assert (sweep / "summary_purity.png").read_bytes()[:8] == PNG
    assert len(read_summary(sweep)) == 4


# ---------------------------------------------------------------- trajectories and held-out data
def test_only_world_settings_change_the_cached_trajectory(tmp_path, make_cfg):
    base = make_cfg(SMALL)
    key = trajectory_key(OmegaConf.to_container(base, resolve=True))

    def k(overrides, kind="train"):
        return trajectory_key(OmegaConf.to_container(make_cfg([*SMALL, *overrides]), resolve=True),
                              kind)

    assert k(["clusters.ns=9", "stop.n_states=15", "metric=cosine"]) == key
    assert k(["data.heldout_steps=99"]) == key
    assert k(["data.heldout_steps=99"], "heldout") != k([], "heldout")
    for world in (["seed=1"], ["noise.sigma=0.02"], ["data.n_steps=201"], ["env.view_range=2.0"]):
        assert k(world) != key, world
    cache = tmp_path / "cache"
    for i, extra in enumerate([["stop.n_states=12"], ["stop.n_states=13"], ["noise.sigma=0.02"]]):
        run(make_cfg([*SMALL, "clusters.ns=8", *extra]), tmp_path / str(i), cache_dir=cache)
    assert len(list(cache.glob("trajectory-*.npz"))) == 2
    assert len(list(cache.glob("heldout-*.npz"))) == 2


def test_heldout_loglik_scores_a_second_walk_through_the_same_world(tmp_path, make_cfg):
    cfg = make_cfg([*SMALL, "clusters.ns=8", "stop.n_states=12"])
    results = run(cfg, tmp_path / "a")
    container = OmegaConf.to_container(cfg, resolve=True)
    registry = Registry.load()
    (train, held), _ = load_data(container, registry.build(container), registry)
    assert len(held) == 150 and held.observations.shape[1] == train.observations.shape[1]
    assert not np.array_equal(held.places[:50], train.places[:50])
    m = TopologicalMap.load(tmp_path / "a" / "map.json")
    expected = m.score(held.observations, held.actions, gds=held.gds, lengths=held.lengths)
    assert results["heldout_loglik"] == pytest.approx(expected, rel=1e-12)
    assert results["heldout_loglik"] != pytest.approx(
        m.score(train.observations, train.actions, gds=train.gds), rel=1e-6)

    none = run(make_cfg([*SMALL, "clusters.ns=8", "stop.n_states=12", "data.heldout_steps=0"]),
               tmp_path / "b")
    assert none["heldout_loglik"] is None and none["heldout_steps"] == 0
    assert json.loads((tmp_path / "b" / "metrics.json").read_text())["heldout_loglik"] is None


def test_heldout_file_for_recorded_data(tmp_path, make_cfg):
    run(make_cfg([*SMALL, "clusters.ns=8", "stop.n_states=12"]), tmp_path / "sim")
    rec = str(tmp_path / "sim" / "trajectory.npz")
    file_cfg = ["data=file", f"data.path={rec}", "clusters.ns=8", "stop.n_states=12",
                "output.figures=false", "output.progress=false"]
    assert run(make_cfg(file_cfg), tmp_path / "a")["heldout_loglik"] is None
    scored = run(make_cfg([*file_cfg, f"data.heldout_path={rec}"]), tmp_path / "b")
    m = TopologicalMap.load(tmp_path / "b" / "map.json")
    t = load_trajectory(rec)
    assert scored["heldout_loglik"] == pytest.approx(m.score(t.observations, t.actions, gds=t.gds))
    with pytest.raises(ValueError, match="does not exist"):
        run(make_cfg([*file_cfg, "data.heldout_path=nope.npz"]), tmp_path / "c")
    assert not (tmp_path / "c").exists()


# ---------------------------------------------------------------- shipped configs
def test_sweep_preset_and_slurm_example_compose(make_cfg):
    cfg = make_cfg(["experiment=sweep_pricai2002"], hydra=True)
    assert cfg.hydra.mode.name == "MULTIRUN"
    params = cfg.hydra.sweeper.params
    ns = [int(v) for v in str(params["clusters.ns"]).split(",")]
    n_states = [int(v) for v in str(params["stop.n_states"]).split(",")]
    assert (min(ns), max(ns), min(n_states), max(n_states)) == (10, 40, 20, 50)
    paper = make_cfg(["experiment=pricai2002"])
    for key in ("env", "noise", "explorer", "data", "seed", "clusters", "stop"):
        assert cfg[key] == paper[key], key
    assert cfg.hydra.callbacks.sweep_report._target_ == "topomap.app.report.callback.SweepReport"

    pytest.importorskip("hydra_plugins.hydra_submitit_launcher")
    slurm = make_cfg(["hydra/launcher=slurm", "hydra.launcher.partition=short"], hydra=True)
    launcher = slurm.hydra.launcher
    assert launcher._target_.endswith("submitit_launcher.SlurmLauncher")
    assert launcher.partition == "short" and launcher.timeout_min > 0 and launcher.mem_gb > 0
