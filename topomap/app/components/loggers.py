"""Experiment tracking: the ``logger`` component records a finished run somewhere else too.

A logger is a component of the kind ``logger`` (``topomap logger=<name>``), registered through
the same ``topomap_register_components`` hook as every other component, so a plugin adds one
(W&B, TensorBoard, ...) the way it adds a world: see ``docs/plugins.md``.  Its factory's
signature is its config (``logger.<param>``); the object it returns has one method,
``log_run(record)``, called once a run has written its outputs, with a :class:`RunRecord`: the
run's config flattened into parameters, its scalar metrics, its per-split series and its files.
It may also have ``check()``, called before the run reads its data (a store that cannot be
reached fails the run at once), and ``log_sweep(sweep_dir, start_dir)``, called once a sweep's
report is written.

topomap ships ``none`` (the default) and ``mlflow`` (:class:`MLflowLogger`, the optional
``mlflow`` package: ``pip install "topomap[mlflow]"``).
"""

from __future__ import annotations

import importlib.util
import os
from contextlib import nullcontext
from dataclasses import dataclass, field
from pathlib import Path

from ..results import COLUMNS, METRICS_FILE, select

__all__ = ["RunRecord", "MLflowLogger", "ARTIFACTS"]

#: the files of a run a logger keeps (those the run wrote): the map, its graph, the metrics and
#: every figure
ARTIFACTS = ("map.json", "map.graphml", METRICS_FILE, "map.html", "fig_*.png")


def _flatten(value, prefix="") -> dict[str, str]:
    if isinstance(value, dict):
        out = {}
        for k, v in value.items():
            out.update(_flatten(v, f"{prefix}{k}."))
        return out
    return {prefix[:-1]: "null" if value is None else str(value)}


@dataclass
class RunRecord:
    """What a logger is given about one finished run.

    Attributes
    ----------
    output_dir : Path
        The run's folder (every file it wrote).
    config : dict
        The run's resolved config.
    results : dict
        What ``metrics.json`` holds.
    start_dir : Path
        The folder ``topomap`` was started from (``outputs/`` is below it by default).
    sweep_dir : Path or None
        The sweep's folder when the run is a job of a sweep (``topomap -m``), else None.
    """

    output_dir: Path
    config: dict
    results: dict
    start_dir: Path = field(default_factory=Path.cwd)
    sweep_dir: Path | None = None

    def params(self) -> dict[str, str]:
        """The config flattened to ``{"clusters.ns": "20", ...}`` (values as text)."""
        return _flatten(self.config)

    def metrics(self) -> dict[str, float]:
        """The run's numbers by name: every numeric column of a sweep's ``summary.csv`` that the
        run has (``ari``, ``nmi``, ``purity``, ``compound_states``, their ``_phase1`` values,
        ``H_o``, ``H_u``, ``H_x``, ``heldout_loglik``, ``n_states``, ``n_states_phase1``, ...),
        ``n_states_split`` for a refined run, ``objective`` and every timing as
        ``time_<part>`` (seconds)."""
        out = {}
        for column in COLUMNS:
            if column.file != METRICS_FILE:
                continue
            places = (column.place,) if isinstance(column.place, str) else column.place
            values = [select(self.results, p) for p in places]
            if all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values):
                out[column.name] = float(sum(values))
        split = select(self.results, "n_states.split")
        if split is not None:
            out["n_states_split"] = float(split)
        objective = select(self.results, "objective.value")
        if objective is not None:
            out["objective"] = float(objective)
        for part, seconds in (self.results.get("timings") or {}).items():
            if isinstance(seconds, (int, float)):
                out[f"time_{part}"] = float(seconds)
        return out

    def series(self) -> dict[str, list[tuple[int, float]]]:
        """The entropies after phase 1 (step 0) and after each split (step k), and after the
        refinement when there is one: ``{"H_o": [(0, ...), (1, ...)], "H_u": ..., "H_x": ...,
        "n_states": ...}``."""
        out: dict[str, list[tuple[int, float]]] = {}
        for step, entry in enumerate(self.results.get("entropy_trace") or []):
            for name in ("H_o", "H_u", "H_x", "n_states"):
                if isinstance(entry.get(name), (int, float)):
                    out.setdefault(name, []).append((step, float(entry[name])))
        return out

    def artifacts(self) -> list[Path]:
        """The run's files of :data:`ARTIFACTS` that it wrote, in that order."""
        out = []
        for pattern in ARTIFACTS:
            out += sorted(Path(self.output_dir).glob(pattern))
        return out

    @property
    def name(self) -> str:
        """The run's name: ``<sweep folder>/<job>`` for a job of a sweep, else
        ``<date>/<time>`` of its folder."""
        out = Path(self.output_dir)
        return f"{out.parent.name}/{out.name}"


