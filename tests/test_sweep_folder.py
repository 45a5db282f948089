"""A sweep into a folder that holds another sweep: refused before its first job, resumed with
``output.resume=true``, and a report that never shows a job's result under other settings."""

import csv
import json
import os
import subprocess
import sys

import pytest
from omegaconf import OmegaConf

from topomap.app.report.jobs import check_sweep_folder, read_jobs

SMALL = ["data.n_steps=200", "data.heldout_steps=0", "output.figures=false",
         "output.progress=false", "stop.n_states=14"]


def topomap(args, cwd):
    env = dict(os.environ, TOPOMAP_DISABLE_PLUGIN_AUTOLOAD="1")
    return subprocess.run([sys.executable, "-m", "topomap", *args], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=300)


def job_folder(sweep, num, overrides, metrics_config=None, status="completed"):
    """A job folder as a sweep leaves it: Hydra's overrides, status.json, metrics.json."""
    folder = sweep / str(num)
    (folder / ".hydra").mkdir(parents=True)
    (folder / ".hydra" / "overrides.yaml").write_text(OmegaConf.to_yaml(list(overrides)))
    (folder / "status.json").write_text(json.dumps({"status": status}))
    if metrics_config is not None:
        (folder / "metrics.json").write_text(json.dumps({"config": metrics_config,
                                                         "n_states": {"final": 3}}))
    return folder


def grid(*overrides):
    return OmegaConf.create({"hydra": {
        "sweeper": {"params": None}, "runtime": {"choices": {"hydra/sweeper": "basic"}},
        "overrides": {"task": list(overrides)}}})


def test_a_used_sweep_folder_is_refused_naming_hydra_sweep_dir(tmp_path):
    job_folder(tmp_path, 0, ["clusters.ns=10"], {"clusters": {"ns": 10}})
    with pytest.raises(ValueError, match=rf"^hydra.sweep.dir={tmp_path} already holds a sweep "
                                         r"\(1 job folders\); choose another hydra.sweep.dir, "
                                         r"or give output.resume=true"):
        check_sweep_folder(tmp_path, grid("clusters.ns=20,25"), resume=False)
    assert check_sweep_folder(tmp_path / "new", grid("clusters.ns=20,25"), resume=False) == []


def test_resume_goes_on_with_the_same_sweep_only(tmp_path):
    job_folder(tmp_path, 0, ["clusters.ns=10"], {"clusters": {"ns": 10}})
    with pytest.raises(ValueError, match=r"holds job 0 of another sweep \(clusters.ns=10\)"):
        check_sweep_folder(tmp_path, grid("clusters.ns=20,25", "output.resume=true"), True)
    (job,) = check_sweep_folder(tmp_path, grid("clusters.ns=10,15", "output.resume=true"), True)
    assert job.num == 0


def test_the_report_never_shows_a_result_under_other_settings(tmp_path):
    """Job 0's folder says clusters.ns=20 (Hydra wrote it) but holds the metrics of a run with
    clusters.ns=10: not a completed job of the sweep."""
    job_folder(tmp_path, 0, ["clusters.ns=20", "env=office"],
               {"clusters": {"component": "fixed", "ns": 10}, "env": {"component": "office"}})
    job_folder(tmp_path, 1, ["clusters.ns=25", "env=office"],
               {"clusters": {"component": "fixed", "ns": 25}, "env": {"component": "office"}})
    first, second = read_jobs(tmp_path)
    assert first.status == "incomplete" and first.metrics == {}
    assert "holds the results of a run of other settings" in first.error
    assert second.status == "completed"


