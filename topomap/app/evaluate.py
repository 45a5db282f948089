"""How good a learned map is: against ground truth, and on held-out data."""

from __future__ import annotations

from ..core import metrics as M
from ..core.learner import MapLearner
from ..core.trajectory import Trajectory

__all__ = ["evaluate"]


def evaluate(learner: MapLearner, traj: Trajectory, heldout: Trajectory | None) -> dict:
    """State counts and entropies after phase 1 and at the end; ARI, NMI, purity and compound
    states against ``traj.places`` when the trajectory has ground truth; the mean log-likelihood
    per step of ``heldout`` under the learned map (None without held-out data)."""
    out = {
        "n_states": {"phase1": learner.map_phase1_.n_states, "final": learner.map_.n_states},
        "entropies": {"phase1": learner.entropies_[0], "final": learner.entropies_[-1]},
    }
    if traj.places is not None:
        out["ground_truth"] = {
            "phase1": M.evaluate(learner.labels_phase1_, traj.places),
            "final": M.evaluate(learner.labels_, traj.places),
        }
    if heldout is None:
        out.update(heldout_loglik=None, heldout_steps=0)
    else:
        out.update(heldout_loglik=learner.map_.score(heldout.observations, heldout.actions,
                                                     gds=heldout.gds, lengths=heldout.lengths),
                   heldout_steps=len(heldout))
    return out
