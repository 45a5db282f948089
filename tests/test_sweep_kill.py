"""A sweep whose job is killed from outside (SIGKILL) stays readable: the report lists the killed
job as ``incomplete`` and keeps every finished job, and half-written job folders are
``incomplete`` with a reason instead of breaking the report."""

import csv
import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from topomap.app.report.cli import main as report_main

pytestmark = pytest.mark.slow  # every test reads a real sweep, started (and killed) as a process

SMALL = ["data.n_steps=200", "data.heldout_steps=0", "output.figures=false",
         "output.progress=false", "clusters.ns=6"]
N_STATES = ["8", "9", "10"]  # job 1 (n_states=9) is killed; job 2 never starts

PLUGIN = '''
"""Test plugin: job {job} of a sweep writes ``{marker}`` (its pid and folder) and waits."""
import json
import os
import time

from hydra.core.hydra_config import HydraConfig

from topomap import hookimpl


@hookimpl
def topomap_learner_event(event, info):
    hydra = HydraConfig.get()
    if event == "phase1" and hydra.job.num == {job}:
        with open("{marker}.tmp", "w") as fh:
            json.dump({{"pid": os.getpid(), "dir": hydra.runtime.output_dir}}, fh)
        os.replace("{marker}.tmp", "{marker}")
        time.sleep(300)
'''


def wait_for(marker: Path, proc: subprocess.Popen, timeout: float = 120.0) -> dict:
    """The marker's content once the slow job wrote it; fails if the sweep ends first."""
    deadline = time.monotonic() + timeout
    while not marker.is_file():
        assert proc.poll() is None, "the sweep ended before the slow job started"
        assert time.monotonic() < deadline, f"no {marker.name} after {timeout:.0f} s"
        time.sleep(0.05)
    return json.loads(marker.read_text())


@pytest.fixture(scope="module")
def killed_sweep(tmp_path_factory):
    """A real sweep of three jobs whose second job is SIGKILLed while it learns.

    Returns ``(sweep_dir, killed_job_dir)``.
    """
    cwd = tmp_path_factory.mktemp("killed")
    marker = cwd / "slow-job-started.json"
    plugin = cwd / "slow_job.py"
    plugin.write_text(PLUGIN.format(job=1, marker=marker))
    args = [sys.executable, "-m", "topomap", "-m", *SMALL, f"stop.n_states={','.join(N_STATES)}",
            f"plugins=[{plugin}]"]
    with open(cwd / "sweep.log", "w") as log:
        proc = subprocess.Popen(args, cwd=cwd, stdout=log, stderr=subprocess.STDOUT)
        try:
            started = wait_for(marker, proc)
            assert started["pid"] == proc.pid  # the basic launcher runs jobs in its own process
            os.kill(proc.pid, signal.SIGKILL)
            assert proc.wait(timeout=30) == -signal.SIGKILL
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
    killed = Path(started["dir"])
    return killed.parent, killed


def read_summary(sweep_dir: Path) -> list[dict]:
    """The rows of ``summary.csv``, each checked to have exactly the header's fields."""
    with open(sweep_dir / "summary.csv", newline="") as fh:
        rows = list(csv.reader(fh))
    header, body = rows[0], rows[1:]
    assert all(len(r) == len(header) for r in body)
    return [dict(zip(header, r)) for r in body]


