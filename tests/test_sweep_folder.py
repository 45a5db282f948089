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
    with pytest.raises(ValueError, match="resume_from=.*no study in .*study.json"):
        SweepStudy(str(tmp_path / "c"), resume_from=str(tmp_path / "nowhere"))


def _search(optuna, folder, values, resume_from=None):
    """A study of ``values`` (maximised; None: a failed trial) kept in ``folder``, one trial of
    ``clusters.ns=ns`` each."""
    from topomap.app.compose.study import SweepStudy

    study = optuna.create_study(storage=SweepStudy(str(folder), resume_from=resume_from,
                                                   objective="heldout_loglik"),
                                study_name="topomap", direction="maximize", load_if_exists=True)
    for ns, value in values:
        t = study.ask({"clusters.ns": optuna.distributions.IntUniformDistribution(ns, ns)})
        study.tell(t, value) if value is not None else study.tell(
            t, state=optuna.trial.TrialState.FAIL)
    return study


def test_a_resumed_study_is_best_at_its_largest_value_and_says_nothing_of_optuna(tmp_path):
    """The earlier search's trials 2.0 then 1.0 (maximised): the resumed study's best is 2.0,
    whichever order they come in, not the least value; adding them warns of nothing."""
    optuna = pytest.importorskip("optuna")
    import warnings

    _search(optuna, tmp_path / "a", [(4, 2.0), (5, 1.0)])
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        later = _search(optuna, tmp_path / "b", [(6, 1.5)], resume_from=str(tmp_path / "a"))
    assert [str(w.message) for w in caught] == []
    assert later.best_value == 2.0 and later.best_params == {"clusters.ns": 4}
    saved = json.loads((tmp_path / "b" / "study.json").read_text())
    assert saved["objective"] == "heldout_loglik"
    assert [(t["values"], t["sweep_dir"], t["job"]) for t in saved["trials"]] == [
        ([2.0], str(tmp_path / "a"), 0), ([1.0], str(tmp_path / "a"), 1),
        ([1.5], str(tmp_path / "b"), 0)]


def test_a_resumed_search_reports_the_best_of_its_whole_study(tmp_path, capsys):
    """This folder's jobs reach 1.5 at best, the earlier search's trial 0 reached 2.0: the
    report names trial 0 (in the earlier folder), and rings no job of this one."""
    optuna = pytest.importorskip("optuna")
    from topomap.app.report.summary import print_report, write_report

    _search(optuna, tmp_path / "a", [(4, 2.0), (5, 1.0)])
    _search(optuna, tmp_path / "b", [(6, 1.5), (7, None)], resume_from=str(tmp_path / "a"))
    for num, (ns, value) in enumerate([(6, 1.5), (7, None)]):
        folder = job_folder(tmp_path / "b", num, [f"clusters.ns={ns}"],
                            status="completed" if value else "failed")
        if value:
            (folder / "metrics.json").write_text(json.dumps({"heldout_loglik": value}))
    report = write_report(tmp_path / "b", metric="heldout_loglik", figure=False)
    assert report.best is None and report.study_best["number"] == 0
    print_report(report)
    assert (f"topomap: best heldout_loglik: 2 (trial 0, the best of the study's 4 trials, an "
            f"earlier search's: job 0 of {tmp_path / 'a'}, clusters.ns=4)") in capsys.readouterr().out
    _search(optuna, tmp_path / "c", [(8, 3.0)], resume_from=str(tmp_path / "b"))
    job_folder(tmp_path / "c", 0, ["clusters.ns=8"])
    (tmp_path / "c" / "0" / "metrics.json").write_text(json.dumps({"heldout_loglik": 3.0}))
    print_report(write_report(tmp_path / "c", metric="heldout_loglik", figure=False))
    assert ("topomap: best heldout_loglik: 3 (job 0: clusters.ns=8, the best of the study's 5 "
            "trials)") in capsys.readouterr().out


def test_a_search_goes_on_only_from_a_study_of_its_objective(tmp_path):
    """resume_from a folder without a study, or with trials of another objective: one line
    naming the key, before the search starts."""
    optuna = pytest.importorskip("optuna")
    from topomap.app.compose.study import check_resume

    _search(optuna, tmp_path / "a", [(4, 2.0)])
    assert [t["values"] for t in check_resume(tmp_path / "a", "heldout_loglik")] == [[2.0]]
    with pytest.raises(ValueError, match=rf"^hydra.sweeper.storage.resume_from={tmp_path / 'a'}: "
                       r"that search's trials are values of objective=heldout_loglik, this "
                       r"search's of objective=ari; give objective=heldout_loglik"):
        check_resume(tmp_path / "a", "ari")
    with pytest.raises(ValueError, match=r"resume_from=.*nowhere: no study in .*study.json"):
        check_resume(tmp_path / "nowhere", "ari")


@pytest.mark.slow
def test_a_resumed_search_prints_one_best_everywhere(tmp_path):
    """Two small searches, the second going on with the first: Hydra's best (its line and
    optimization_results.yaml), the best of study.json and topomap's line are the same trial."""
    pytest.importorskip("hydra_plugins.hydra_optuna_sweeper")
    small = ["data.n_steps=200", "data.heldout_steps=150", "output.figures=false",
             "output.progress=false", "clusters.ns=int(interval(4,8))",
             "stop.n_states=int(interval(10,16))", "hydra/sweeper=optuna"]
    first = topomap(["-m", *small, "hydra.sweeper.n_trials=3", "hydra.sweep.dir=s1"], tmp_path)
    assert first.returncode == 0, first.stderr
    second = topomap(["-m", *small, "hydra.sweeper.n_trials=2", "hydra.sweep.dir=s2",
                      "hydra.sweeper.storage.resume_from=s1", "hydra.sweeper.sampler.seed=1"],
                     tmp_path)
    assert second.returncode == 0, second.stderr
    assert "Warning" not in second.stderr and "alembic" not in second.stderr
    trials = json.loads((tmp_path / "s2" / "study.json").read_text())["trials"]
    assert len(trials) == 5
    best = max((t for t in trials if t["state"] == "COMPLETE"), key=lambda t: t["values"][0])
    found = OmegaConf.load(tmp_path / "s2" / "optimization_results.yaml")
    assert found.best_value == best["values"][0] and dict(found.best_params) == best["params"]
    assert f"Best value: {best['values'][0]}" in second.stderr + second.stdout
    line = next(x for x in second.stdout.splitlines() if x.startswith("topomap: best "))
    assert line.startswith(f"topomap: best heldout_loglik: {best['values'][0]:.4g} ")
    assert "the best of the study's 5 trials" in line


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
