"""What a run checks before it makes its folder, and how it holds the folder while it runs."""

import json
import os
import subprocess
import sys
import time

import pytest

from topomap.app.run import checks
from topomap.app.run.experiment import prepare
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
        prepare(make_cfg([*extra, override]))


def test_a_told_size_above_half_the_steps_is_refused_before_the_walk(make_cfg, monkeypatch):
    """2,000 steps hold at most 1,000 states of two steps each: 1,001 is refused, 1,000 is not
    (before anything is simulated)."""
    cfg = ["env=gridroom", "refine=em", "data.n_steps=2000"]
    with pytest.raises(ValueError, match=r"^stop.n_states=1001 is more than half of the 2000 "
                                         r"steps.*give at most stop.n_states=1000"):
        prepare(make_cfg([*cfg, "stop.n_states=1001"]))
    prepare(make_cfg([*cfg, "stop.n_states=1000"]))


def test_a_walk_that_cannot_fit_in_memory_is_refused_with_what_it_needs(make_cfg, monkeypatch):
    """The office world's observations have 15 features: a step takes (15 + 5) x 8 = 160 bytes,
    so with 1 GiB available 10 million steps (and as many held out) are refused: 3 GiB."""
    monkeypatch.setattr(checks, "available_memory", lambda: 2 ** 30)
    with pytest.raises(ValueError, match=r"^data.n_steps=10000000 needs at least 3 GiB for the "
                                         r"walk alone \(20000000 steps, held-out walk included, "
                                         r"of 15 features\) and 1 GiB"):
        prepare(make_cfg(["data.n_steps=10000000"]))
    prepare(make_cfg(["data.n_steps=3000000", "data.heldout_steps=0"]))  # 0.45 GiB


def test_a_folder_held_by_a_run_is_refused_to_another(tmp_path):
    folder = tmp_path / "run"
    with locked_output_dir(folder) as new:
        assert new and (folder / LOCK_FILE).exists()
        with pytest.raises(OutputDirInUse, match="another topomap run is writing into"):
            with locked_output_dir(folder):
                pass
    with locked_output_dir(folder) as new:  # free again
        assert not new


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


@pytest.mark.slow
@pytest.mark.parametrize("override", ["seed=-1", "clusters.ns=0", "data.n_steps=0",
                                      "stop.n_states=5000"])
def test_a_setting_error_leaves_no_folder_and_prints_one_line_on_stderr(override, tmp_path):
    r = topomap([override, f"hydra.run.dir={tmp_path / 'run'}"], tmp_path)
    assert r.returncode == 1 and r.stdout == "" and len(r.stderr.splitlines()) == 1, r.stderr
    assert r.stderr.startswith("topomap: error: ") and not (tmp_path / "run").exists()
