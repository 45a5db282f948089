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
def test_an_interrupt_is_raised_and_recorded_and_its_handlers_are_given_back(sig):
    """Ctrl-C or SIGTERM raises Interrupted where the program stands; when that exception is
    dropped (Python drops one raised in a destructor), the record raises it again at the next
    check; giving the handlers back restores the earlier ones and forgets the record."""
    from topomap.app.run import interrupts

    if threading.current_thread() is not threading.main_thread():
        pytest.skip("signals reach the main thread only")
    before = signal.getsignal(sig)
    replaced = interrupts.take_interrupts()
    try:
        interrupts.stop_if_interrupted()  # nothing received: goes on
        with pytest.raises(interrupts.Interrupted, match=f"signal {sig.name}"):
            signal.raise_signal(sig)
        assert interrupts.interrupted() == sig.name
        with pytest.raises(KeyboardInterrupt, match=f"signal {sig.name}"):
            interrupts.stop_if_interrupted()  # and again, at every later check
    finally:
        interrupts.give_back(replaced)
    assert signal.getsignal(sig) is before and interrupts.interrupted() is None


def test_a_run_interrupted_where_the_exception_was_dropped_leaves_none_of_its_files(
        tmp_path, make_cfg, monkeypatch):
    """A signal received while the figures were drawn, its exception dropped: the run's files
    never move into its folder."""
    from topomap.app.run import interrupts

    monkeypatch.setattr(interrupts, "_received", ["SIGINT"])
    with pytest.raises(interrupts.Interrupted):
        experiment.run(small_cfg(make_cfg), tmp_path / "out")
    assert list((tmp_path / "out").iterdir()) == []


FIGURES_PLUGIN = '''
"""Test plugin: job 0 of a sweep gets SIGINT while it draws its figures, {where}."""
import os
import signal

from hydra.core.hydra_config import HydraConfig

from topomap.app import plots

_draw = plots.write_figures


def _wait_for_the_handler():
    for _ in range(200_000):  # Python runs the signal's handler between these steps
        pass


class SignalsWhenCollected:
    def __del__(self):
        os.kill(os.getpid(), signal.SIGINT)
        _wait_for_the_handler()


def write_figures(*args, **kwargs):
    if HydraConfig.get().job.num == 0:
        if {in_destructor}:
            SignalsWhenCollected()  # collected at once: the interrupt is raised in __del__
        else:
            os.kill(os.getpid(), signal.SIGINT)
            _wait_for_the_handler()
    return _draw(*args, **kwargs)


plots.write_figures = write_figures
'''


@pytest.mark.slow
@pytest.mark.parametrize("in_destructor", [False, True], ids=["plain", "in-a-destructor"])
def test_ctrl_c_while_a_job_draws_its_figures_ends_the_sweep(tmp_path, in_destructor):
    """SIGINT lands while job 0 draws its figures; where it lands inside a destructor (as in
    matplotlib's weak-reference callbacks) Python drops the exception ("Exception ignored in"),
    yet the sweep stops there: status 130, job 0 interrupted with none of its files, job 1 not
    started, the report written."""
    plugin = tmp_path / "figures_interrupted.py"
    plugin.write_text(FIGURES_PLUGIN.format(
        in_destructor=in_destructor,
        where="inside a destructor, where Python drops the exception" if in_destructor
        else "in plain code"))
    sweep = tmp_path / "sweep"
    r = subprocess.run([sys.executable, "-m", "topomap", "-m", *SMALL, "output.figures=true",
                        "stop.n_states=8,9", f"hydra.sweep.dir={sweep}", f"plugins=[{plugin}]"],
                       cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert r.returncode == 130, r.stdout + r.stderr
    assert ("Exception ignored in" in r.stderr) == in_destructor, r.stderr
    assert r.stderr.strip().splitlines()[-1] == \
        f"topomap: interrupted; sweep report in {sweep / 'summary.csv'}", r.stderr
    with open(sweep / "summary.csv", newline="") as fh:
        rows = {row["job"]: row for row in csv.DictReader(fh)}
    assert [(rows[j]["stop.n_states"], rows[j]["status"]) for j in "01"] == [
        ("8", "interrupted"), ("9", "not started")]
    assert sorted(p.name for p in (sweep / "0").iterdir()) == [".hydra", "status.json",
                                                              "topomap.log"]
    assert not (sweep / "1").exists()


def test_a_second_interrupt_while_the_command_ends_is_recorded_not_raised():
    """The first Ctrl-C is raised; once the command says it is ending (writing a status, the
    report), a second one is only recorded, and taking the signals again raises once more."""
    from topomap.app.run import interrupts

    if threading.current_thread() is not threading.main_thread():
        pytest.skip("signals reach the main thread only")
    replaced = interrupts.take_interrupts()
    try:
        with pytest.raises(interrupts.Interrupted):
            signal.raise_signal(signal.SIGINT)
        interrupts.ending()
        signal.raise_signal(signal.SIGINT)  # recorded only
        signal.raise_signal(signal.SIGTERM)
        assert interrupts._received == ["SIGINT", "SIGINT", "SIGTERM"]
        interrupts.give_back(interrupts.take_interrupts())
        interrupts.take_interrupts()
        with pytest.raises(interrupts.Interrupted):
            signal.raise_signal(signal.SIGINT)
    finally:
        interrupts.give_back(replaced)


TWICE_PLUGIN = FIGURES_PLUGIN.format(in_destructor=False, where="then again as the report is "
                                     "written (Ctrl-C pressed twice)") + '''

from topomap.app.report import callback

_report = callback.write_report


def write_report(*args, **kwargs):
    os.kill(os.getpid(), signal.SIGINT)
    _wait_for_the_handler()
    return _report(*args, **kwargs)


callback.write_report = write_report
'''


@pytest.mark.slow
def test_ctrl_c_twice_ends_the_sweep_with_its_report(tmp_path):
    """SIGINT while job 0 draws its figures, and a second one while the command writes the
    report: the report is written all the same, one line, status 130, no traceback."""
    plugin = tmp_path / "twice.py"
    plugin.write_text(TWICE_PLUGIN)
    sweep = tmp_path / "sweep"
    r = subprocess.run([sys.executable, "-m", "topomap", "-m", *SMALL, "output.figures=true",
                        "stop.n_states=8,9", f"hydra.sweep.dir={sweep}", f"plugins=[{plugin}]"],
                       cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert r.returncode == 130 and "Traceback" not in r.stderr, r.stdout + r.stderr
    assert r.stderr.strip().splitlines()[-1] == \
        f"topomap: interrupted; sweep report in {sweep / 'summary.csv'}", r.stderr
    with open(sweep / "summary.csv", newline="") as fh:
        assert [row["status"] for row in csv.DictReader(fh)] == ["interrupted", "not started"]
