"""Soft symbol evidence: the refinement when sensors misread some views.

The hard refinement (:class:`topomap.core.refine.methods.EMRefinement`) takes every step's K-means
symbol as exact: each clone emits one symbol, so a misread view must be explained by a clone of
the symbol it was read as, and every misread starts a new clone chain (gridroom 8x6 with 18 %
misreads: 227 states for 48 places).  Here the symbol read is evidence: a clone of symbol ``k``
reads ``r`` with probability ``C[k, r]`` (the confusion matrix, learned by EM with a prior that
favours the diagonal; GDS ids are never confused), so a step may be explained by a clone of
another symbol, which corrects the reading.

This module holds the soft round (:func:`soft_round`: Baum-Welch with soft evidence, then
Viterbi) and its settings (:class:`SoftSettings`); the confusion matrix and the misread share are
:mod:`topomap.core.refine.confusion`, evidence from each step's own observation in place of it
:mod:`topomap.core.refine.observed`; merging twin states (:func:`merge_twins`) and choosing the
states a round keeps (:func:`keep_states`) are :mod:`topomap.core.refine.soft_states`.  Soft EM
cannot create structure and a hard refinement on misread symbols creates too much, so the two
alternate; :mod:`topomap.core.refine.rounds` sequences the hard and soft rounds.  Kernels:
:mod:`topomap.core.refine.soft_kernels`.
"""

from __future__ import annotations

import numbers
from collections.abc import Mapping
from dataclasses import dataclass, fields, replace

import numpy as np

from ..checks import ParameterError, check_count
from ..progress import report
from .clones import compact_labels
from .accelerate import ACCELERATIONS, squarem
from .convergence import ConvergenceMonitor
from .soft_kernels import (SoftData, SoftModel, SoftStats, soft_backward, soft_candidates,
                           soft_forward, soft_forward_read, soft_offsets, soft_viterbi,
                           read_tables)
from .soft_states import (keep_states, merge_twins, min_steps_of, successor_surprise,
                          twin_overlap)
from .confusion import (co_successors, confusion_mstep, initial_confusion, misread_rate,
                        misread_share)

__all__ = ["SoftSettings", "soft_settings", "SoftFit", "EVIDENCE", "check_evidence", "soft_round",
           "misread_rate", "misread_share", "successor_surprise", "merge_twins", "keep_states",
           "min_steps_of"]


