"""One job of a sweep, and the ``status.json`` a job or a run that did not complete leaves.

A job shares simulated trajectories through the sweep's folder and never raises what fails it:
the error goes to its ``status.json``, so that the other jobs and the sweep report are not
lost (:func:`run_job`).  :func:`write_status` writes the file (``completed``, ``failed`` or
``interrupted``, the error, the process and the host).
"""

from __future__ import annotations

import logging
import os
import socket
import time
import traceback
from pathlib import Path

from ..results import CACHE_DIR, STATUS_FILE
from .experiment import run
from .outputs import OutputDirInUse, write_json

log = logging.getLogger("topomap")

__all__ = ["run_job", "write_status"]


def run_job(cfg, output_dir, *, sweep_dir, registry=None, needs_objective=False) -> dict | None:
    """Run one job of a sweep into ``output_dir``; return its results, or None if it failed.

    Trajectories are shared through ``<sweep_dir>/.cache``.  Any exception is logged and written to
    ``output_dir/status.json`` (``{"status": "failed", "error": ..., "traceback": ...}``) rather than
    raised, so the other jobs and the sweep report are not lost.  An interrupt (Ctrl-C, SIGTERM)
    is written as ``{"status": "interrupted"}`` and raised again: it ends the sweep.
    ``status.json`` also holds the job's wall time, process id and host.  A job folder that holds
    another run's outputs is left as it is (the error is logged).
    """
    out = Path(output_dir)
    t0 = time.perf_counter()
    try:
        results = run(cfg, out, registry=registry, cache_dir=Path(sweep_dir) / CACHE_DIR,
                      needs_objective=needs_objective)
    except OutputDirInUse as exc:
        log.error("job not run: %s", exc)
        return None
    except KeyboardInterrupt:
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
