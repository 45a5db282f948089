"""How good a learned map is: against ground truth, and on held-out data."""

from __future__ import annotations

import logging

import numpy as np

from ...core.data.trajectory import Trajectory
from ...core.learner import MapLearner
from ...core.progress import report
from ...evaluation import metres as positions
from ...evaluation import partitions as M

from ..results import METRICS, OBJECTIVES

log = logging.getLogger("topomap")

__all__ = ["evaluate", "localization_scores", "objective_value", "check_objective",
           "position_entry"]


def _objective(name) -> str:
    """The name of the objective ``name`` (its name, or a member of
    :class:`~topomap.app.compose.schemas.Objective`) of
    :data:`~topomap.app.results.OBJECTIVES`."""
    name = getattr(name, "value", name)
    if name not in OBJECTIVES:
        raise ValueError(f"objective={name!r} is not one of {', '.join(OBJECTIVES)}")
    return name


def check_objective(name, traj: Trajectory, heldout: Trajectory | None) -> None:
    """Refuse, before learning, data that cannot give the objective ``name`` (a ValueError
    naming the config keys to set)."""
    name = _objective(name)
    missing = heldout is None if name == "heldout_loglik" else traj.places is None
    if missing:
        other = next(n for n in OBJECTIVES if n != name)
        raise ValueError(f"objective={name} needs {OBJECTIVES[name]}; or choose "
                         f"objective={other}")


def objective_value(results: dict, name) -> float | None:
    """The objective ``name`` of a run's ``results`` (None where the run has no value for it)."""
    value = METRICS[_objective(name)].read(results)
    return None if value is None else float(value)


def evaluate(learner: MapLearner, traj: Trajectory, heldout: Trajectory | None,
             parts=None) -> dict:
    """State counts and entropies after phase 1 and at the end; ARI, NMI, purity and compound
    states against ``traj.places`` when the trajectory has ground truth; the mean log-likelihood
    per step of ``heldout`` under the learned map (None without held-out data); scores in metres
    where the steps have positions but no places (:func:`position_entry`); and what the run's
    ``evaluate`` component measures (``navigation``)."""
    refined = learner.map_ is not learner.map_split_
    out = {
        "n_states": {"phase1": learner.map_phase1_.n_states, "final": learner.map_.n_states},
        "entropies": {"phase1": learner.entropies_[0], "final": learner.entropies_[-1]},
    }
    if refined:
        out["n_states"]["split"] = learner.map_split_.n_states
    if traj.places is not None:
        out["ground_truth"] = {
            "phase1": M.evaluate(traj.places, learner.labels_phase1_),
            "final": M.evaluate(traj.places, learner.labels_),
        }
        if refined:
            out["ground_truth"]["split"] = M.evaluate(traj.places, learner.labels_split_)
    if heldout is None:
        out.update(heldout_loglik=None, heldout_steps=0)
    else:
        report("held-out scoring", 0, 1)
        out.update(heldout_loglik=learner.map_.score(heldout.observations, heldout.actions,
                                                     gds=heldout.gds, lengths=heldout.lengths),
                   heldout_steps=len(heldout))
        report("held-out scoring", 1, 1)
    simulated = parts is not None and getattr(parts.data, "simulates", False)
    located = position_entry(learner, traj, heldout, None if parts is None else parts.env,
                             "the held-out walk" if simulated else "the held-out recording")
    if located is not None:
        out["position"] = located
    if parts is not None and parts.evaluate is not None:
        if parts.env is None or traj.places is None:
            raise ValueError("evaluate=navigation needs a simulated world with ground truth "
                             "(data=simulate)")
        out["navigation"] = parts.evaluate.evaluate(learner.map_, learner.labels_, traj.places,
                                                    parts.env, parts.noise)
    return out


