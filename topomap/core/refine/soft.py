"""Soft symbol evidence: the refinement when sensors misread some views.

The hard refinement (:class:`topomap.core.refine.methods.EMRefinement`) takes every step's K-means
symbol as exact: each clone emits one symbol, so a misread view must be explained by a clone of
the symbol it was read as, and every misread starts a new clone chain (gridroom 8x6 with 18 %
misreads: 227 states for 48 places).  Here the symbol read is evidence: a clone of symbol ``k``
reads ``r`` with probability ``C[k, r]`` (the confusion matrix, learned by EM with a prior that
favours the diagonal; GDS ids are never confused), so a step may be explained by a clone of
another symbol, which corrects the reading.

This module holds the soft round (:func:`soft_round`: Baum-Welch with soft evidence, then
Viterbi); its settings are :class:`~topomap.core.refine.settings.SoftRounds` and
:class:`~topomap.core.refine.settings.Reading`, what every soft round runs
:mod:`topomap.core.refine.evidence`; the confusion matrix and the misread share are
:mod:`topomap.core.refine.confusion`, evidence from each step's own observation in place of it
:mod:`topomap.core.refine.observed`; merging twin states (:func:`merge_twins`) and choosing the
states a round keeps (:func:`keep_states`) are :mod:`topomap.core.refine.soft_states`.  Soft EM
cannot create structure and a hard refinement on misread symbols creates too much, so the two
alternate; :mod:`topomap.core.refine.rounds` sequences the hard and soft rounds.  Kernels:
:mod:`topomap.core.refine.soft_kernels`.
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from ..checks import ParameterError
from ..progress import report
from .accelerate import squarem
from .clones import compact_labels
from .confusion import (co_successors, confusion_mstep, initial_confusion, misread_rate,
                        misread_share)
from .convergence import ConvergenceMonitor
from .evidence import (READ_DENSE, decode, episode_data, evidence_model, normalise_transitions,
                       soft_estep, warm_counts)
from .renamed import SOFT_FIELDS, SoftSettings
from .settings import Reading, SoftRounds, settings_of
from .soft_kernels import SoftStats
from .soft_states import keep_states, merge_twins, min_steps_of, successor_surprise

__all__ = ["SoftFit", "EVIDENCE", "check_evidence", "soft_round", "misread_rate",
           "misread_share", "successor_surprise", "merge_twins", "keep_states", "min_steps_of",
           "SoftSettings", "soft_settings", "READ_DENSE"]


@dataclass
class SoftFit:
    """Result of a soft round: Viterbi ``labels`` (T,), ``state_symbol`` (n,), the confusion matrix
    ``conf`` (n_ids, n_ids), the corrected symbols ``sym`` (T,) and ``info``."""

    labels: np.ndarray
    state_symbol: np.ndarray
    conf: np.ndarray
    sym: np.ndarray
    info: dict


def _clone_emission(conf, clone_symbol, counts, strength):
    """Per-clone read-symbol distributions: the clone's expected read counts ``counts`` (S, K)
    shrunk towards its symbol's row of ``conf`` with ``strength`` pseudo-steps (``inf`` or no
    counts: the row itself).  GDS clones keep their identity row."""
    prior = conf[clone_symbol]
    if counts is None or not np.isfinite(strength):
        return prior
    return (counts + strength * prior) / (counts.sum(axis=1, keepdims=True) + strength)


def split_soft_settings(settings) -> tuple[SoftRounds, Reading]:
    """The soft rounds' and the reading's part of an old :class:`SoftSettings` (its growth
    caps, which a soft round does not use, are left out)."""
    parts = {"soft": {}, "reading": {}, "growth": {}}
    for old, new in SOFT_FIELDS.items():
        group, name = new.split(".")
        parts[group][name] = getattr(settings, old)
    return SoftRounds(**parts["soft"]), Reading(**parts["reading"])


def soft_settings(value) -> SoftSettings:
    """``value`` -- an old :class:`SoftSettings` or a mapping of its fields -- checked, as a
    :class:`SoftSettings` (until 0.4: the settings are :class:`SoftRounds`, :class:`Reading`
    and :class:`~topomap.core.refine.settings.Growth`'s caps since 0.3)."""
    warnings.warn("soft_settings goes in 0.4: the soft settings are SoftRounds and Reading "
                  "(topomap.core.refine.settings.settings_of checks either)", FutureWarning,
                  stacklevel=2)
    if isinstance(value, Mapping):
        value = SoftSettings(**value)
    if not isinstance(value, SoftSettings):
        raise ParameterError("soft", f"must be SoftSettings or a mapping of its fields, got "
                                     f"{value!r}")
    parts = split_soft_settings(value)
    for cls, part, group in ((SoftRounds, parts[0], "soft"), (Reading, parts[1], "soft")):
        settings_of(cls, part, group)
    return value


def soft_round(seq, labels, state_symbol, conf=None, *, spare: int = 0,
               soft: SoftRounds = SoftRounds(), reading: Reading = Reading(), rng=None,
               keep=None, learn_conf: bool = True, exact_below: float | None = None,
               settings: SoftSettings | None = None) -> SoftFit:
    """One soft-evidence EM round warm-started from a hard labelling.

    ``seq`` is a :class:`topomap.core.refine.methods.SymbolSequence` (the symbols as read),
    ``labels`` / ``state_symbol`` a labelling of its steps (from the hard refinement); ``keep``
    (n_states,) bool drops the states marked False (their steps must be explained by the others).
    Every kept state becomes a clone of its symbol, plus ``spare`` random clones per K-means
    symbol; Baum-Welch learns the transitions and (``learn_conf``) the confusion matrix ``conf``
    (default :func:`initial_confusion`), then Viterbi decodes.  ``soft`` and ``reading`` are its
    settings (``settings``, an old :class:`SoftSettings` in their place, until 0.4).  Returns a
    :class:`SoftFit` whose ``sym`` are the symbols of the decoded clones (the corrected
    readings).

    With ``exact_below``, the round stops after ``reading.detect_iter`` iterations when EM
    explains fewer than that share of the steps as misread (:func:`misread_share`): the
    readings are exact, and the :class:`SoftFit` holds ``labels`` and ``state_symbol``
    unchanged and ``info["stopped"] = "exact"``.
    """
    if settings is not None:
        warnings.warn("soft_round's settings= was split in 0.3 into soft= (SoftRounds) and "
                      "reading= (Reading); settings= goes in 0.4", FutureWarning, stacklevel=2)
        soft, reading = split_soft_settings(settings)
    ns, data = seq.n_symbols, episode_data(seq)
    rng = np.random.default_rng(0) if rng is None else rng
    state_symbol = np.asarray(state_symbol, dtype=np.int64)
    keep = np.ones(state_symbol.size, bool) if keep is None else np.asarray(keep, bool)
    counts, clone_symbol = warm_counts(data, labels, state_symbol, keep, ns, seq.n_actions,
                                       spare, rng)
    conf = (initial_confusion(seq.n_ids, ns, reading.init_error, co_successors(seq, labels))
            if conf is None else np.asarray(conf, float))
    trans, emit, conf, N, monitor = _soft_em(seq, data, counts, clone_symbol, conf,
                                             (soft, reading), learn_conf, exact_below)
    info = {"em_iterations": monitor.iter, "em_loglik": monitor.history[-1],
            "clones": int(clone_symbol.size), "misread": misread_share(N, ns)}
    exact = exact_below is not None and info["misread"] < exact_below
    if exact and monitor.iter <= reading.detect_iter:
        return SoftFit(labels, state_symbol, conf, seq.sym, dict(info, stopped="exact"))
    model = evidence_model(trans, emit, np.full(clone_symbol.size, 1.0 / clone_symbol.size),
                           reading.floor)
    path, log_p = decode(data, model)
    labels, state_symbol, _ = compact_labels(path, clone_symbol)
    new_sym = clone_symbol[path]
    info.update(viterbi_logp=log_p, corrected=float(np.mean(new_sym != seq.sym)),
                conf_offdiag=misread_rate(conf, ns))  # the map file's name for the misread rate
    return SoftFit(labels, state_symbol, conf, new_sym, info)


def _soft_em(seq, data, counts, clone_symbol, conf, settings, learn_conf, exact_below):
    """Soft-evidence Baum-Welch from ``counts`` and ``conf`` (:func:`soft_round`; ``settings``
    its ``(soft, reading)``); returns ``(trans, emit, conf, N, monitor)``, ``N`` the last
    E-step's (true x read symbol) counts.  With ``soft.accelerate="squarem"``, after its first
    E-step (its first ``reading.detect_iter`` with ``exact_below``) the iterations are SQUAREM's
    cycles (:func:`_soft_squarem`); with ``soft.label_every``, the plain loop stops once its
    decoded path settles (:func:`_moved`)."""
    (s, r), ns, S = settings, seq.n_symbols, clone_symbol.size
    init, pseudo = np.full(S, 1.0 / S), s.row_prior / S
    monitor = ConvergenceMonitor(s.tol * seq.T, s.max_iter, min_iter=2, rtol=s.rtol or None)
    accelerated, path = s.accelerate == "squarem", None
    plain = (r.detect_iter if exact_below is not None else 1) if accelerated else s.max_iter
    trans = normalise_transitions(counts, pseudo)
    emit = _clone_emission(conf, clone_symbol, None, r.clone_prior)
    while not monitor.converged and monitor.iter < plain:
        stats, ll = soft_estep(data, evidence_model(trans, emit, init, r.floor), clone_symbol,
                               prune=s.prune, read_share=r.read_share)
        monitor.report(ll)
        last = (stats.trans.copy(), stats.emit) if accelerated else None
        trans, emit, conf, N = _soft_mstep(stats, conf, clone_symbol, ns, r, pseudo,
                                           learn_conf and monitor.iter >= r.conf_warmup)
        report("EM", monitor.iter, s.max_iter)
        if (exact_below is not None and monitor.iter == r.detect_iter
                and misread_share(N, ns) < exact_below):
            break
        if s.label_every and monitor.iter % s.label_every == 0 and not monitor.converged:
            path, moved = _moved(data, evidence_model(trans, emit, init, r.floor), path)
            if moved < s.label_tol:
                break
    else:
        if accelerated and not monitor.converged:
            trans, emit, conf, N = _soft_squarem(data, last, conf, clone_symbol, settings,
                                                 learn_conf, monitor, seq)
    report("EM", monitor.iter, monitor.iter)
    return trans, emit, conf, N, monitor


def _moved(data, model, previous):
    """``model``'s Viterbi path, the share of steps off the path ``previous`` (None: 1.0)."""
    path, _ = decode(data, model)
    return path, 1.0 if previous is None else float(np.mean(path != previous))


def _soft_mstep(stats, conf, clone_symbol, ns, reading, pseudo, learn_conf):
    """The soft M-step from the expected counts ``stats`` (their ``trans`` normalised in place):
    ``(trans, emit, conf, N)``, the confusion matrix learned only where ``learn_conf``."""
    trans = normalise_transitions(stats.trans, pseudo)
    N = np.zeros((conf.shape[0], conf.shape[0]))
    np.add.at(N, clone_symbol, stats.emit)
    if learn_conf:
        conf = confusion_mstep(N, ns, reading)
    emit = _clone_emission(conf, clone_symbol, stats.emit, reading.clone_prior)
    emit[clone_symbol >= ns] = conf[clone_symbol[clone_symbol >= ns]]  # GDS: never confused
    return trans, emit, conf, N


def _soft_squarem(data, last, conf, clone_symbol, settings, learn_conf, monitor, seq):
    """The rest of :func:`_soft_em`'s iterations as SQUAREM's cycles
    (:func:`~topomap.core.refine.accelerate.squarem`) on the expected transition and emission
    counts (``last``: those of the E-step before, unnormalised), every E-step reported to
    ``monitor``; its stops as the plain loop's (``tol`` or ``rtol`` judged on every cycle's
    plain step), the confusion matrix learned from ``reading.conf_warmup`` E-steps on (the
    M-step of a point depends only on it and on its counts).  Returns the M-step of the last
    counts."""
    (s, r), ns, S, A, n_ids = settings, seq.n_symbols, clone_symbol.size, seq.n_actions, seq.n_ids
    init, pseudo, size = np.full(S, 1.0 / S), s.row_prior / S, A * S * S
    conf0 = conf

    def mstep(c):
        stats = SoftStats(c[:size].reshape(A, S, S).copy(), c[size:].reshape(S, n_ids), None)
        learn = learn_conf and monitor.iter >= r.conf_warmup
        return _soft_mstep(stats, conf0, clone_symbol, ns, r, pseudo, learn)

    def em_step(c):
        trans, emit, _, _ = mstep(c)
        stats, ll = soft_estep(data, evidence_model(trans, emit, init, r.floor), clone_symbol,
                               prune=s.prune, read_share=r.read_share)
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
is kept when the first soft round finds fewer misreads than :attr:`Reading.detect
<topomap.core.refine.settings.Reading.detect>`)."""


def check_evidence(evidence: str) -> str:
    """``evidence`` if it is one of :data:`EVIDENCE`; a :class:`ParameterError` otherwise."""
    if evidence not in EVIDENCE:
        raise ParameterError("evidence", f"must be one of {', '.join(EVIDENCE)}, got {evidence!r}")
    return evidence
