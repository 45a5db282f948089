"""What a run checks before it makes its folder, and how it holds the folder while it runs."""

import json
import os
import subprocess
import sys
import time

import pytest

from topomap.app.run import checks
from topomap.app.run.experiment import check_and_build
from topomap.app.run.outputs import LOCK_FILE, OutputDirInUse, locked_output_dir

SMALL = ["data.n_steps=300", "data.heldout_steps=0", "output.progress=false",
         "output.figures=false", "clusters.ns=10", "stop.n_states=20"]


def topomap(args, cwd, timeout=300, **kw):
    env = dict(os.environ, TOPOMAP_DISABLE_PLUGIN_AUTOLOAD="1")
    return subprocess.run([sys.executable, "-m", "topomap", *args], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=timeout, **kw)


@pytest.mark.parametrize("override, message", [
    ("seed=-1", r"^seed=-1 must be a non-negative integer$"),
    ("output.min_prob=2", r"^output.min_prob=2.0 must be a probability in \[0, 1\)"),
    ("output.min_prob=-1", r"^output.min_prob=-1.0 must be a probability"),
    ("evaluate.episodes=0", r"^evaluate=navigation: evaluate.episodes must be a positive"),
])
def test_a_bad_run_setting_is_refused_naming_its_key(override, message, make_cfg):
    extra = ["evaluate=navigation"] if override.startswith("evaluate") else []
    with pytest.raises(ValueError, match=message):
        check_and_build(make_cfg([*extra, override]))


def test_a_told_size_above_half_the_steps_is_refused_before_the_walk(make_cfg, monkeypatch):
    """2,000 steps hold at most 1,000 states of two steps each: 1,001 is refused, 1,000 is not
    (before anything is simulated)."""
    cfg = ["env=gridroom", "refine=em", "data.n_steps=2000"]
    with pytest.raises(ValueError, match=r"^stop.n_states=1001 is more than half of the 2000 "
                                         r"steps.*give at most stop.n_states=1000"):
        check_and_build(make_cfg([*cfg, "stop.n_states=1001"]))
    check_and_build(make_cfg([*cfg, "stop.n_states=1000"]))


def test_a_walk_that_cannot_fit_in_memory_is_refused_with_what_it_needs(make_cfg, monkeypatch):
    """The office world's observations have 15 features: a step takes (15 + 5) x 8 = 160 bytes,
    so with 1 GiB available 10 million steps (and as many held out) are refused: 3 GiB."""
    monkeypatch.setattr(checks, "available_memory", lambda: 2 ** 30)
    with pytest.raises(ValueError, match=r"^data.n_steps=10000000 needs at least 3 GiB for the "
                                         r"walk alone \(20000000 steps, held-out walk included, "
                                         r"of 15 features\) and 1 GiB"):
        check_and_build(make_cfg(["data.n_steps=10000000"]))
    check_and_build(make_cfg(["data.n_steps=3000000", "data.heldout_steps=0"]))  # 0.45 GiB


def test_a_folder_held_by_a_run_is_refused_to_another(tmp_path):
    folder = tmp_path / "run"
    with locked_output_dir(folder) as new:
        assert new and (folder / LOCK_FILE).exists()
        with pytest.raises(OutputDirInUse, match="another topomap run is writing into"):
            with locked_output_dir(folder):
                pass
    with locked_output_dir(folder) as new:  # free again
        assert not new


def test_a_run_writing_its_files_is_named_as_such_and_a_killed_ones_leftovers_are_not_outputs(
        tmp_path):
    """While a run moves its files in, its folder holds the hidden staging folder and the
    run's lock: a second run is told that another run is writing there (not shown the staging
    folder's name as if it were an output).  Left by a killed run, with no lock held, the staging
    folder holds no outputs: the folder is free."""
    from topomap.app.run.outputs import STAGE_PREFIX, claim_output_dir

    folder = tmp_path / "run"
    with locked_output_dir(folder):
        (folder / f"{STAGE_PREFIX}x").mkdir()
        with pytest.raises(OutputDirInUse, match=rf"^another topomap run is writing into the "
                                                 rf"output folder {folder}; choose another"):
            with locked_output_dir(folder):
                pass
    with locked_output_dir(folder) as new:  # the first run was killed: its leftovers
        assert not new
        assert claim_output_dir(folder) == [] and not (folder / f"{STAGE_PREFIX}x").exists()


