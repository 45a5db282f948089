"""One job of a sweep, and the ``status.json`` a job or a run that did not complete leaves.

A job shares simulated trajectories through the sweep's folder and never raises what fails it:
the error goes to its ``status.json``, so that the other jobs and the sweep report are not
lost (:func:`run_job`).  :func:`write_status` writes the file (``completed``, ``failed`` or
``interrupted``, the error, the process and the host).
"""

from __future__ import annotations

import json
import logging
import os
import socket
import time
import traceback
from pathlib import Path

from ..results import CACHE_DIR, METRICS_FILE, STATUS_FILE
from .experiment import run
from .interrupts import ending, stop_if_interrupted
from .outputs import OutputDirInUse, write_json

log = logging.getLogger("topomap")

__all__ = ["run_job", "write_status", "completed_before"]


def run_job(cfg, output_dir, *, sweep_dir, registry=None, needs_objective=False) -> dict | None:
    """Run one job of a sweep into ``output_dir``; return its results, or None if it failed.

    Trajectories are shared through ``<sweep_dir>/.cache``.  Any exception is logged and written to
    ``output_dir/status.json`` (``{"status": "failed", "error": ..., "traceback": ...}``) rather than
    raised, so the other jobs and the sweep report are not lost.  An interrupt (Ctrl-C, SIGTERM)
    is written as ``{"status": "interrupted"}`` and raised again: it ends the sweep; one
    received before the job starts (its exception dropped where it landed,
    :mod:`~topomap.app.run.interrupts`) ends it there.
    ``status.json`` also holds the job's wall time, process id and host.  A job folder that holds
    another run's outputs is left as it is (the error is logged).
    """
    out = Path(output_dir)
    t0 = time.perf_counter()
    done = completed_before(out, cfg)
    if done is not None:
        log.info("job in %s completed before with the same config (output.resume=true): not "
                 "run again", out)
        return done
    try:
        stop_if_interrupted()
        results = run(cfg, out, registry=registry, cache_dir=Path(sweep_dir) / CACHE_DIR,
                      needs_objective=needs_objective, folder_key="hydra.sweep.dir")
    except OutputDirInUse as exc:
        log.error("job not run: %s", exc)
        return None
    except KeyboardInterrupt:
        ending()  # a second Ctrl-C must not cut the status and the report short
        write_status(out, "interrupted", job_time=time.perf_counter() - t0)
        raise
    except Exception as exc:
        if isinstance(exc, ValueError):
            log.error("job failed: %s", exc)
        else:
            log.exception("job failed: %s", f"{type(exc).__name__}: {exc}")
        write_status(out, "failed", exc, job_time=time.perf_counter() - t0)
        return None
    write_status(out, "completed", job_time=time.perf_counter() - t0)
    return results


def _comparable(cfg: dict) -> dict:
    """A run's config as ``metrics.json`` keeps it, without ``output.resume``."""
    plain = json.loads(json.dumps(cfg, default=str))
    (plain.get("output") or {}).pop("resume", None)
    return plain


def completed_before(out: Path, cfg) -> dict | None:
    """With ``output.resume``: the results of the job that completed in ``out`` with the same
    config (its ``status.json`` says completed, its ``metrics.json`` holds the config), else
    None (it runs)."""
    from omegaconf import OmegaConf

    plain = OmegaConf.to_container(cfg, resolve=True, enum_to_str=True) \
        if OmegaConf.is_config(cfg) else dict(cfg)
    if not (plain.get("output") or {}).get("resume"):
        return None
    try:
        status = json.loads((out / STATUS_FILE).read_text())
        metrics = json.loads((out / METRICS_FILE).read_text())
    except (OSError, ValueError):
        return None
    if status.get("status") != "completed" or not isinstance(metrics, dict):
        return None
    return metrics if _comparable(metrics.get("config") or {}) == _comparable(plain) else None


def write_status(out, status: str, error: BaseException | None = None, **extra) -> None:
    """Write ``out/status.json``: the ``status`` (``completed``, ``failed``, ``interrupted``),
    the ``error`` (``"<type>: <message>"``) and its traceback, the process id and the host."""
    record = {"status": status, "error": None, **extra}
    if error is not None:
        record["error"] = f"{type(error).__name__}: {error}"
        record["traceback"] = "".join(traceback.format_exception(error))
    _write_status(Path(out), record)


def _write_status(out: Path, status: dict) -> None:
    write_json(out / STATUS_FILE, {**status, "pid": os.getpid(), "host": socket.gethostname()})