def test_a_killed_job_is_incomplete_and_no_finished_job_is_lost(killed_sweep):
    sweep, killed = killed_sweep
    assert not (sweep / "summary.csv").exists()  # the sweep died before its report
    assert not (sweep / "2").exists()  # the job after the killed one never started
    result = subprocess.run([sys.executable, "-m", "topomap.app.report", str(sweep)],
                            capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    assert "sweep of 3 jobs, 1 completed, 0 failed, 1 incomplete, 1 not started" in result.stdout
    rows = {r["job"]: r for r in read_summary(sweep)}
    assert sorted(rows) == ["0", "1", "2"]
    assert (rows["2"]["stop.n_states"], rows["2"]["status"]) == ("10", "not started")
    done, cut = rows["0"], rows["1"]
    assert (done["stop.n_states"], cut["stop.n_states"]) == ("8", "9")
    metrics = json.loads((sweep / done["output_dir"] / "metrics.json").read_text())
    assert done["status"] == "completed" and done["error"] == ""
    assert int(done["n_states"]) == metrics["n_states"]["final"] == 8
    assert float(done["ari"]) == metrics["ground_truth"]["final"]["ari"]
    assert float(done["H_x"]) == metrics["entropies"]["final"]["H_x"]
    assert sweep / cut["output_dir"] == killed
    assert cut["status"] == "incomplete" and cut["ari"] == "" and cut["n_states"] == ""
    assert "killed" in cut["error"]
    assert f"job 1 incomplete: {cut['error']}" in result.stdout


def damage_hydra_only(job: Path) -> None:
    """Killed while Hydra wrote the job's config: an empty ``.hydra`` and nothing else."""
    shutil.rmtree(job)
    (job / ".hydra").mkdir(parents=True)


def damage_garbled_overrides(job: Path) -> None:
    """An ``overrides.yaml`` that is not YAML (the job itself finished)."""
    (job / ".hydra" / "overrides.yaml").write_text("- stop.n_states=8\n- [clusters.ns=")


def damage_truncated_status(job: Path) -> None:
    """Killed while writing ``status.json`` in place (no metrics)."""
    text = (job / "status.json").read_text()
    (job / "status.json").write_text(text[: len(text) // 2])
    (job / "metrics.json").unlink()


def damage_truncated_metrics(job: Path) -> None:
    """A ``metrics.json`` cut short (written in place by something else than topomap)."""
    text = (job / "metrics.json").read_text()
    (job / "metrics.json").write_text(text[: len(text) // 2])


def damage_status_not_an_object(job: Path) -> None:
    """A ``status.json`` that is JSON but not an object."""
    (job / "status.json").write_text("[]")
    (job / "metrics.json").unlink()


def damage_unknown_status(job: Path) -> None:
    """A ``status.json`` with a status topomap never writes."""
    (job / "status.json").write_text('{"status": "running"}')


def damage_no_status_yet(job: Path) -> None:
    """Killed after ``metrics.json`` (written last of the outputs) but before ``status.json``."""
    (job / "status.json").unlink()


DAMAGE = {
    damage_hydra_only: ("incomplete", ["overrides.yaml is missing", "killed"]),
    damage_garbled_overrides: ("completed", ["overrides.yaml is unreadable"]),
    damage_truncated_status: ("incomplete", ["status.json is unreadable"]),
    damage_truncated_metrics: ("incomplete", ["metrics.json is unreadable"]),
    damage_status_not_an_object: ("incomplete", ["status.json does not hold a JSON object"]),
    damage_unknown_status: ("incomplete", ["unknown status 'running'"]),
    damage_no_status_yet: ("completed", []),
}


@pytest.mark.parametrize("damage", DAMAGE, ids=[f.__name__[7:] for f in DAMAGE])
def test_a_half_written_job_folder_is_reported_with_its_reason(killed_sweep, tmp_path, capsys,
                                                               damage):
    sweep = tmp_path / "sweep"
    shutil.copytree(killed_sweep[0], sweep)
    job = sweep / "7"
    shutil.copytree(sweep / "0", job)
    (job / ".hydra" / "hydra.yaml").unlink()  # else it would say it is job 0
    damage(job)
    assert report_main([str(sweep), "--no-figure"]) == 0
    rows = {r["job"]: r for r in read_summary(sweep)}
    assert sorted(rows) == ["0", "1", "2", "7"]  # job 2 of the plan never started
    assert rows["0"]["status"] == "completed" and rows["1"]["status"] == "incomplete"
    status, reasons = DAMAGE[damage]
    assert rows["7"]["status"] == status
    for reason in reasons:
        assert reason in rows["7"]["error"]
    if status == "completed":
        assert rows["7"]["ari"] == rows["0"]["ari"]
    else:
        assert rows["7"]["ari"] == "" and f"job 7 incomplete: {rows['7']['error']}" in \
            capsys.readouterr().out


def test_a_column_is_read_where_its_file_has_it_and_is_none_wherever_it_does_not():
    """A run's numbers are read the same whatever else its metrics.json holds: a missing level,
    a level that is no mapping, a text that looks like an interpolation all give None."""
    from topomap.app.results import METRICS

    ari, fit_time = METRICS["ari"], METRICS["fit_time"]
    assert ari.read({"ground_truth": {"final": {"ari": 0.5}}, "config": {"x": "${nope}"}}) == 0.5
    for broken in ({}, {"ground_truth": None}, {"ground_truth": [1, 2]},
                   {"ground_truth": {"final": {"ari": "${nope}"}}}, {"ground_truth": 3}):
        assert ari.read(broken) is None
    assert fit_time.read({"timings": {"phase1": 1.0, "phase2": 2.5}}) == 3.5  # summed
    assert fit_time.read({"timings": {"phase1": 1.0}}) is None  # not all of its places