@dataclass(frozen=True)
class SoftSettings:
    """Knobs of the soft-evidence refinement (the ``soft`` parameter of
    :class:`~topomap.core.refine.methods.EMRefinement` and
    :class:`~topomap.core.refine.methods.CSCGRefinement`; ``refine.soft.<key>`` in the config).

    ``rounds`` soft round + hard refinement cycles; ``min_steps`` states with fewer steps are
    dropped before every soft round (0: keep all; a float below 1 is a fraction of the mean
    steps per state of the reference count, the split's states; ``prune_every=False``: only
    before the last round); ``spare`` extra clones per K-means symbol in the intermediate soft rounds;
    ``max_iter`` / ``tol`` Baum-Welch's stop (nats per step; ``rtol`` > 0: instead once an
    iteration gains at most that share of the log-likelihood, in the refinements only after a
    hard round whose labelling shows many misreads,
    :data:`~topomap.core.refine.rounds.CAP_SURPRISE`); ``row_prior`` the pseudocount mass of
    a transition row; ``conf_diag`` / ``conf_off`` the Dirichlet pseudocounts of the confusion
    matrix's diagonal / off-diagonal entries (per row); ``init_error`` the misread rate the
    confusion matrix starts from; ``floor`` the smallest ``C[k, r]`` allowed as evidence (smaller
    entries are 0: the sparse kernel never tries clones of ``k`` at a step read as ``r``);
    ``prune`` the filtered probabilities dropped in the forward pass; ``detect``: with
    ``evidence="auto"`` the hard result is kept when all but that share of its transitions go
    to the symbol their (state, action) predicts (:func:`successor_surprise`: no soft round),
    or the first soft round explains fewer steps as misread (:func:`misread_share`, judged
    after ``detect_iter`` iterations) and corrects fewer.  ``clone_prior``:
    per-clone read distributions shrunk towards the confusion row with that many pseudo-steps
    (``inf``: the row itself); ``twin`` / ``twin_merge``: the predecessor overlap above which a
    small state is the residue of misreads / a state is merged into its twin of another symbol
    (:func:`merge_twins`); ``conf_warmup``: EM iterations with the confusion matrix held at its
    start before it is learned (0: from the first; docs/refinement.md has its effect on
    gridroom at 23 % misreads).  ``stage_cap`` / ``stage_rtol``: where the first stage's
    labelling of a hard round's prefix already shows many misreads (``CAP_SURPRISE``), the
    growth stages' Baum-Welch stops after ``stage_cap`` iterations unless its last iteration
    still gained more than ``stage_rtol`` x |log-likelihood|, and then once an iteration gains
    less (``stage_cap`` 0: off; ``stage_rtol`` inf: never goes on;
    :meth:`~topomap.core.refine.methods.EMRefinement._stage_cap`).  ``accelerate``
    (:data:`~topomap.core.refine.accelerate.ACCELERATIONS`): ``"squarem"`` runs the soft rounds'
    Baum-Welch, after its first iteration, as SQUAREM's cycles on the expected counts
    (``max_iter`` counts E-steps; default ``"none"``: plain EM).  ``prune_loose`` (0: off)
    replaces ``prune`` in the soft rounds after a first hard round whose labelling shows a
    successor surprise below ``loose_below`` (few misreads;
    :func:`~topomap.core.refine.rounds._round_settings`).  ``label_every`` (0: off): a soft round
    decodes its model that often and stops once under ``label_tol`` of the steps moved.
    ``read_share`` (3e-4; 0: off): where candidates are dense (:data:`READ_DENSE`), a step's
    candidates of a symbol whose share of its evidence, given the forward message, is below it
    stay 0 (:func:`~.soft_kernels.soft_forward_read`).  ``observed`` (6; 0: off): the soft rounds
    ``observed_in`` (``"auto"``: all but the first, or only the last, which gives the map, where
    the first finds a view phase 1 cut in two, :data:`~.rounds.PAIRED_READ`; ``"last"``;
    ``"all"``) take each step's evidence from its own observation instead of the confusion
    matrix -- the likelihood of every symbol under phase 1's Gaussians, tempered by ``observed``
    (:mod:`~topomap.core.refine.observed`; a fit not given the observations' log-densities uses
    the confusion matrix).
    """

    rounds: int = 3
    min_steps: float = 0.3
    spare: int = 1
    max_iter: int = 30
    tol: float = 1e-5
    row_prior: float = 0.5
    conf_diag: float = 20.0
    conf_off: float = 0.05
    init_error: float = 0.2
    floor: float = 1e-3
    prune: float = 1e-6
    detect: float = 0.002
    prune_every: bool = True
    clone_prior: float = float("inf")
    twin: float = 0.5
    twin_merge: float = 0.5
    conf_warmup: int = 0
    detect_iter: int = 3
    stage_cap: int = 0
    stage_rtol: float = float("inf")
    rtol: float = 0.0
    accelerate: str = "none"
    prune_loose: float = 0.0
    loose_below: float = 0.12
    label_every: int = 0
    label_tol: float = 1e-3
    read_share: float = 3e-4
    observed: float = 6.0
    observed_in: str = "auto"


#: the soft rounds that take each step's evidence from its observation (``soft.observed_in``)
OBSERVED_IN = ("last", "auto", "all")

