"""A search's Optuna study kept beside its sweep, so that a later search can go on with it.

``hydra/sweeper=optuna`` (as topomap sets it, :mod:`topomap.app.compose.optuna`) keeps its
study in :class:`SweepStudy`: Optuna's in-memory storage that writes every finished trial to
``<sweep dir>/study.json`` as the search goes, and starts from the trials of an earlier search's
file when told (``hydra.sweeper.storage.resume_from=<its sweep folder>``), so that its sampler
goes on from what they found and its best trial is the best of them all: the one Hydra prints
(``Best value``, ``optimization_results.yaml``), the one ``study.json`` holds and the one the
sweep report names (:func:`~topomap.app.report.summary.print_report`).  It also watches the
trials: when every one of a search's ``n_trials`` has failed, it ends the search with one line
saying why the first failed, and the ``topomap`` command writes the sweep's report
(:func:`~topomap.app.report.callback.report_early_end`).  (Optuna's SQLite storage is not
used: the Optuna that the Hydra sweeper plugin requires, 2.x, cannot create its tables under
SQLAlchemy 2.)

``study.json`` holds the objective the trials' values are of, and each trial's sweep folder and
job number there (:func:`~topomap.app.report.jobs.read_study`).
"""

from __future__ import annotations

import json
import os
import warnings
from pathlib import Path

import optuna
from optuna.distributions import distribution_to_json, json_to_distribution
from optuna.storages import InMemoryStorage
from optuna.trial import TrialState

from ..report.jobs import read_jobs, read_study
from ..results import STUDY_FILE

__all__ = ["SweepStudy", "STUDY_FILE", "check_resume"]


def check_resume(resume_from, objective: str | None) -> list[dict]:
    """The trials of the earlier search in ``resume_from`` that a search of ``objective`` goes
    on with; a ValueError naming ``hydra.sweeper.storage.resume_from`` when there is no study
    there, or its trials' values are of another objective."""
    key = f"hydra.sweeper.storage.resume_from={resume_from}"
    try:
        study = read_study(resume_from)
    except ValueError as exc:
        raise ValueError(f"{key}: {exc}; give the sweep folder of an earlier search") from None
    if objective is not None and study["objective"] not in (None, objective):
        raise ValueError(f"{key}: that search's trials are values of objective="
                         f"{study['objective']}, this search's of objective={objective}; give "
                         f"objective={study['objective']} to go on with it")
    return study["trials"]


class SweepStudy(InMemoryStorage):
    """Optuna's in-memory storage, every finished trial also written to ``folder/study.json``.

    Parameters
    ----------
    folder : str
        The sweep folder (``${hydra.sweep.dir}``).
    resume_from : str, optional
        The sweep folder of an earlier search of the same parameters and objective: its trials
        are the study's first (its ``study.json`` must exist, :func:`check_resume`).
    n_trials : int, optional
        The trials of this search (``${hydra.sweeper.n_trials}``): when every one of them has
        failed, the search ends once the last is written, with one line saying why the first
        failed (rather than Optuna's error of a study without a completed trial).
    objective : str, optional
        What the trials' values are (``${objective}``), written into ``study.json``.
    """

    def __init__(self, folder: str, resume_from: str | None = None, n_trials: int | None = None,
                 objective: str | None = None):
        super().__init__()
        self.n_trials = n_trials
        self.objective = None if objective is None else str(getattr(objective, "value",
                                                                     objective))
        optuna.logging.set_verbosity(optuna.logging.WARNING)  # the sweep logs the study itself
        self.path = Path(folder) / STUDY_FILE
        self.path.parent.mkdir(parents=True, exist_ok=True)  # the study is kept in the sweep's
        self.earlier: list[dict] = []
        if resume_from not in (None, ""):
            self.earlier = check_resume(resume_from, self.objective)
        self._waiting: set[int] = set()  # studies whose earlier trials wait for their direction

    def create_new_study(self, study_name: str | None = None) -> int:
        study_id = super().create_new_study(study_name)
        self._waiting.add(study_id)
        return study_id

    def set_study_directions(self, study_id: int, directions) -> None:
        """Set the study's direction, then add the earlier search's trials: Optuna's in-memory
        storage finds the best trial as each is added, by the direction set then (a study
        without one takes the least value as the best)."""
        super().set_study_directions(study_id, directions)
        if study_id not in self._waiting:
            return
        self._waiting.discard(study_id)
        for t in self.earlier:
            with warnings.catch_warnings():  # create_trial is Optuna 2's documented way to add
                warnings.simplefilter("ignore", optuna.exceptions.ExperimentalWarning)
                trial = optuna.trial.create_trial(
                    state=TrialState[t["state"]], values=t["values"], params=t["params"],
                    distributions={k: json_to_distribution(d)
                                   for k, d in t["distributions"].items()})
            self.create_new_trial(study_id, template_trial=trial)

    def set_trial_state(self, trial_id: int, state: TrialState) -> bool:
        changed = super().set_trial_state(trial_id, state)
        if state.is_finished():
            study_id = self.get_study_id_from_trial_id(trial_id)
            self._write(study_id)
            self._stop_if_all_failed(study_id)
        return changed

    def _stop_if_all_failed(self, study_id: int) -> None:
        """End the search with one line when all its ``n_trials`` trials failed."""
        mine = self.get_all_trials(study_id, deepcopy=False)[len(self.earlier):]
        if self.n_trials is None or len(mine) < self.n_trials or any(
                t.state != TrialState.FAIL for t in mine):
            return
        why = next((j.error for j in read_jobs(self.path.parent) if j.error),
                   "no trial returned its objective")
        raise SystemExit(f"topomap: error: all {len(mine)} trials of the search failed, the "
                         f"first with: {why}")

    def _where(self, number: int) -> dict:
        """Where the study's trial ``number`` ran: the earlier search's folder and job, or this
        search's (its trials are its jobs, in order)."""
        if number < len(self.earlier):
            return {k: self.earlier[number][k] for k in ("sweep_dir", "job")}
        return {"sweep_dir": str(self.path.parent), "job": number - len(self.earlier)}

    def _write(self, study_id: int) -> None:
        trials = [{"number": t.number, "state": t.state.name, "values": t.values,
                   "params": t.params,
                   "distributions": {k: distribution_to_json(d)
                                     for k, d in t.distributions.items()},
                   **self._where(t.number)}
                  for t in self.get_all_trials(study_id) if t.state.is_finished()]
        self.path.parent.mkdir(parents=True, exist_ok=True)
        tmp = self.path.with_name(f".{self.path.name}.{os.getpid()}")
        study = {"objective": self.objective, "sweep_dir": str(self.path.parent), "trials": trials}
        tmp.write_text(json.dumps(study, indent=1) + "\n")
        os.replace(tmp, self.path)
