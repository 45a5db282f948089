"""Choosing the number of states automatically (the paper's future work).

``stop=auto`` (:class:`AutoStates`, or ``MapLearner(n_states="auto")``) splits up to
``max_factor`` (10) times the states phase 1 creates (or until no split gains anything, or until
``patience`` splits in a row -- by default as many as phase 1 has states, at least 10 -- have not
improved the best score), scores the map after every split, and keeps the best size; the learner
then splits to that size.  Two criteria:

``"heldout"`` (the default)
    the log-likelihood per step of a held-out final block of the data (``holdout``, 20 % of the
    steps, the last ones) under the map split on the rest (forward algorithm, the Gaussian
    emissions of the phase-1 symbols; the symbols themselves come from all steps).
``"bic"``
    the Bayesian information criterion of the discrete model on all the data:
    ``-2 log L + k log T``, with ``log L = sum_x,u n log P(u|x) + sum_x,u,x' n log P(x'|x,u)``
    (the hard-assignment likelihood of the actions and transitions; ``H(o|x)`` is the same at
    every size, as split states share their symbol's Gaussian) and ``k`` the free parameters,
    one less than the distinct outcomes of every row of ``P(u|x)`` and ``P(x'|x,u)``.

The held-out score is the default because BIC misjudges short runs: a split that makes a
state's transitions deterministic lowers the hard-assignment likelihood's entropy without adding
a counted parameter, so on the paper's 2,000 steps BIC chooses 82, 33 and 165 states (seeds 0-2)
for 29 places, where the held-out score chooses 35, 30 and 24 (``docs/choosing-size.md``).  With
``refine="em"`` the refinement decides the final number of states itself (it merges duplicates of
a place and splits compound states), so the split size matters little there.
"""

from __future__ import annotations

import numpy as np

from .checks import ParameterError, check_count
from .map.model import TopologicalMap
from .split.engine import Splitter
from .stats import episode_masks
from .progress import report

__all__ = ["AutoStates", "UpTo", "bic", "parameter_count", "split_holdout", "SizeScores",
           "probe_sizes", "refined_sizes", "REFINED_LADDER"]

CRITERIA = ("bic", "heldout")


class UpTo:
    """A stopping rule: split while a split gains anything, up to ``factor`` x the states phase 1
    creates (the probe fit of :class:`AutoStates`)."""

    def __init__(self, factor: float):
        self.factor = float(factor)
        self._limit = None

    def check(self, n_initial: int) -> None:
        self._limit = max(int(self.factor * n_initial), n_initial)

    def should_stop(self, n_states: int, best_score: float) -> bool:
        return (self._limit is not None and n_states >= self._limit) or best_score <= 0

    def __repr__(self) -> str:
        return f"UpTo(factor={self.factor})"


class AutoStates:
    """``stop=auto``: choose the number of states (see the module docstring).

    :class:`topomap.MapLearner` recognises it: after phase 1, a probe splits with
    :meth:`probe_rule` and scores every size (:class:`SizeScores`), then the learner splits to
    the best one.  Its stopping-rule methods make
    it usable anywhere a stopping rule is (they stop like the probe).
    """

    name = "auto"

    def __init__(self, criterion: str = "heldout", max_factor: float = 10.0, holdout: float = 0.2,
                 patience: int | None = None):
        if criterion not in CRITERIA:
            raise ParameterError("criterion", f"must be one of {', '.join(CRITERIA)}, got {criterion!r}")
        if not max_factor >= 1:
            raise ParameterError("max_factor", f"must be >= 1, got {max_factor!r}")
        if not 0 < holdout < 1:
            raise ParameterError("holdout", f"must lie in (0, 1), got {holdout!r}")
        self.patience = check_count(patience, "patience", allow_none=True)
        self.criterion, self.max_factor, self.holdout = criterion, float(max_factor), float(holdout)
        self._probe = UpTo(self.max_factor)

    def probe_rule(self) -> UpTo:
        """The stopping rule of the probe fit that scores every size."""
        return UpTo(self.max_factor)

    def patience_for(self, n_initial: int) -> int:
        """Splits without a better score after which the probe stops."""
        return self.patience if self.patience is not None else max(10, int(n_initial))

    def check(self, n_initial: int) -> None:
        self._probe.check(n_initial)

    def should_stop(self, n_states: int, best_score: float) -> bool:
        return self._probe.should_stop(n_states, best_score)

    def __repr__(self) -> str:
        return (f"AutoStates(criterion={self.criterion!r}, max_factor={self.max_factor}, "
                f"holdout={self.holdout}, patience={self.patience})")