#: the real-valued soft settings and what each must be
_RANGES = {
    "min_steps": (lambda v: v >= 0, ">= 0"), "tol": (lambda v: v >= 0, ">= 0"),
    "row_prior": (lambda v: v > 0, "> 0"), "conf_diag": (lambda v: v > 0, "> 0"),
    "conf_off": (lambda v: v > 0, "> 0"), "init_error": (lambda v: 0 <= v < 1, "in [0, 1)"),
    "floor": (lambda v: 0 < v < 1, "in (0, 1)"), "prune": (lambda v: 0 <= v < 1, "in [0, 1)"),
    "detect": (lambda v: v == v, "a number"), "clone_prior": (lambda v: v > 0, "> 0"),
    "twin": (lambda v: v >= 0, ">= 0"), "twin_merge": (lambda v: v >= 0, ">= 0"),
    "stage_rtol": (lambda v: v >= 0, ">= 0"), "rtol": (lambda v: v >= 0, ">= 0"),
    "prune_loose": (lambda v: 0 <= v < 1, "in [0, 1)"), "loose_below": (lambda v: v >= 0, ">= 0"),
    "label_tol": (lambda v: 0 <= v <= 1, "in [0, 1]"),
    "read_share": (lambda v: 0 <= v < 1, "in [0, 1)"),
    "observed": (lambda v: v >= 0 and v != float("inf"), ">= 0 and finite"),
}


def soft_settings(value) -> SoftSettings:
    """``value`` -- a :class:`SoftSettings` or a mapping of some of its fields (the config's
    ``refine.soft``) -- as checked settings; a :class:`ParameterError` names ``soft.<field>``."""
    names = [f.name for f in fields(SoftSettings)]
    if isinstance(value, Mapping):
        unknown = sorted(set(value) - set(names))
        if unknown:
            raise ParameterError(f"soft.{unknown[0]}", "is not a soft setting; the settings are "
                                                      + ", ".join(names))
        value = SoftSettings(**value)
    if not isinstance(value, SoftSettings):
        raise ParameterError("soft", f"must be SoftSettings or a mapping of its fields, "
                                     f"got {value!r}")
    for name in ("rounds", "spare", "conf_warmup", "detect_iter", "stage_cap", "label_every"):
        check_count(getattr(value, name), f"soft.{name}", minimum=0)
    check_count(value.max_iter, "soft.max_iter")
    for name, (ok, what) in _RANGES.items():
        v = getattr(value, name)
        if not (isinstance(v, numbers.Real) and not isinstance(v, bool) and ok(v)):
            raise ParameterError(f"soft.{name}", f"must be {what}, got {v!r}")
    if value.observed_in not in OBSERVED_IN:
        raise ParameterError("soft.observed_in", f"must be one of {', '.join(OBSERVED_IN)}, "
                                                 f"got {value.observed_in!r}")
    if value.accelerate not in ACCELERATIONS:
        raise ParameterError("soft.accelerate", f"must be one of {', '.join(ACCELERATIONS)}, "
                                                f"got {value.accelerate!r}")
    if not isinstance(value.prune_every, (bool, np.bool_)):
        raise ParameterError("soft.prune_every", f"must be true or false, got {value.prune_every!r}")
    return value


@dataclass
class SoftFit:
    """Result of a soft round: Viterbi ``labels`` (T,), ``state_symbol`` (n,), the confusion matrix
    ``conf`` (n_ids, n_ids), the corrected symbols ``sym`` (T,) and ``info``."""

    labels: np.ndarray
    state_symbol: np.ndarray
    conf: np.ndarray
    sym: np.ndarray
    info: dict


def _episode_data(seq) -> SoftData:
    has_next = np.ones(seq.T, dtype=bool)
    has_next[np.cumsum(seq.lengths) - 1] = False
    return SoftData(np.ascontiguousarray(seq.sym, dtype=np.int64),
                    np.ascontiguousarray(seq.u, dtype=np.int64), has_next)


def _clone_emission(conf, clone_symbol, counts, strength):
    """Per-clone read-symbol distributions: the clone's expected read counts ``counts`` (S, K)
    shrunk towards its symbol's row of ``conf`` with ``strength`` pseudo-steps (``inf`` or no
    counts: the row itself).  GDS clones keep their identity row."""
    prior = conf[clone_symbol]
    if counts is None or not np.isfinite(strength):
        return prior
    return (counts + strength * prior) / (counts.sum(axis=1, keepdims=True) + strength)