def localization_scores(m, traj: Trajectory, beliefs, viterbi) -> dict:
    """How a saved map localises on a recording: its log-likelihood per step, and with ground
    truth the ARI / NMI / purity of the filtered (past only) and Viterbi (whole sequence)
    states against the places."""
    out = {"n_steps": len(traj), "n_states": m.n_states,
           "loglik": m.score(traj.observations, traj.actions, gds=traj.gds, lengths=traj.lengths),
           "mean_max_belief": float(beliefs.max(axis=1).mean())}
    if traj.places is not None:
        out["ground_truth"] = {"filter": M.evaluate(traj.places, beliefs.argmax(axis=1)),
                               "viterbi": M.evaluate(traj.places, viterbi)}
    return out


def _regions(env):
    """The world's regions: ``(names, region_of)``, or ``(None, None)`` for a world without
    them (or no world: a recording)."""
    names = list(getattr(env, "region_names", None) or [])
    return (names, env.region_of) if names else (None, None)


def _shares(coverage: dict, walk: str) -> str:
    return ", ".join(f"{name} {c[walk]:.0%}" for name, c in coverage["regions"].items())


def coverage_entry(names, region_of, traj: Trajectory, heldout: Trajectory) -> dict | None:
    """:func:`~topomap.evaluation.metres.region_coverage` of the two walks (None without
    regions), said on the console: each walk's share of steps in every region, and a warning
    when the held-out walk spends steps in regions the training walk never entered."""
    if region_of is None:
        return None
    cover = positions.region_coverage(names, region_of(traj.positions),
                                      region_of(heldout.positions))
    log.info("regions covered: training %s; held-out %s", _shares(cover, "training"),
             _shares(cover, "heldout"))
    if cover["unvisited"]:
        log.warning("%.0f%% of the held-out steps lie in regions the training walk never "
                    "entered (%s): no map learned from it can place them there; walk longer "
                    "(data.n_steps) or through them",
                    100 * cover["heldout_unvisited"], ", ".join(cover["unvisited"]))
    return cover


def position_entry(learner: MapLearner, traj: Trajectory, heldout: Trajectory | None,
                   env=None, held: str = "the held-out recording") -> dict | None:
    """Scores in metres of the held-out walk (:mod:`topomap.evaluation.metres`: the map's,
    the ceiling's and K-means on the views', each with the median and 90th-percentile error and,
    where the world has regions, the wrong-region share), with which walk was held out (as the
    world says in ``heldout.meta``, else ``held``) and the regions; None unless both walks have
    positions and the steps have no discrete places (whose scores are ARI and purity).  The
    ceiling is None (with ``ceiling_note``) when the map has fewer states than the walk has
    regions."""
    if (heldout is None or traj.positions is None or heldout.positions is None
            or traj.places is not None):
        return None
    dims = (traj.positions.shape[1], heldout.positions.shape[1])
    if dims[0] != dims[1]:
        raise ValueError(f"positions: the held-out walk's have {dims[1]} coordinates, the walk "
                         f"learned from {dims[0]}; scores in metres need the same")
    names, region_of = _regions(env)
    m, labels, seed = learner.map_, learner.labels_, learner.random_state
    report("scores in metres", 0, 4)
    out = {"heldout": (heldout.meta or {}).get("heldout", held),
           "heldout_steps": len(heldout), "regions": names, "ceiling_note": None,
           "coverage": coverage_entry(names, region_of, traj, heldout),
           "map": positions.learner_map_scores(learner, traj, heldout, region_of)}
    report("scores in metres", 1, 4)
    out["kmeans_views"] = positions.kmeans_view_scores(m.n_states, traj, heldout, region_of, seed)
    report("scores in metres", 2, 4)
    out["kmeans_positions"] = positions.kmeans_position_scores(m.n_states, traj, heldout,
                                                               region_of, seed)
    report("scores in metres", 3, 4)
    held_regions = 1 if region_of is None else np.unique(region_of(traj.positions)).size
    if m.n_states >= held_regions:
        out["ceiling"] = positions.ceiling_scores(m, labels, traj, heldout, region_of, seed)
    else:
        out["ceiling"] = None
        out["ceiling_note"] = (f"the map's {m.n_states} states are fewer than the "
                               f"{held_regions} regions the walk entered")
    report("scores in metres", 4, 4)
    return out
