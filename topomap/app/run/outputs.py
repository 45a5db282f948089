"""The files a run writes into its output folder."""

from __future__ import annotations

import json
import os
import shutil
import sys
import tempfile
import time
from contextlib import contextmanager
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path

import numpy as np

from ...core.data.atomic import atomic_write
from ...core.data.trajectory import save_trajectory
from ...core.map.files import finite_json
from ..results import (FIGURE_FILES, LOCALIZE_FILES, MAPPING_FIGURES, METRICS_FILE, OUTPUT_FILES,
                       PATH_FIGURES, ROBOT_FILES, STATUS_FILE)
from .interrupts import held_signals, stop_if_interrupted

__all__ = ["write_outputs", "write_localization", "versions", "numeric_kernels", "write_json",
           "staged", "own_files", "claim_output_dir", "locked_output_dir", "remove_new_folder",
           "OutputDirInUse", "LOCK_FILE"]

#: where a run stages its files before they move into its folder (hidden, removed afterwards)
STAGE_PREFIX = ".topomap-partial-"


def own_files(out) -> list[Path]:
    """The files of ``out`` that a topomap run writes (every file of :data:`OUTPUT_FILES`,
    :data:`FIGURE_FILES`, :data:`PATH_FIGURES`, :data:`MAPPING_FIGURES`, :data:`LOCALIZE_FILES`,
    :data:`ROBOT_FILES`, ``status.json``, and
    any staging folder a killed run left); never a file topomap does not know, nor Hydra's
    ``.hydra/`` and log."""
    out = Path(out)
    names = {*OUTPUT_FILES, *FIGURE_FILES, *PATH_FIGURES, *MAPPING_FIGURES, *LOCALIZE_FILES,
             *ROBOT_FILES, STATUS_FILE}
    if not out.is_dir():
        return []
    return sorted(p for p in out.iterdir()
                  if p.name in names or (p.is_dir() and p.name.startswith(STAGE_PREFIX)))


class OutputDirInUse(ValueError):
    """The output folder holds another run's outputs (and ``output.overwrite`` is false), or
    another run is writing into it."""


def claim_output_dir(out, overwrite: bool = False, *, check_only: bool = False,
                     key: str = "hydra.run.dir") -> list[str]:
    """Make ``out`` ready for a run: refuse (:class:`OutputDirInUse`, naming the config ``key``
    that chose the folder) when it holds another run's outputs (:func:`own_files`), or with
    ``overwrite`` remove them.  Returns the names removed.  A folder whose run failed, was
    interrupted or killed (it holds ``status.json`` or the hidden staging folder of files that
    never moved in, and nothing else of topomap's) is free: they are removed.  A run still
    writing holds the folder's lock (:func:`locked_output_dir`), checked before this.
    ``check_only``: refuse as said, and change nothing."""
    found = own_files(out)
    if [p.name for p in found if not p.name.startswith(STAGE_PREFIX)] in ([], [STATUS_FILE]):
        if not check_only:
            for p in found:
                shutil.rmtree(p) if p.is_dir() else p.unlink()
        return []
    if found and not overwrite:
        names = ", ".join(p.name for p in found[:3]) + (", ..." if len(found) > 3 else "")
        raise OutputDirInUse(f"the output folder {out} holds another run's outputs ({names}); "
                             f"choose another {key}, or give output.overwrite=true to "
                             "replace them")
    if check_only:
        return []
    for p in found:
        shutil.rmtree(p) if p.is_dir() else p.unlink()
    return [p.name for p in found]


#: the lock file a run holds in its folder while it runs
LOCK_FILE = ".topomap.lock"


