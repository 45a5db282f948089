"""A search's Optuna study kept beside its sweep, so that a later search can go on with it.

``hydra/sweeper=optuna`` (as topomap sets it, :mod:`topomap.app.compose.optuna`) keeps its
study in :class:`SweepStudy`: Optuna's in-memory storage that writes every finished trial to
``<sweep dir>/study.json`` as the search goes, and starts from the trials of an earlier search's
file when told (``hydra.sweeper.storage.resume_from=<its sweep folder>``), so that its sampler
goes on from what they found.  It also watches the trials: when every one of a search's
``n_trials`` has failed, it ends the search with one line saying why the first failed, and the
``topomap`` command writes the sweep's report
(:func:`~topomap.app.report.callback.report_early_end`).  (Optuna's SQLite storage is not
used: the Optuna that the Hydra sweeper plugin requires, 2.x, cannot create its tables under
SQLAlchemy 2.)
"""

from __future__ import annotations

import json
import logging
import os
from pathlib import Path

import optuna
from optuna.distributions import distribution_to_json, json_to_distribution
from optuna.storages import InMemoryStorage
from optuna.trial import TrialState

__all__ = ["SweepStudy", "STUDY_FILE"]

#: the file of a search's trials, in its sweep folder
STUDY_FILE = "study.json"


class SweepStudy(InMemoryStorage):
    """Optuna's in-memory storage, every finished trial also written to ``folder/study.json``.

    Parameters
    ----------
    folder : str
        The sweep folder (``${hydra.sweep.dir}``).
    resume_from : str, optional
        The sweep folder of an earlier search of the same parameters: its trials are the
        study's first (its ``study.json`` must exist).
    n_trials : int, optional
        The trials of this search (``${hydra.sweeper.n_trials}``): when every one of them has
        failed, the search ends once the last is written, with one line saying why the first
        failed (rather than Optuna's error of a study without a completed trial).
    """

    def __init__(self, folder: str, resume_from: str | None = None, n_trials: int | None = None):
        super().__init__()
        self.n_trials = n_trials
        optuna.logging.set_verbosity(optuna.logging.WARNING)  # the sweep logs the study itself
        logging.getLogger("alembic").setLevel(logging.WARNING)  # Optuna's database migrations
        self.path = Path(folder) / STUDY_FILE
        self.path.parent.mkdir(parents=True, exist_ok=True)  # the study is kept in the sweep's
        self.earlier: list[dict] = []
        if resume_from not in (None, ""):
            source = Path(resume_from) / STUDY_FILE
            try:
                self.earlier = json.loads(source.read_text())["trials"]
            except (OSError, ValueError, KeyError, TypeError) as exc:
                raise ValueError(f"hydra.sweeper.storage.resume_from={resume_from}: no study to "
                                 f"go on with ({source}: {exc})") from None

    def create_new_study(self, study_name: str | None = None) -> int:
        study_id = super().create_new_study(study_name)
        for t in self.earlier:
            self.create_new_trial(study_id, template_trial=optuna.trial.create_trial(
                state=TrialState[t["state"]], values=t["values"], params=t["params"],
                distributions={k: json_to_distribution(d)
                               for k, d in t["distributions"].items()}))
        return study_id

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
        from ..report.jobs import read_jobs

        why = next((j.error for j in read_jobs(self.path.parent) if j.error),
                   "no trial returned its objective")
        raise SystemExit(f"topomap: error: all {len(mine)} trials of the search failed, the "
                         f"first with: {why}")

    def _write(self, study_id: int) -> None:
        trials = [{"number": t.number, "state": t.state.name, "values": t.values,
                   "params": t.params,
                   "distributions": {k: distribution_to_json(d)
                                     for k, d in t.distributions.items()}}
                  for t in self.get_all_trials(study_id) if t.state.is_finished()]
        self.path.parent.mkdir(parents=True, exist_ok=True)
        tmp = self.path.with_name(f".{self.path.name}.{os.getpid()}")
        tmp.write_text(json.dumps({"trials": trials}, indent=1) + "\n")
        os.replace(tmp, self.path)
