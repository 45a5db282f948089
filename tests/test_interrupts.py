"""Ctrl-C, SIGTERM and failures end a run or a sweep cleanly: one line and exit status 130 for an
interrupt, the sweep report written with the interrupted job and the jobs that did not start, a
``status.json`` saying what happened, and never a folder holding part of a run's files."""

import csv
import json
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from topomap.app import plots
from topomap.app.run import experiment, job, outputs

SMALL = ["data.n_steps=200", "data.heldout_steps=0", "output.figures=false",
         "output.progress=false", "clusters.ns=6"]

PLUGIN = '''
"""Test plugin: {which} writes ``{marker}`` once phase 1 is done, then waits."""
import os
import threading
import time

from hydra.core.hydra_config import HydraConfig

from topomap import hookimpl


@hookimpl
def topomap_learner_event(event, info):
    hydra = HydraConfig.get()
    if event == "phase1" and ({job} is None or hydra.job.num == {job}):
        with open("{marker}", "w") as fh:
            fh.write(hydra.runtime.output_dir)
        time.sleep(300)
'''


def start(cwd: Path, args, job=None):
    """``topomap <args>`` as a process whose job ``job`` (every job: None) waits after phase 1;
    returns the process and the marker file the waiting job writes its folder into."""
    marker = cwd / "waiting.txt"
    plugin = cwd / "slow_job.py"
    plugin.write_text(PLUGIN.format(job=job, marker=marker,
                                    which="every job" if job is None else f"job {job}"))
    proc = subprocess.Popen([sys.executable, "-m", "topomap", *args, f"plugins=[{plugin}]"],
                            cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 120
    while not marker.is_file() or not marker.read_text():
        assert proc.poll() is None, proc.communicate()
        assert time.monotonic() < deadline, "the job never reached phase 1"
        time.sleep(0.05)
    return proc, Path(marker.read_text())


def finish(proc) -> tuple[int, str, str]:
    out, err = proc.communicate(timeout=120)
    return proc.returncode, out, err


@pytest.mark.slow
def test_ctrl_c_ends_a_sweep_with_its_report(tmp_path):
    proc, job_dir = start(tmp_path, ["-m", *SMALL, "stop.n_states=8,9,10"], job=1)
    proc.send_signal(signal.SIGINT)
    code, out, err = finish(proc)
    assert code == 130, err
    assert "Traceback" not in err and err.strip().splitlines()[-1].startswith(
        "topomap: interrupted; sweep report in "), err
    sweep = job_dir.parent
    assert "sweep of 3 jobs, 1 completed, 0 failed, 1 interrupted, 1 not started" in out
    with open(sweep / "summary.csv", newline="") as fh:
        rows = {r["job"]: r for r in csv.DictReader(fh)}
    assert [(rows[j]["stop.n_states"], rows[j]["status"]) for j in "012"] == [
        ("8", "completed"), ("9", "interrupted"), ("10", "not started")]
    status = json.loads((job_dir / "status.json").read_text())
    assert status["status"] == "interrupted"
    assert not (job_dir / "map.json").exists() and not (sweep / "2").exists()
    rebuilt = subprocess.run([sys.executable, "-m", "topomap.app.report", str(sweep)],
                             capture_output=True, text=True, timeout=120)
    assert "sweep of 3 jobs, 1 completed, 0 failed, 1 interrupted, 1 not started" in rebuilt.stdout


@pytest.mark.slow
def test_sigterm_ends_a_run_with_one_line_and_its_status(tmp_path):
    run_dir = tmp_path / "run"
    proc, job_dir = start(tmp_path, [*SMALL, f"hydra.run.dir={run_dir}"])
    assert job_dir == run_dir
    proc.send_signal(signal.SIGTERM)
    code, out, err = finish(proc)
    assert code == 130
    assert err.strip().splitlines() == [
        f"topomap: interrupted; {run_dir}/status.json says so"]
    assert json.loads((run_dir / "status.json").read_text())["status"] == "interrupted"
    assert sorted(p.name for p in run_dir.iterdir()) == [".hydra", ".topomap.lock", "status.json",
                                                         "topomap.log"]


@pytest.mark.slow
def test_a_run_failed_by_its_data_leaves_no_folder_and_one_line(tmp_path):
    """The data file is missing: one line on stderr, nothing on stdout, and no run folder (the
    command made it, so it removes it)."""
    run_dir = tmp_path / "run"
    r = subprocess.run([sys.executable, "-m", "topomap", "output.progress=false", "data=file",
                        "data.path=nope.npz", f"hydra.run.dir={run_dir}"], cwd=tmp_path,
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 1 and r.stderr.count("\n") == 1, r.stderr
    assert r.stderr.startswith("topomap: error: trajectory file nope.npz does not exist")
    assert "ERROR" not in r.stdout and not run_dir.exists()


def interrupted(*args, **kwargs):
    """Stands in for a function the user's Ctrl-C stops."""
    raise KeyboardInterrupt


def small_cfg(make_cfg):
    return make_cfg(["data.n_steps=200", "data.heldout_steps=0", "output.progress=false",
                     "clusters.ns=6"])


def test_an_interrupt_while_writing_leaves_none_of_the_run_files(tmp_path, make_cfg,
                                                                  monkeypatch):
    """Interrupted while drawing the figures (after the map was written, before the metrics):
    the folder holds none of the run's files and no staging folder."""
    monkeypatch.setattr(plots, "write_figures", interrupted)
    with pytest.raises(KeyboardInterrupt):
        experiment.run(small_cfg(make_cfg), tmp_path / "out")
    assert list((tmp_path / "out").iterdir()) == []


def test_a_sweep_job_that_is_interrupted_says_so_and_ends_the_sweep(tmp_path, make_cfg,
                                                                    monkeypatch):
    monkeypatch.setattr(outputs, "_write_outputs", interrupted)
    with pytest.raises(KeyboardInterrupt):
        job.run_job(small_cfg(make_cfg), tmp_path / "0", sweep_dir=tmp_path)
    assert [p.name for p in (tmp_path / "0").iterdir()] == ["status.json"]
    assert json.loads((tmp_path / "0" / "status.json").read_text())["status"] == "interrupted"


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_while_a_sweep_runs_an_interrupt_carries_the_sweep_and_its_end_gives_the_handlers_back(
        tmp_path, sig, capsys):
    """Ctrl-C or SIGTERM during a sweep is a KeyboardInterrupt that carries the sweep (whoever
    catches it writes the report); once the sweep ends, the signals are handled as before."""
    from omegaconf import OmegaConf

    from topomap.app.report.callback import SweepInterrupted, SweepReport

    if threading.current_thread() is not threading.main_thread():
        pytest.skip("signals reach the main thread only")
    config = OmegaConf.create({"hydra": {"sweep": {"dir": str(tmp_path)}}})
    callback = SweepReport(figure=False)
    before = signal.getsignal(sig)
    callback.on_multirun_start(config)
    try:
        with pytest.raises(KeyboardInterrupt) as caught:
            signal.raise_signal(sig)
        assert isinstance(caught.value, SweepInterrupted)
        assert caught.value.write_report() == tmp_path / "summary.csv"
        assert "topomap: sweep of 0 jobs" in capsys.readouterr().out
    finally:
        callback.on_multirun_end(config)
    assert signal.getsignal(sig) is before