@pytest.mark.slow
def test_a_second_sweep_into_one_folder_is_refused_then_resumed(tmp_path):
    sweep = tmp_path / "sweep"
    first = topomap(["-m", *SMALL, f"hydra.sweep.dir={sweep}", "clusters.ns=5,6"], tmp_path)
    assert first.returncode == 0, first.stderr
    summary = (sweep / "summary.csv").read_text()
    other = topomap(["-m", *SMALL, f"hydra.sweep.dir={sweep}", "clusters.ns=7,8"], tmp_path)
    assert other.returncode == 1 and other.stderr.splitlines() == [
        f"topomap: error: hydra.sweep.dir={sweep} already holds a sweep (2 job folders); "
        "choose another hydra.sweep.dir, or give output.resume=true to run only the jobs it "
        "has not completed"]
    assert (sweep / "summary.csv").read_text() == summary and not (sweep / "2").exists()
    more = topomap(["-m", *SMALL, f"hydra.sweep.dir={sweep}", "clusters.ns=5,6,7",
                    "output.resume=true"], tmp_path)
    assert more.returncode == 0, more.stderr
    assert more.stdout.count("completed before with the same config") == 2
    with open(sweep / "summary.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert [(r["clusters.ns"], r["status"]) for r in rows] == [
        ("5", "completed"), ("6", "completed"), ("7", "completed")]
    assert [r["n_states_phase1"] for r in rows] == ["7", "8", "9"]  # ns + 2 GDS, each its own


# ---------------------------------------------------------------- a search's study
def test_a_study_is_written_as_it_goes_and_a_later_one_goes_on_with_it(tmp_path):
    """Two trials of a study (one completed, one failed) written to study.json; a study that
    resumes from that folder starts with both, the same parameters, values and states."""
    optuna = pytest.importorskip("optuna")
    from topomap.app.compose.study import STUDY_FILE, SweepStudy

    first = optuna.create_study(storage=SweepStudy(str(tmp_path / "a")), study_name="topomap",
                                direction="maximize", load_if_exists=True)
    t = first.ask({"ns": optuna.distributions.IntUniformDistribution(4, 10)})
    first.tell(t, 1.5)
    t = first.ask({"ns": optuna.distributions.IntUniformDistribution(4, 10)})
    first.tell(t, state=optuna.trial.TrialState.FAIL)
    saved = json.loads((tmp_path / "a" / STUDY_FILE).read_text())["trials"]
    assert [(s["state"], s["values"]) for s in saved] == [("COMPLETE", [1.5]), ("FAIL", None)]
    later = optuna.create_study(storage=SweepStudy(str(tmp_path / "b"), resume_from=str(tmp_path / "a")),
                                study_name="topomap", direction="maximize", load_if_exists=True)
    assert [(x.state.name, x.values, x.params) for x in later.trials] == \
        [(x.state.name, x.values, x.params) for x in first.trials]
    assert later.best_value == 1.5
    with pytest.raises(ValueError, match="resume_from=.*no study to go on with"):
        SweepStudy(str(tmp_path / "c"), resume_from=str(tmp_path / "nowhere"))


@pytest.mark.slow
def test_a_search_whose_every_trial_failed_says_why_in_one_line(tmp_path):
    """No held-out walk (data.heldout_steps=0) while the objective is the held-out score: every
    trial fails, the report lists them, and the command says why, once."""
    pytest.importorskip("hydra_plugins.hydra_optuna_sweeper")
    sweep = tmp_path / "search"
    r = topomap(["-m", *SMALL, "hydra/sweeper=optuna", "hydra.sweeper.n_trials=2",
                 f"hydra.sweep.dir={sweep}", "clusters.ns=int(interval(4,6))"], tmp_path)
    assert r.returncode == 1
    assert r.stderr.splitlines() == [
        "topomap: error: all 2 trials of the search failed, the first with: ValueError: "
        "objective=heldout_loglik needs held-out data: data.heldout_steps > 0 (data=simulate; "
        "default: data.n_steps) or data.heldout_path (data=file, data=rosbag); or choose "
        "objective=ari"]
    with open(sweep / "summary.csv", newline="") as fh:
        assert [row["status"] for row in csv.DictReader(fh)] == ["failed", "failed"]
    assert len(json.loads((sweep / "study.json").read_text())["trials"]) == 2
