"""Reading a sweep: the job folders that ``topomap -m ...`` left, and the keys the sweep varies.

Every job of a sweep writes its folder (Hydra's ``.hydra/``, then ``status.json`` and
``metrics.json``, see :func:`topomap.app.run.job.run_job`); :func:`read_jobs` reads them back
as :class:`Job` records, whatever a crash or a kill left behind, and :func:`swept_keys` names the
keys whose values tell the jobs apart.  :mod:`topomap.app.report.summary` builds the report from them.
"""

from __future__ import annotations

import itertools
import json
from dataclasses import dataclass, field
from pathlib import Path

from ..results import CACHE_DIR, METRICS_FILE, STATUS_FILE, STUDY_FILE

__all__ = ["Job", "read_jobs", "swept_keys", "planned_jobs", "not_started", "STATUSES",
           "check_sweep_folder", "read_study"]

#: the option of Hydra's ``hydra/sweeper`` group that runs a grid (Hydra's default), as the
#: multirun config records the choices made (``hydra.runtime.choices``)
BASIC_SWEEPER = "basic"

#: the status of a job in the report: completed, failed or interrupted (its ``status.json``
#: says so), incomplete (no status: still running, killed or lost) or not started (a job of
#: the sweep's plan without a folder)
STATUSES = ("completed", "failed", "interrupted", "incomplete", "not started")


@dataclass
class Job:
    """What one job folder of a sweep holds: its number and folder, its overrides (``{key:
    value}``), its ``status`` (one of :data:`STATUSES`) and ``error``, its
    ``metrics.json`` (``{}`` unless completed) and its ``status.json`` (``{}`` if none)."""

    num: int
    path: Path
    overrides: dict[str, str]
    status: str
    error: str | None = None
    metrics: dict = field(default_factory=dict)
    status_file: dict = field(default_factory=dict)

    @property
    def job_time(self) -> float | None:
        """The job's wall time in seconds (from ``status.json``), None if not recorded."""
        return self.status_file.get("job_time")


def check_sweep_folder(sweep_dir, multirun_cfg, resume: bool) -> list[Job]:
    """Refuse (a ValueError naming ``hydra.sweep.dir``) a sweep into a folder that holds jobs,
    before its first job: their folders would be taken by the new sweep's jobs of the same
    number.  With ``resume`` (``output.resume=true``) the folder must hold the jobs of the same
    sweep (for a grid, each job's settings are those the sweep plans for its number); the
    completed ones are then not run again.  Returns the jobs found."""
    sweep_dir = Path(sweep_dir)
    jobs = read_jobs(sweep_dir) if sweep_dir.is_dir() else []
    if not jobs:
        return jobs
    if not resume:
        raise ValueError(f"hydra.sweep.dir={sweep_dir} already holds a sweep ({len(jobs)} job "
                         "folders); choose another hydra.sweep.dir, or give output.resume=true "
                         "to run only the jobs it has not completed")
    plan = planned_jobs(multirun_cfg)
    if plan is None:
        raise ValueError(f"hydra.sweep.dir={sweep_dir} holds a search; output.resume=true goes "
                         "on with a grid: a search goes on with its study in a new sweep "
                         "folder, given hydra.sweeper.storage.resume_from="
                         f"{sweep_dir.resolve()}")
    for job in jobs:
        wanted = _settings(plan[job.num]) if job.num < len(plan) else {}
        held = _settings(job.overrides)
        if wanted != held:
            other = " ".join(f"{k}={job.overrides[k]}" for k in held
                             if wanted.get(k, _ABSENT) != held[k]) or "other settings"
            raise ValueError(f"hydra.sweep.dir={sweep_dir} holds job {job.num} of another "
                             f"sweep ({other}); output.resume=true goes on with the same sweep "
                             "only: choose another hydra.sweep.dir")
    return jobs


def _settings(overrides: dict[str, str]) -> dict:
    """A job's overrides as values (YAML's reading of the text), without ``output.resume``."""
    import yaml

    out = {}
    for key, text in overrides.items():
        if key != "output.resume":
            try:
                out[key] = yaml.safe_load(text)
            except yaml.YAMLError:
                out[key] = text
    return out


def _key_value(override: str) -> tuple[str, str]:
    key, _, value = str(override).partition("=")
    return key.lstrip("+~"), value


def _job_num(path: Path, fallback: int) -> int:
    from omegaconf import OmegaConf

    try:
        return int(OmegaConf.load(path / ".hydra" / "hydra.yaml").hydra.job.num)
    except Exception:
        try:
            return int(path.name)
        except ValueError:
            return fallback