@pytest.mark.slow
def test_a_refused_run_changes_nothing_in_the_other_runs_folder(tmp_path):
    folder = tmp_path / "run"
    assert topomap([*SMALL, f"hydra.run.dir={folder}"], tmp_path).returncode == 0
    before = {p: p.read_bytes() for p in folder.rglob("*") if p.is_file()}
    r = topomap([*SMALL, "seed=1", f"hydra.run.dir={folder}"], tmp_path)
    assert r.returncode == 1 and r.stderr.splitlines() == [
        f"topomap: error: the output folder {folder} holds another run's outputs (map.graphml, "
        "map.json, metrics.json, ...); choose another hydra.run.dir, or give "
        "output.overwrite=true to replace them"]
    assert {p: p.read_bytes() for p in folder.rglob("*") if p.is_file()} == before


@pytest.mark.slow
def test_of_two_runs_started_into_one_folder_one_is_refused(tmp_path):
    folder = tmp_path / "run"
    env = dict(os.environ, TOPOMAP_DISABLE_PLUGIN_AUTOLOAD="1")
    first = subprocess.Popen([sys.executable, "-m", "topomap", *SMALL, "data.n_steps=3000",
                              f"hydra.run.dir={folder}"], cwd=tmp_path, env=env,
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 120
        while not (folder / ".hydra").exists() and time.monotonic() < deadline:
            time.sleep(0.05)
        second = topomap([*SMALL, "seed=1", f"hydra.run.dir={folder}"], tmp_path)
    finally:
        out, err = first.communicate(timeout=300)
    assert first.returncode == 0, err
    (line,) = second.stderr.splitlines()  # refused while the first runs, or once it is done
    assert second.returncode == 1 and line.startswith("topomap: error: ") and (
        f"another topomap run is writing into the output folder {folder}" in line
        or f"the output folder {folder} holds another run's outputs" in line), line
    assert json.loads((folder / "metrics.json").read_text())["config"]["seed"] == 0
    assert "seed: 0" in (folder / ".hydra" / "config.yaml").read_text()


COUNTED = """
import atexit, sys
from topomap.app.run import experiment
calls = []
checked = experiment.check_and_build
def counted(*args, **kwargs):
    calls.append(1)
    return checked(*args, **kwargs)
experiment.check_and_build = counted
atexit.register(lambda: print(f"checked {{len(calls)}} time(s)", file=sys.stderr))
sys.argv = ["topomap", *{args!r}]
from topomap.app.cli import main
main()
"""


@pytest.mark.slow
@pytest.mark.parametrize("extra", [[], ["env=gridroom", "refine=em", "clusters.ns=4"]])
def test_a_run_checks_its_config_and_builds_its_components_once(tmp_path, extra):
    """The command checks the config before Hydra makes the run's folder; the run takes that
    check over instead of making it again."""
    args = [*SMALL, *extra, f"hydra.run.dir={tmp_path / 'run'}"]
    env = dict(os.environ, TOPOMAP_DISABLE_PLUGIN_AUTOLOAD="1")
    r = subprocess.run([sys.executable, "-c", COUNTED.format(args=args)], cwd=tmp_path, env=env,
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert r.stderr.splitlines()[-1] == "checked 1 time(s)"
    assert (tmp_path / "run" / "map.json").is_file()


@pytest.mark.slow
@pytest.mark.parametrize("override", ["seed=-1", "clusters.ns=0", "data.n_steps=0",
                                      "stop.n_states=5000"])
def test_a_setting_error_leaves_no_folder_and_prints_one_line_on_stderr(override, tmp_path):
    r = topomap([override, f"hydra.run.dir={tmp_path / 'run'}"], tmp_path)
    assert r.returncode == 1 and r.stdout == "" and len(r.stderr.splitlines()) == 1, r.stderr
    assert r.stderr.startswith("topomap: error: ") and not (tmp_path / "run").exists()


# ---------------------------------------------------------------- values of the command line
@pytest.mark.parametrize("override, message", [
    ("clusters.ns=abc", "clusters.ns=abc is not an integer"),
    ("clusters.ns=1.5", "clusters.ns=1.5 is not an integer"),
    ("-m clusters.ns=3,abc", "clusters.ns=abc is not an integer"),
    ("seed=x", "seed=x is not an integer"),
    ("output.min_prob=x", "output.min_prob=x is not a number"),
    ("output.compound_state=a", "output.compound_state=a is not an integer or null"),
    ("task=localise", "task=localise is not one of learn, localize; did you mean task=localize?"),
    ("objective=aric", "objective=aric is not one of heldout_loglik, ari; did you mean "
                       "objective=ari?"),
    ("refine=EM", "unknown refine=EM; did you mean refine=em? (the options: cscg, em, none)"),
])
def test_a_value_of_the_wrong_type_is_one_line_naming_the_key(override, message):
    from topomap.app.compose.command_line import compose

    with pytest.raises(ValueError) as err:
        compose([override.removeprefix("-m ")])
    assert str(err.value) == message


@pytest.mark.parametrize("override, package, extra", [
    ("hydra/sweeper=optuna_pricai2002", "hydra_optuna_sweeper", "optuna"),
    ("hydra/sweeper=optuna", "hydra_optuna_sweeper", "optuna"),
    ("hydra/launcher=ray", "hydra_ray_launcher", "ray"),
    ("hydra/launcher=ray_cluster", "hydra_ray_launcher", "ray"),
    ("hydra/launcher=slurm", "hydra_submitit_launcher", "cluster"),
    ("hydra/launcher=joblib", "hydra_joblib_launcher", "cluster"),
])
def test_a_sweeper_or_launcher_without_its_plugin_names_the_extra(override, package, extra,
                                                                  monkeypatch):
    """The plugin hidden: the command line is refused with the pip command of its extra."""
    import importlib.util

    from topomap.app.compose.command_line import compose

    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec",
                        lambda name, *a: None if name == f"hydra_plugins.{package}"
                        else real(name, *a))
    with pytest.raises(ValueError) as err:
        compose([override])
    option = override.split("=")[1]
    assert str(err.value) == (f"{override.split('=')[0]}={option} needs the "
                              f"{package.replace('_', '-')} plugin: pip install "
                              f'"topomap[{extra}]"')


def test_a_slurm_sweep_without_slurm_stops_before_its_first_job(monkeypatch, make_cfg,
                                                                 tmp_path):
    import shutil

    from topomap.app.cli import check_sweep

    cfg = make_cfg(["hydra/launcher=slurm", f"hydra.sweep.dir={tmp_path}"], hydra=True)
    monkeypatch.setattr(shutil, "which", lambda name: None)
    with pytest.raises(ValueError, match="hydra/launcher=slurm submits the jobs with SLURM's "
                                         "sbatch, which is not on this machine's PATH"):
        check_sweep(cfg)
    monkeypatch.setattr(shutil, "which", lambda name: f"/usr/bin/{name}")
    check_sweep(cfg)  # goes on


# ---------------------------------------------------------------- what a run says in its log
def test_without_a_terminal_a_long_loop_logs_when_it_starts_and_ends(make_cfg, tmp_path, caplog):
    """clusters=bic with no terminal: a line when BIC starts, one when it ends."""
    from topomap.app.run.experiment import run

    with caplog.at_level("INFO", logger="topomap"):
        run(make_cfg(["clusters=bic", "clusters.min_ns=4", "clusters.max_ns=6",
                      "data.n_steps=200", "data.heldout_steps=0", "output.figures=false",
                      "stop.n_states=10"]), tmp_path / "run")
    lines = [r.getMessage() for r in caplog.records if r.getMessage().startswith("BIC")]
    assert lines[0] == "BIC: started" and lines[1].startswith("BIC: done (3 steps, ")
    assert len(lines) == 2


def test_a_localising_run_says_what_it_did_in_its_log(make_cfg, tmp_path, caplog):
    from topomap.app.run.experiment import run

    run(make_cfg(SMALL), tmp_path / "learn")
    with caplog.at_level("INFO", logger="topomap"):
        results = run(make_cfg(["task=localize", f"map={tmp_path / 'learn' / 'map.json'}",
                                "data.n_steps=100", "output.progress=false"]), tmp_path / "loc")
    said = [r.getMessage() for r in caplog.records]
    assert said[0] == f"map {tmp_path / 'learn' / 'map.json'}: 20 states, 17 actions"
    assert said[1] == "trajectory: 100 steps, 15 features, 17 actions"
    assert said[-1].startswith(f"localised 100 steps: log-likelihood {results['loglik']:.3f}")