def _model(trans, emit, init, floor) -> SoftModel:
    emit = np.where(emit >= floor, emit, 0.0)
    empty = emit.sum(axis=0) == 0  # a read symbol no clone may explain: allow every clone
    emit[:, empty] = floor
    cptr, cidx = soft_candidates(emit)
    return SoftModel(trans, np.ascontiguousarray(emit), init, cptr, cidx)


def _log(model: SoftModel) -> SoftModel:
    with np.errstate(divide="ignore"):
        return SoftModel(np.log(model.trans), np.log(model.emit), np.log(model.init),
                         model.cptr, model.cidx)


def _normalise_trans(counts, pseudo):  # in place (no new (A, S, S) array): counts is not reused
    z = counts.sum(axis=2, keepdims=True) + pseudo * counts.shape[1]
    return np.divide(np.add(counts, pseudo, out=counts), z, out=counts)


def _warm_counts(data: SoftData, labels, state_symbol, keep, n_symbols: int, n_actions: int,
                 spare: int, rng):
    """Transition counts (A, S, S) of a warm start and the clones' symbols: every kept state a
    clone (renumbered) with the labelling's transitions between kept states, then ``spare`` clones
    of every K-means symbol with random rows."""
    labels, n_kept = np.asarray(labels, dtype=np.int64), int(keep.sum())
    rename = np.full(state_symbol.size, -1, dtype=np.int64)
    rename[keep] = np.arange(n_kept)
    clone_symbol = np.concatenate([state_symbol[keep],
                                   np.repeat(np.arange(n_symbols, dtype=np.int64), spare)])
    S, A = clone_symbol.size, n_actions
    x = rename[labels]
    t = np.flatnonzero(data.has_next)
    ok = (x[t] >= 0) & (x[t + 1] >= 0)
    counts = np.zeros((A, S, S))
    np.add.at(counts, (data.u[t[ok]], x[t[ok]], x[t[ok] + 1]), 1.0)
    if spare:
        per_row = max(1.0, counts.sum() / max(n_kept, 1) / A)
        counts[:, n_kept:, :] = rng.random((A, S - n_kept, S)) * per_row / S * 4
        counts[:, :, n_kept:] += rng.random((A, S, S - n_kept)) * 0.1
    return counts, clone_symbol


def soft_round(seq, labels, state_symbol, conf=None, *, spare: int = 0,
               settings: SoftSettings = SoftSettings(), rng=None, keep=None,
               learn_conf: bool = True, exact_below: float | None = None) -> SoftFit:
    """One soft-evidence EM round warm-started from a hard labelling.

    ``seq`` is a :class:`topomap.core.refine.methods.SymbolSequence` (the symbols as read),
    ``labels`` / ``state_symbol`` a labelling of its steps (from the hard refinement); ``keep``
    (n_states,) bool drops the states marked False (their steps must be explained by the others).
    Every kept state becomes a clone of its symbol, plus ``spare`` random clones per K-means
    symbol; Baum-Welch learns the transitions and (``learn_conf``) the confusion matrix ``conf``
    (default :func:`initial_confusion`), then Viterbi decodes.  Returns a :class:`SoftFit` whose
    ``sym`` are the symbols of the decoded clones (the corrected readings).

    With ``exact_below``, the round stops after ``settings.detect_iter`` iterations when EM
    explains fewer than that share of the steps as misread (:func:`misread_share`): the
    readings are exact, and the :class:`SoftFit` holds ``labels`` and ``state_symbol``
    unchanged and ``info["stopped"] = "exact"``.
    """
    s, ns, data = settings, seq.n_symbols, _episode_data(seq)
    rng = np.random.default_rng(0) if rng is None else rng
    state_symbol = np.asarray(state_symbol, dtype=np.int64)
    keep = np.ones(state_symbol.size, bool) if keep is None else np.asarray(keep, bool)
    counts, clone_symbol = _warm_counts(data, labels, state_symbol, keep, ns, seq.n_actions,
                                        spare, rng)
    conf = (initial_confusion(seq.n_ids, ns, s.init_error, co_successors(seq, labels))
            if conf is None else np.asarray(conf, float))
    trans, emit, conf, N, monitor = _soft_em(seq, data, counts, clone_symbol, conf, s, learn_conf,
                                             exact_below)
    info = {"em_iterations": monitor.iter, "em_loglik": monitor.history[-1],
            "clones": int(clone_symbol.size), "misread": misread_share(N, ns)}
    exact = exact_below is not None and info["misread"] < exact_below
    if exact and monitor.iter <= s.detect_iter:
        return SoftFit(labels, state_symbol, conf, seq.sym, dict(info, stopped="exact"))
    model = _model(trans, emit, np.full(clone_symbol.size, 1.0 / clone_symbol.size), s.floor)
    path, log_p = soft_viterbi(data, _log(model), soft_offsets(data, model))
    labels, state_symbol, _ = compact_labels(path, clone_symbol)
    new_sym = clone_symbol[path]
    info.update(viterbi_logp=float(log_p), corrected=float(np.mean(new_sym != seq.sym)),
                conf_offdiag=misread_rate(conf, ns))  # the map file's name for the misread rate
    return SoftFit(labels, state_symbol, conf, new_sym, info)


