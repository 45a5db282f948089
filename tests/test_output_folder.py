"""A run into a folder that holds another run's outputs refuses with one line, or with
``output.overwrite=true`` replaces them (topomap's own files only)."""

import subprocess
import sys

import pytest

from topomap.app.run.experiment import run
from topomap.app.results import FIGURE_FILES
from topomap.app.run.outputs import OutputDirInUse

SMALL = ["data.n_steps=200", "data.heldout_steps=0", "output.progress=false", "clusters.ns=6",
         "stop.n_states=10"]


def test_a_folder_holding_another_run_is_refused(make_cfg, tmp_path):
    run(make_cfg([*SMALL, "output.figures=false"]), tmp_path)
    before = {p.name: p.read_bytes() for p in tmp_path.iterdir()}
    with pytest.raises(OutputDirInUse) as err:
        run(make_cfg([*SMALL, "output.figures=false", "seed=1"]), tmp_path)
    message = str(err.value)
    assert str(tmp_path) in message and "output.overwrite=true" in message
    assert "\n" not in message
    assert {p.name: p.read_bytes() for p in tmp_path.iterdir()} == before


def test_overwrite_replaces_the_previous_runs_files_and_keeps_the_users(make_cfg, tmp_path):
    run(make_cfg(SMALL), tmp_path)  # with figures
    assert all((tmp_path / name).exists() for name in ("fig_states.png", "fig_map.png"))
    (tmp_path / "notes.txt").write_text("mine")
    run(make_cfg([*SMALL, "output.figures=false", "seed=1", "output.overwrite=true"]), tmp_path)
    names = {p.name for p in tmp_path.iterdir()}
    assert not names & set(FIGURE_FILES)  # the first run's figures went with it
    assert {"map.json", "metrics.json", "notes.txt"} <= names
    assert (tmp_path / "notes.txt").read_text() == "mine"


@pytest.mark.slow
def test_the_command_refuses_a_reused_folder_and_restarts_its_log_on_overwrite(tmp_path):
    folder = tmp_path / "mine"

    def topomap(*args):
        return subprocess.run([sys.executable, "-m", "topomap", *SMALL, "output.figures=false",
                               f"hydra.run.dir={folder}", *args], cwd=tmp_path,
                              capture_output=True, text=True, timeout=300)

    assert topomap().returncode == 0
    log = (folder / "topomap.log").read_text()
    refused = topomap("seed=1")
    assert refused.returncode == 1
    assert refused.stderr.splitlines() == [
        f"topomap: error: the output folder {folder} holds another run's outputs (map.graphml, "
        "map.json, metrics.json, ...); choose another hydra.run.dir, or give "
        "output.overwrite=true to replace them"]
    assert (folder / "topomap.log").read_text() == log  # the other run's log is left as it was
    assert topomap("seed=1", "output.overwrite=true").returncode == 0
    assert (folder / "topomap.log").read_text().count("phase 1:") == 1  # this run's lines only