@contextmanager
def locked_output_dir(out, overwrite: bool = False):
    """Hold ``out`` for one run of the ``topomap`` command, from before Hydra writes its
    ``.hydra/`` to the end: a second run into the same folder is refused
    (:class:`OutputDirInUse`) while this one holds it (a lock file, ``filelock``) or once it has
    left its outputs (:func:`claim_output_dir`).  Yields whether the folder is new: a run that
    fails on its settings or its data removes a folder it made (:func:`remove_new_folder`)."""
    from filelock import FileLock, Timeout

    out = Path(out)
    claim_output_dir(out, overwrite, check_only=True)  # before making anything
    new = not out.exists()
    out.mkdir(parents=True, exist_ok=True)
    lock = FileLock(str(out / LOCK_FILE), timeout=0)
    try:
        lock.acquire()
    except Timeout:
        raise OutputDirInUse(f"another topomap run is writing into the output folder {out}; "
                             "choose another hydra.run.dir") from None
    try:
        claim_output_dir(out, overwrite, check_only=True)  # a run that ended meanwhile
        yield new
    finally:
        lock.release()


def remove_new_folder(out) -> bool:
    """Remove the folder of a run that made it and failed before writing its outputs: what
    Hydra wrote (``.hydra/``, the log), the run's ``status.json`` and the lock file.  A folder
    holding the run's outputs (it failed after writing them: its logger, say) is kept.
    Returns whether it was removed."""
    if any(p.name != STATUS_FILE and not p.name.startswith(STAGE_PREFIX) for p in own_files(out)):
        return False
    shutil.rmtree(out, ignore_errors=True)
    return True


#: files moved into a run's folder last, in this order: a reader that finds them finds the rest
_LAST = (METRICS_FILE, STATUS_FILE)