def parameter_count(labels, actions, n_actions: int, has_next) -> int:
    """Free parameters of ``P(u|x)`` and ``P(x'|x,u)`` estimated from a labelling: for every
    row, one less than its distinct outcomes."""
    x, u = np.asarray(labels, dtype=np.int64), np.asarray(actions, dtype=np.int64)
    rows = x * n_actions + u
    k_act = np.unique(rows).size - np.unique(x).size
    t = np.flatnonzero(has_next)
    pairs = np.unique(rows[t] * (int(x.max()) + 1) + x[t + 1])
    k_trans = pairs.size - np.unique(pairs // (int(x.max()) + 1)).size
    return int(k_act + k_trans)


def bic(entropies: dict, n_params: int, n_steps: int, n_transitions: int) -> float:
    """``-2 log L + k log T`` from the learner's entropies (bits) of a labelling."""
    loglik = -np.log(2) * (n_steps * entropies["H_u"] + n_transitions * entropies["H_x"])
    return float(-2.0 * loglik + n_params * np.log(n_steps))


def split_holdout(n_steps: int, lengths, holdout: float):
    """``(train_lengths, heldout_lengths, cut)``: the last ``holdout`` share of the steps (at
    least 3) is held out, cutting the episode it falls in in two."""
    cut = min(max(int(round(n_steps * (1 - holdout))), 3), n_steps - 3)
    ends = np.cumsum(lengths)
    starts = ends - np.asarray(lengths)
    train = [min(e, cut) - s for s, e in zip(starts, ends) if s < cut]
    held = [e - max(s, cut) for s, e in zip(starts, ends) if e > cut]
    return np.array(train, dtype=np.int64), np.array(held, dtype=np.int64), cut


class SizeScores:
    """The score of the map after phase 1 and after every split of a probe (a
    :class:`topomap.core.split.engine.Splitter`): ``scores`` maps a state count to its score
    (higher is better: BIC enters negated).

    ``criterion="bic"`` scores the labelling of the data being split, ``data = (X, u, lengths,
    n_actions)``; ``"heldout"`` builds each map from that data and scores ``heldout = (X, u,
    gds, lengths)`` with it.
    """

    def __init__(self, criterion: str, data, heldout=None):
        self.criterion, self.data, self.heldout = criterion, data, heldout
        self.scores: dict[int, float] = {}
        _, self._has_next = episode_masks(data[1].size, data[2])

    def add(self, splitter) -> None:
        """Score the splitter's current labelling."""
        X, u, lengths, n_actions = self.data
        if self.criterion == "bic":
            k = parameter_count(splitter.labels, u, n_actions, self._has_next)
            score = -bic(splitter.entropies(), k, u.size, int(self._has_next.sum()))
        else:
            m = TopologicalMap.from_labels(X, u, splitter.labels, lengths=lengths,
                                           state_symbol=splitter.symbol, state_gds=splitter.gds,
                                           state_parent=splitter.parent, n_actions=n_actions)
            Xh, uh, gh, Lh = self.heldout
            score = m.score(Xh, uh, gds=gh, lengths=Lh)
        self.scores[splitter.n_states] = float(score)

    def best(self) -> int:
        """The state count of the best score (the smallest on ties)."""
        return max(sorted(self.scores), key=lambda n: self.scores[n])

    def stale(self, patience: int) -> bool:
        """Whether the last ``patience`` sizes scored have not improved on the best."""
        return max(self.scores) - self.best() >= patience


#: the sizes, as multiples of the refinement's own, that ``stop=auto`` scores for a refined map
REFINED_LADDER = (0.5, 0.67, 0.8, 0.9, 1.0, 1.1, 1.25, 1.5, 2.0)


def refined_sizes(n_own: int, n_min: int) -> list[int]:
    """The state counts ``stop=auto`` scores for a refined map whose refinement chose ``n_own``
    states: :data:`REFINED_LADDER` x ``n_own``, none below ``n_min`` (the states phase 1 makes)."""
    return sorted({max(int(round(f * n_own)), n_min) for f in REFINED_LADDER})


def probe_sizes(labels_phase1, data, splitter, rule: AutoStates) -> dict:
    """``stop=auto``'s choice: from the phase-1 labels, a probe splits up to the rule's limit or
    patience -- on all steps for BIC, on all but the held-out final block for ``"heldout"`` --
    and every size is scored.  ``data`` has the learner's ``X, u, gds, lengths, n_actions``.
    Returns ``{"criterion", "chosen", "scores"}``."""
    X, u, g, L, A = data.X, data.u, data.gds, data.lengths, data.n_actions
    cut = u.size
    if rule.criterion == "heldout":
        L, held, cut = split_holdout(u.size, L, rule.holdout)
        scores = SizeScores("heldout", (X[:cut], u[:cut], L, A),
                            heldout=(X[cut:], u[cut:], g[cut:], held))
    else:
        scores = SizeScores("bic", (X, u, L, A))
    probe = Splitter(labels_phase1[:cut], u[:cut], A, *episode_masks(cut, L),
                     symbol=splitter.symbol, gds=splitter.gds,
                     obs_entropy=splitter.obs_entropy, criterion=splitter.criterion)
    stop, patience = rule.probe_rule(), rule.patience_for(probe.n_states)
    stop.check(probe.n_states)
    stage = "held-out scoring" if rule.criterion == "heldout" else "BIC scoring"
    scores.add(probe)
    report(stage, 1)
    while (best := probe.best()) is not None and not stop.should_stop(
            probe.n_states, best.score) and not scores.stale(patience):
        probe.apply(best)
        scores.add(probe)
        report(stage, len(scores.scores))
    report(stage, len(scores.scores), len(scores.scores))
    return {"criterion": rule.criterion, "chosen": scores.best(),
            "scores": {int(n): v for n, v in scores.scores.items()}}