def _soft_em(seq, data, counts, clone_symbol, conf, s, learn_conf, exact_below):
    """Soft-evidence Baum-Welch from ``counts`` and ``conf`` (:func:`soft_round`); returns
    ``(trans, emit, conf, N, monitor)``, ``N`` the last E-step's (true x read symbol) counts.
    With ``s.accelerate="squarem"``, after its first E-step (its first ``detect_iter`` with
    ``exact_below``) the iterations are SQUAREM's cycles (:func:`_soft_squarem`); with
    ``s.label_every``, the plain loop stops once its decoded path settles (:func:`_moved`)."""
    ns, S = seq.n_symbols, clone_symbol.size
    init, pseudo = np.full(S, 1.0 / S), s.row_prior / S
    monitor = ConvergenceMonitor(s.tol * seq.T, s.max_iter, min_iter=2, rtol=s.rtol or None)
    accelerated, path = s.accelerate == "squarem", None
    plain = (s.detect_iter if exact_below is not None else 1) if accelerated else s.max_iter
    trans = _normalise_trans(counts, pseudo)
    emit = _clone_emission(conf, clone_symbol, None, s.clone_prior)
    while not monitor.converged and monitor.iter < plain:
        stats, ll = _soft_estep(data, _model(trans, emit, init, s.floor), s, clone_symbol)
        monitor.report(ll)
        last = (stats.trans.copy(), stats.emit) if accelerated else None
        trans, emit, conf, N = _soft_mstep(stats, conf, clone_symbol, ns, s, pseudo,
                                           learn_conf and monitor.iter >= s.conf_warmup)
        report("EM", monitor.iter, s.max_iter)
        if (exact_below is not None and monitor.iter == s.detect_iter
                and misread_share(N, ns) < exact_below):
            break
        if s.label_every and monitor.iter % s.label_every == 0 and not monitor.converged:
            path, moved = _moved(data, _model(trans, emit, init, s.floor), path)
            if moved < s.label_tol:
                break
    else:
        if accelerated and not monitor.converged:
            trans, emit, conf, N = _soft_squarem(data, last, conf, clone_symbol, s, learn_conf,
                                                 monitor, seq)
    report("EM", monitor.iter, monitor.iter)
    return trans, emit, conf, N, monitor


def _moved(data, model, previous):
    """``model``'s Viterbi path, the share of steps off the path ``previous`` (None: 1.0)."""
    path, _ = soft_viterbi(data, _log(model), soft_offsets(data, model))
    return path, 1.0 if previous is None else float(np.mean(path != previous))


#: ``soft.read_share`` acts where the candidates are at least this share of the clones (gridroom
#: 8 x 6 1.0, random_graph 60 0.85; the office 0.1-0.13, where it saved no time but moved ARIs)
READ_DENSE = 0.5