class MLflowLogger:
    """Log every run to MLflow: the flattened config as parameters, the metrics
    (:meth:`RunRecord.metrics`), the entropies per split as stepped metrics (``split.H_u``, ...)
    and the run's files (:data:`ARTIFACTS`) as artifacts; one MLflow run per run, or per job of a
    sweep (all in one experiment, tagged with the sweep's folder).

    Parameters
    ----------
    tracking_uri : str or None
        Where MLflow keeps the runs (any MLflow tracking URI: ``sqlite:///path/mlflow.db``,
        ``http://host:5000``, ...).  None: a local store, ``outputs/mlflow.db`` below the folder
        ``topomap`` was started from; no server needed (``mlflow ui --backend-store-uri
        sqlite:///outputs/mlflow.db`` shows it).  A local SQLite store keeps the artifacts of
        the experiments it creates in ``mlartifacts/`` beside it.
    experiment : str
        The MLflow experiment the runs go to (made when missing).
    """

    def __init__(self, tracking_uri: str | None = None, experiment: str = "topomap"):
        if importlib.util.find_spec("mlflow") is None:
            raise ValueError('needs the mlflow package: pip install "topomap[mlflow]"')
        if not experiment:
            from ...core.checks import ParameterError

            raise ParameterError("experiment", "must name an MLflow experiment")
        self.tracking_uri = tracking_uri
        self.experiment = experiment

    def check(self) -> None:
        """Before the run reads its data: refuse a tracking server that does not answer
        (:func:`check_server`)."""
        try:
            check_server(self.tracking_uri)
        except ValueError as exc:
            raise ValueError(f"logger=mlflow: {exc}") from None

    def store(self, start_dir) -> tuple[str, str | None]:
        """``(tracking URI, artifact location of a new experiment)``: a local SQLite store keeps
        its artifacts in ``mlartifacts/`` beside it; for any other URI the location is None (the
        tracking server's own)."""
        uri = self.tracking_uri or f"sqlite:///{Path(start_dir).resolve() / 'outputs' / 'mlflow.db'}"
        if not uri.startswith("sqlite:///"):
            return uri, None
        folder = Path(uri[len("sqlite:///"):]).parent
        folder.mkdir(parents=True, exist_ok=True)
        return uri, (folder / "mlartifacts").as_uri()

    def log_run(self, record: RunRecord) -> str:
        """Log ``record`` as one MLflow run (a child of its sweep's run, for a job of a
        sweep); returns its run id.  A store that cannot take it is a one-line ValueError."""
        uri, artifacts = self.store(record.start_dir)
        with self._lock(uri):
            try:
                return self._log(uri, artifacts, record)
            except Exception as exc:  # MLflow's and its HTTP client's errors alike
                raise ValueError(f"logger=mlflow could not log the run to {uri} "
                                 f"({type(exc).__name__}: {' '.join(str(exc).split())[:200]}); "
                                 f"its files are in {record.output_dir}") from None

    @staticmethod
    def _lock(uri: str):
        from filelock import FileLock

        if uri.startswith("sqlite:///"):  # jobs of a sweep writing at once: one at a time
            return FileLock(uri[len("sqlite:///"):] + ".lock", timeout=600)
        return nullcontext()

    def log_sweep(self, sweep_dir, start_dir=None) -> str | None:
        """Put the sweep report's files (``summary.csv``, ``summary_<metric>.png``) into the
        sweep's MLflow run, the parent of its jobs' runs, and end it; returns its run id (None
        when no job of the sweep was logged)."""
        from mlflow.tracking import MlflowClient

        uri, _ = self.store(start_dir or Path.cwd())
        parent = _parent_file(sweep_dir)
        if not parent.is_file():
            return None
        run_id = parent.read_text().strip()
        with self._lock(uri):
            client = MlflowClient(tracking_uri=uri)
            for path in sorted(Path(sweep_dir).glob("summary*")):
                client.log_artifact(run_id, str(path))
            client.set_terminated(run_id)
        return run_id

    def _log(self, uri, artifacts, record: RunRecord) -> str:
        import time

        from mlflow.entities import Metric, Param, RunTag
        from mlflow.tracking import MlflowClient

        client = MlflowClient(tracking_uri=uri)
        experiment = client.get_experiment_by_name(self.experiment)
        experiment_id = (experiment.experiment_id if experiment is not None else
                         client.create_experiment(self.experiment, artifact_location=artifacts))
        tags = {"topomap.output_dir": str(Path(record.output_dir).resolve())}
        if record.sweep_dir is not None:
            tags["topomap.sweep_dir"] = str(Path(record.sweep_dir).resolve())
            tags["mlflow.parentRunId"] = _sweep_run(client, experiment_id, record.sweep_dir)
        run = client.create_run(experiment_id, run_name=record.name, tags=tags)
        run_id = run.info.run_id
        now = int(time.time() * 1000)
        params = [Param(k, v[:6000]) for k, v in record.params().items()]
        metrics = [Metric(k, v, now, 0) for k, v in record.metrics().items()]
        metrics += [Metric(f"split.{name}", v, now, step)
                    for name, points in record.series().items() for step, v in points]
        for i in range(0, max(len(params), len(metrics)), 100):  # MLflow's batch limits
            client.log_batch(run_id, metrics=metrics[i:i + 100], params=params[i:i + 100],
                             tags=[RunTag("topomap.version", record.results.get(
                                 "versions", {}).get("topomap") or "")] if i == 0 else [])
        for path in record.artifacts():
            client.log_artifact(run_id, str(path))
        client.set_terminated(run_id)
        return run_id