def read_jobs(sweep_dir) -> list[Job]:
    """Every job folder under ``sweep_dir`` (a folder holding ``.hydra/``), by job number.

    A job's status is that of its ``status.json``; without one it is ``completed`` if it wrote
    ``metrics.json`` and ``incomplete`` otherwise (still running, killed or lost).  Reading never
    fails on what a crash or a kill leaves behind: a ``.hydra`` folder without ``overrides.yaml``,
    a truncated ``status.json`` or ``metrics.json``; the job's error says what is wrong, and a job
    without a readable ``metrics.json`` is never ``completed``.
    """
    sweep_dir = Path(sweep_dir)
    jobs = []
    for i, hydra_dir in enumerate(sorted(sweep_dir.rglob(".hydra"))):
        path = hydra_dir.parent
        if hydra_dir.is_dir() and CACHE_DIR not in path.relative_to(sweep_dir).parts:
            jobs.append(_read_job(path, i))
    return sorted(jobs, key=lambda j: j.num)


def _read_job(path: Path, index: int) -> Job:
    """The job in folder ``path`` (``index``: its number if Hydra's files do not tell)."""
    problems: list[str] = []
    overrides = _read_overrides(path, problems)
    status = _read_json(path / STATUS_FILE, problems)
    metrics = _read_json(path / METRICS_FILE, problems)
    state = status.get("status")
    if state is None:  # no status.json: the job ended (or was stopped) before writing it
        state = "completed" if metrics else "incomplete"
        if not (path / STATUS_FILE).exists() and not (path / METRICS_FILE).exists():
            problems.append(f"no {STATUS_FILE} or {METRICS_FILE}: the job is still running, or "
                            "was killed or lost")
    elif state not in ("completed", "failed", "interrupted"):
        problems.append(f"{STATUS_FILE} gives the unknown status {state!r}")
        state = "incomplete"
    if state == "completed" and not metrics:
        state = "incomplete"
        if not (path / METRICS_FILE).is_file():
            problems.append(f"{METRICS_FILE} is missing")
    if state == "completed" and not _same_settings(overrides, metrics.get("config")):
        state = "incomplete"
        problems.append(f"its {METRICS_FILE} holds the results of a run of other settings")
    errors = [str(status["error"])] if status.get("error") else []
    return Job(num=_job_num(path, index), path=path, overrides=overrides, status=state,
               error="; ".join(errors + problems) or None,
               metrics=metrics if state == "completed" else {}, status_file=status)


def _same_settings(overrides: dict[str, str], config) -> bool:
    """Whether the run's resolved ``config`` (``metrics.json``) has the values its job's
    ``overrides`` give (a group's value is its component's name); True without a config."""
    import yaml

    if not isinstance(config, dict):
        return True
    for key, text in overrides.items():
        if key == "output.resume":  # a resumed sweep keeps its jobs of the same settings
            continue
        node = config
        for part in key.split("."):
            if not isinstance(node, dict) or part not in node:
                node = _ABSENT
                break
            node = node[part]
        if node is _ABSENT:
            continue  # a key the run's config does not keep (hydra.*, a deleted one)
        if isinstance(node, dict):
            node = node.get("component", node)
        try:
            value = yaml.safe_load(text)
        except yaml.YAMLError:
            value = text
        if node != value and str(node) != text:
            return False
    return True


_ABSENT = object()


def _read_overrides(path: Path, problems: list[str]) -> dict[str, str]:
    """The job's ``.hydra/overrides.yaml`` as ``{key: value}``; ``{}`` (and a note in
    ``problems``) when it is missing or unreadable."""
    from omegaconf import OmegaConf

    file = path / ".hydra" / "overrides.yaml"
    if not file.is_file():
        problems.append(f"{file.relative_to(path)} is missing")
        return {}
    try:
        overrides = OmegaConf.to_container(OmegaConf.load(file))
        if not isinstance(overrides, list):
            raise ValueError("it is not a list of overrides")
        return dict(_key_value(o) for o in overrides)
    except Exception as exc:  # a YAML or OmegaConf error: the file was cut short
        problems.append(f"{file.relative_to(path)} is unreadable ({_one_line(exc)})")
        return {}


def _read_json(path: Path, problems: list[str]) -> dict:
    """The JSON object in ``path``; ``{}`` when there is no such file, and also (with a note in
    ``problems``) when it is unreadable, e.g. cut short by a kill."""
    if not path.is_file():
        return {}
    try:
        value = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, RecursionError, ValueError) as exc:
        problems.append(f"{path.name} is unreadable ({_one_line(exc)})")
        return {}
    if not isinstance(value, dict):
        problems.append(f"{path.name} does not hold a JSON object")
        return {}
    return value


def _one_line(exc: BaseException) -> str:
    """An exception's message on one line, cut to 120 characters."""
    text = " ".join(str(exc).split()) or type(exc).__name__
    return text if len(text) <= 120 else text[:117] + "..."