def _soft_estep(data, model, s, clone_symbol):
    """One soft E-step on ``model``: the expected counts (:class:`SoftStats`) and the
    log-likelihood (``s.read_share`` > 0 and candidates dense, :data:`READ_DENSE`: the forward
    pass :func:`soft_forward_read`)."""
    A, S, n_ids = model.trans.shape[0], model.trans.shape[1], model.emit.shape[1]
    pos = soft_offsets(data, model)
    if s.read_share and pos[-1] >= READ_DENSE * S * data.read.size:
        alpha, log_c = soft_forward_read(data, model, pos, s.prune, clone_symbol,
                                         read_tables(model, clone_symbol, n_ids), s.read_share)
    else:
        alpha, log_c = soft_forward(data, model, pos, s.prune)
    stats = SoftStats(np.zeros((A, S, S)), np.zeros((S, n_ids)), np.zeros(S))
    soft_backward(data, model, pos, alpha, log_c, stats)
    return stats, float(log_c.sum())


def _soft_mstep(stats, conf, clone_symbol, ns, s, pseudo, learn_conf):
    """The soft M-step from the expected counts ``stats`` (their ``trans`` normalised in place):
    ``(trans, emit, conf, N)``, the confusion matrix learned only where ``learn_conf``."""
    trans = _normalise_trans(stats.trans, pseudo)
    N = np.zeros((conf.shape[0], conf.shape[0]))
    np.add.at(N, clone_symbol, stats.emit)
    if learn_conf:
        conf = confusion_mstep(N, ns, s)
    emit = _clone_emission(conf, clone_symbol, stats.emit, s.clone_prior)
    emit[clone_symbol >= ns] = conf[clone_symbol[clone_symbol >= ns]]  # GDS: never confused
    return trans, emit, conf, N


def _soft_squarem(data, last, conf, clone_symbol, s, learn_conf, monitor, seq):
    """The rest of :func:`_soft_em`'s iterations as SQUAREM's cycles
    (:func:`~topomap.core.refine.accelerate.squarem`) on the expected transition and emission
    counts (``last``: those of the E-step before, unnormalised), every E-step reported to
    ``monitor``; its stops as the plain loop's (``tol`` or ``rtol`` judged on every cycle's
    plain step), the confusion matrix learned from ``conf_warmup`` E-steps on (the M-step of
    a point depends only on it and on its counts).  Returns the M-step of the last counts."""
    ns, S, A, n_ids = seq.n_symbols, clone_symbol.size, seq.n_actions, seq.n_ids
    init, pseudo, size = np.full(S, 1.0 / S), s.row_prior / S, A * S * S
    conf0 = conf

    def mstep(c):
        stats = SoftStats(c[:size].reshape(A, S, S).copy(), c[size:].reshape(S, n_ids), None)
        learn = learn_conf and monitor.iter >= s.conf_warmup
        return _soft_mstep(stats, conf0, clone_symbol, ns, s, pseudo, learn)

    def em_step(c):
        trans, emit, _, _ = mstep(c)
        stats, ll = _soft_estep(data, _model(trans, emit, init, s.floor), s, clone_symbol)
        monitor.report(ll)
        return np.concatenate([stats.trans.ravel(), stats.emit.ravel()]), None, ll

    counts = np.concatenate([last[0].ravel(), last[1].ravel()])
    c, _, _, _ = squarem(em_step, counts, max_iter=s.max_iter - monitor.iter, tol=s.tol * seq.T,
                         rtol=s.rtol, min_iter=max(0, 2 - monitor.iter))
    return mstep(c)


EVIDENCE = ("auto", "soft", "hard")
"""Values of the refinements' ``evidence`` parameter: ``"hard"`` the symbols as read are exact
(the refinement of old); ``"soft"`` hard and soft rounds alternate
(:mod:`topomap.core.refine.methods`); ``"auto"`` the same with misread detection (the hard result
is kept when the first soft round finds fewer misreads than :attr:`SoftSettings.detect`)."""


def check_evidence(evidence: str) -> str:
    """``evidence`` if it is one of :data:`EVIDENCE`; a :class:`ParameterError` otherwise."""
    if evidence not in EVIDENCE:
        raise ParameterError("evidence", f"must be one of {', '.join(EVIDENCE)}, got {evidence!r}")
    return evidence