@contextmanager
def staged(out):
    """A hidden folder inside ``out`` to write a run's files into.  When the block succeeds
    they move into ``out`` together (``metrics.json`` last, signals held meanwhile), so that
    ``out`` never holds some of a run's files without the rest; when it fails, or is
    interrupted -- also by a signal whose exception was dropped where it landed, while the
    figures were drawn, say (:func:`~topomap.app.run.interrupts.stop_if_interrupted`) -- the
    folder is removed and ``out`` is left as it was."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    stage = Path(tempfile.mkdtemp(prefix=STAGE_PREFIX, dir=out))
    try:
        yield stage
        stop_if_interrupted()
        names = sorted((p.name for p in stage.iterdir()),
                       key=lambda n: (_LAST.index(n) if n in _LAST else -1, n))
        with held_signals():
            for name in names:
                os.replace(stage / name, out / name)
    finally:
        shutil.rmtree(stage, ignore_errors=True)


def versions() -> dict:
    """Python's and every relevant package's version, and the machine's numeric kernels
    (``numeric_kernels``: :func:`numeric_kernels`), for the record."""
    out = {"python": sys.version.split()[0]}
    for pkg in ("topomap", "numpy", "scikit-learn", "networkx", "hydra-core", "omegaconf",
                "pluggy", "matplotlib", "plotly"):
        try:
            out[pkg] = version(pkg)
        except PackageNotFoundError:
            out[pkg] = None
    out["numeric_kernels"] = numeric_kernels()
    return out


def numeric_kernels() -> dict:
    """The vector instructions numpy's loops use on this CPU (``numpy_simd``, e.g. ``["X86_V3",
    "X86_V4", "AVX512_ICL"]``) and the BLAS build and kernel set (``blas``, e.g. ``"openblas
    0.3.31 SkylakeX"``).  Sums and transcendental functions round their last bit by these, so
    two machines that differ here can give maps whose floats differ in the last bits, and
    continuous walks that part after a few thousand steps (``docs/file-formats.md``)."""
    from threadpoolctl import threadpool_info

    try:  # numpy's own record of its dispatch, as np.show_runtime() prints it (numpy 2)
        from numpy._core._multiarray_umath import __cpu_dispatch__, __cpu_features__
    except ImportError:  # pragma: no cover - numpy 1.26
        from numpy.core._multiarray_umath import __cpu_dispatch__, __cpu_features__
    simd = [f for f in __cpu_dispatch__ if __cpu_features__.get(f)]
    blas = [" ".join(str(p) for p in (i.get("internal_api"), i.get("version"),
                                      i.get("architecture")) if p)
            for i in threadpool_info() if i.get("user_api") == "blas"]
    return {"numpy_simd": simd, "blas": blas}


def _json_default(obj):
    if isinstance(obj, np.integer):
        return int(obj)
    if isinstance(obj, np.floating):
        return float(obj)
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    raise TypeError(f"{type(obj).__name__} is not JSON serialisable")


def write_json(path, obj) -> None:
    """Write ``obj`` as indented JSON with sorted keys, atomically."""
    text = json.dumps(finite_json(json.loads(json.dumps(obj, default=_json_default))), indent=1,
                      sort_keys=True, allow_nan=False)
    atomic_write(path, lambda tmp: Path(tmp).write_text(text + "\n"))


def write_states(path: Path, traj, **columns) -> None:
    """``states.csv``: the step, the given state columns and, with ground truth, the place."""
    columns = {"step": np.arange(len(traj)), **columns}
    if traj.places is not None:
        columns["place"] = traj.places
    table = np.column_stack(list(columns.values()))
    atomic_write(path, lambda tmp: np.savetxt(tmp, table, fmt="%d", delimiter=",",
                                              header=",".join(columns), comments=""))


def write_outputs(out: Path, traj, learner, results, cfg, env=None) -> None:
    """Write every output file of a run into ``out``: all of them are written into a staging
    folder first and move into ``out`` together (:func:`staged`)."""
    with staged(out) as stage:
        _write_outputs(stage, traj, learner, results, cfg, env)


def _write_outputs(out: Path, traj, learner, results, cfg, env=None) -> None:
    t0 = time.perf_counter()
    save_trajectory(traj, out / "trajectory.npz")
    m = learner.map_
    m.save(out / "map.json")
    m.to_graphml(out / "map.graphml", min_prob=cfg["output"]["min_prob"])
    if getattr(learner, "robot_map_", None) is not None:  # learner.motion.mode=robot
        from ...core.motion.robot_io import save_robot_map
        save_robot_map(learner.robot_map_, out / next(iter(ROBOT_FILES)))
    write_states(out / "states.csv", traj, state_phase1=learner.labels_phase1_,
                 state=learner.labels_)
    if cfg["output"]["figures"]:
        from .. import plots

        plots.write_figures(out, traj, learner, env, min_prob=cfg["output"]["min_prob"],
                            compound_state=cfg["output"].get("compound_state"),
                            seed=int(cfg["seed"]))
        from ..plots.interactive import write_map_html

        names = (traj.meta or {}).get("place_names") or getattr(env, "place_names", None)
        walls = getattr(env, "wall_segments", None) if traj.positions is not None else None
        write_map_html(out / "map.html", m, learner.labels_, traj.positions, traj.places,
                       min_prob=cfg["output"]["min_prob"], seed=int(cfg["seed"]),
                       place_names=names, walls=walls)
    results["timings"]["outputs"] = time.perf_counter() - t0
    write_json(out / METRICS_FILE, results)


def write_localization(out: Path, traj, beliefs, viterbi, results) -> None:
    """Write the files of a ``task=localize`` run (:data:`LOCALIZE_FILES`) into ``out`` (staged
    like :func:`write_outputs`)."""
    with staged(out) as stage:
        _write_localization(stage, traj, beliefs, viterbi, results)


def _write_localization(out: Path, traj, beliefs, viterbi, results) -> None:
    write_states(out / "states.csv", traj, state_filter=beliefs.argmax(axis=1),
                 state_viterbi=viterbi)

    def save_beliefs(tmp):
        with open(tmp, "wb") as fh:
            np.savez_compressed(fh, beliefs=beliefs)

    atomic_write(out / "beliefs.npz", save_beliefs)
    write_json(out / METRICS_FILE, results)