def read_study(folder) -> dict:
    """The study a search left in ``folder`` (its :data:`~topomap.app.results.STUDY_FILE`):
    ``objective`` (None in a file that does not say), ``sweep_dir`` (the search's folder, as
    its command gave it; ``folder`` in a file that does not say) and ``trials``, each with
    ``number``, ``state``, ``values``, ``params``, ``distributions`` and where it ran,
    ``sweep_dir`` and ``job`` (in a file that does not say: the search's and the trial's
    number).  A ValueError
    naming the file when there is none or it cannot be read."""
    source = Path(folder) / STUDY_FILE
    try:
        study = json.loads(source.read_text())
        trials = [dict(t) for t in study["trials"]]
        home = str(study.get("sweep_dir", folder))
        for t in trials:
            t.setdefault("sweep_dir", home)
            t.setdefault("job", t["number"])
            missing = [k for k in ("state", "values", "params", "distributions") if k not in t]
            if missing:
                raise KeyError(f"a trial without {missing[0]!r}")
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise ValueError(f"no study in {source} ({type(exc).__name__}: {exc})") from None
    return {"objective": study.get("objective"), "sweep_dir": home, "trials": trials}


def planned_jobs(multirun_cfg) -> list[dict[str, str]] | None:
    """The overrides (``{key: value}``) of every job the sweep of ``multirun_cfg`` was to run, in
    job order, when its sweeper plans them ahead (Hydra's basic sweeper: every combination of
    the swept values); None when it does not tell (e.g. an optimising sweeper)."""
    from hydra.core.override_parser.overrides_parser import OverridesParser
    from omegaconf import OmegaConf

    if multirun_cfg is None:
        return None
    choices = OmegaConf.select(multirun_cfg, "hydra.runtime.choices", default=None) or {}
    if choices.get("hydra/sweeper") != BASIC_SWEEPER:
        return None
    task = OmegaConf.select(multirun_cfg, "hydra.overrides.task", default=None)
    params = OmegaConf.select(multirun_cfg, "hydra.sweeper.params", default=None)
    texts = [f"{k}={v}" for k, v in (OmegaConf.to_container(params) if params else {}).items()]
    texts += [str(o) for o in (OmegaConf.to_container(task) if task is not None else [])]
    try:  # as the basic sweeper reads them: its params, then the command line's
        overrides = OverridesParser.create().parse_overrides(texts)
    except Exception:  # an override the basic sweeper would not take: no plan to compare
        return None
    return _combinations(overrides)


def _combinations(overrides) -> list[dict[str, str]] | None:
    """Every combination of the overrides' values, in the order Hydra's basic sweeper runs them
    (the last override of a key wins, in the place of its first); None when a sweep is not a
    list of values (the basic sweeper refuses it)."""
    values: dict[str, list[str]] = {}
    for override in overrides:
        key = override.get_key_element()
        if not override.is_sweep_override():
            values[key] = [override.get_value_element_as_str()]
        elif override.is_discrete_sweep():
            values[key] = list(override.sweep_string_iterator())
        else:
            return None
    return [{_key_value(f"{key}={value}")[0]: value for key, value in zip(values, job)}
            for job in itertools.product(*values.values())]


def not_started(jobs: list[Job], plan, sweep_dir) -> list[Job]:
    """The jobs of ``plan`` (:func:`planned_jobs`) that have no folder among ``jobs``."""
    seen = {j.num for j in jobs}
    return [Job(num=i, path=Path(sweep_dir) / str(i), overrides=overrides, status="not started",
                error="the sweep ended before this job started")
            for i, overrides in enumerate(plan or ()) if i not in seen]


def _sweep_overrides(multirun_cfg) -> list[str]:
    """The task overrides of a multirun config and its sweeper's ``params``, as ``key=value``."""
    from omegaconf import OmegaConf

    if multirun_cfg is None:
        return []
    task = OmegaConf.select(multirun_cfg, "hydra.overrides.task", default=None)
    params = OmegaConf.select(multirun_cfg, "hydra.sweeper.params", default=None)
    out = [str(o) for o in (OmegaConf.to_container(task) if task is not None else [])]
    if params is not None:
        out += [f"{k}={v}" for k, v in OmegaConf.to_container(params).items()]
    return out


def swept_keys(multirun_cfg=None, jobs=()) -> list[str]:
    """The keys a sweep varies: the sweep overrides of ``multirun_cfg`` (``a=1,2``,
    ``range(...)``, ``choice(...)``, sweeper ``params``) plus every key whose value differs
    between ``jobs``; ordered as in the first job's overrides."""
    from hydra.core.override_parser.overrides_parser import OverridesParser

    keys: list[str] = []
    parser = OverridesParser.create()
    for text in _sweep_overrides(multirun_cfg):
        try:
            (override,) = parser.parse_overrides([text])
        except Exception:  # a sweeper-specific syntax: the job values below still find it
            continue
        if override.is_sweep_override() and override.key_or_group not in keys:
            keys.append(override.key_or_group)
    for job in jobs:
        for key, value in job.overrides.items():
            if key not in keys and any(j.overrides.get(key) != value for j in jobs):
                keys.append(key)
    order = list(jobs[0].overrides) if jobs else []
    return sorted(keys, key=lambda k: (order.index(k) if k in order else len(order), keys.index(k)))