def _parent_file(sweep_dir) -> Path:
    """Where a sweep keeps the id of its MLflow run."""
    return Path(sweep_dir) / ".mlflow_run"


def _sweep_run(client, experiment_id: str, sweep_dir) -> str:
    """The id of the sweep's MLflow run, the parent of its jobs' runs: made by the first job
    that logs (its id kept in the sweep folder, under a lock every job of the sweep sees)."""
    from filelock import SoftFileLock

    path = _parent_file(sweep_dir)
    with SoftFileLock(str(path) + ".lock", timeout=600):
        if path.is_file():
            return path.read_text().strip()
        folder = Path(sweep_dir).resolve()
        run = client.create_run(experiment_id, run_name=f"{folder.parent.name}/{folder.name}",
                                tags={"topomap.sweep_dir": str(folder)})
        path.write_text(run.info.run_id + "\n")
        return run.info.run_id


def check_server(tracking_uri: str | None, timeout: float = 5.0) -> None:
    """Refuse, in one line, an ``http(s)://`` tracking URI where no server answers (MLflow's
    client would retry for minutes after the map is learned, then end in a traceback)."""
    if not tracking_uri or not tracking_uri.startswith(("http://", "https://")):
        return
    import urllib.error
    import urllib.request

    try:
        with urllib.request.urlopen(tracking_uri.rstrip("/") + "/health", timeout=timeout):
            pass
    except urllib.error.HTTPError:
        pass  # a server answers (perhaps behind a proxy or with authentication)
    except (urllib.error.URLError, OSError) as exc:
        reason = getattr(exc, "reason", exc)
        raise ValueError(f"logger.tracking_uri={tracking_uri}: no MLflow tracking server "
                         f"answers ({reason}); start it (mlflow server --host ... --port ...) "
                         "or leave logger.tracking_uri out to keep the runs in "
                         "outputs/mlflow.db") from None


def start_dir() -> Path:
    """The folder ``topomap`` was started from: Hydra's ``runtime.cwd`` inside a Hydra job,
    else the working directory."""
    try:
        from hydra.core.hydra_config import HydraConfig

        return Path(HydraConfig.get().runtime.cwd)
    except Exception:  # not inside a Hydra job (the Python API, tests)
        return Path(os.getcwd())
