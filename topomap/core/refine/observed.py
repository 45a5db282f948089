"""Soft evidence from each step's own observation (``refine.reading.temperature``).

The soft rounds of :mod:`topomap.core.refine.soft` weigh a clone of symbol ``k`` at a step read as
``r`` by the confusion matrix, ``C[k, r]``: the same for every step read as ``r``.  But phase 1
models every symbol by a Gaussian, so each step's observation ``o_t`` says by itself how likely
each symbol is to have made it: an observation deep inside its cluster is read surely, one near
the boundary of two clusters could be either.  With ``reading.temperature`` > 0 a soft round
takes that as the evidence of the step,

    e_t(k) = (p(o_t | k) / max_j p(o_t | j)) ** (1 / temperature),

the symbols' likelihood relative to the best one, tempered; a symbol is a candidate
where that is at least :data:`SHARE`, and a GDS step keeps its GDS id (so does a step whose
observation no symbol's model gives a finite density: its symbol as read).  The transitions are
learned as in a confusion-matrix round; the evidence stays fixed.  A temperature above 1
flattens the evidence, so the map's transitions weigh more against a reading.

By default (``reading.observed_in="early"``) every soft round takes this evidence where the
first hard round's labelling shows misreads and its moves pair no two symbols often
(:func:`~topomap.core.refine.soft_states.successor_pairing` under
:data:`~topomap.core.refine.rounds.PAIRED_READ`); else the first soft round reads with the
confusion matrix and the rounds after it take this evidence unless that matrix pairs two
symbols as often (``"auto"``): a view phase 1 cut into two symbols, whose halves the Gaussians
would keep apart as two places while the confusion matrix lets one clone explain both; then
only the last round, which gives the map, takes it (``"last"`` always so; ``"all"``: every
round, the first too).  The first round on this evidence stops once its readings settle
(``reading.settle``).

A round runs what every soft round runs (:mod:`topomap.core.refine.evidence`), each step its own
"read symbol": the evidence of a round is a dense (clones, steps) table, at most
:data:`MAX_BYTES` (a round that would need more is the confusion matrix's, recorded
``"observed": "over MAX_BYTES"``).
"""

from __future__ import annotations

import numpy as np

from .clones import compact_labels
from .convergence import ConvergenceMonitor
from .evidence import decode, episode_data, normalise_transitions, soft_estep, warm_counts
from .settings import Reading, SoftRounds
from .soft import SoftFit, soft_round
from .soft_kernels import SoftData, SoftModel, soft_candidates

__all__ = ["SHARE", "MAX_BYTES", "step_evidence", "observed_evidence", "observed_round"]

#: a symbol whose tempered evidence at a step is below this is not a candidate there.  At
#: temperature 1 gridroom 8x6 at 9.8 % misreads keeps 3.1 of its 4 symbols per step, the true symbol
#: of 99.5 % of the misread steps among them (``bench_noise_floor.py --candidates``); the same
#: cut made before tempering lowered the office at 25.6 % misreads, seed 2, from 0.98 to 0.75
SHARE = 1e-6

#: the most memory a round's (clones x steps) evidence table may take
MAX_BYTES = 2 * 1024 ** 3


def step_evidence(loglik, sym, n_symbols: int, n_ids: int, temperature: float) -> np.ndarray:
    """The (T, n_ids) evidence of every step (module docstring): ``loglik`` (T, n_symbols) the
    log-density of each step's observation under each K-means symbol's model, ``sym`` (T,) the
    symbols read (ids from ``n_symbols`` on are GDS ids: one-hot rows)."""
    sym = np.asarray(sym)
    ev = np.zeros((sym.size, n_ids))
    plain = np.flatnonzero(sym < n_symbols)
    with np.errstate(invalid="ignore"):  # a row of -inf: no candidate, its reading kept below
        rel = (loglik[plain] - loglik[plain].max(axis=1, keepdims=True)) / temperature
        ev[plain, :n_symbols] = np.where(rel >= np.log(SHARE), np.exp(rel), 0.0)
    alone = np.flatnonzero((sym >= n_symbols) | (ev.sum(axis=1) == 0))
    ev[alone, sym[alone]] = 1.0
    return ev


def observed_evidence(seq, temperature: float, observed):
    """The evidence the soft rounds on ``seq`` take (:func:`step_evidence`), or None -- the
    confusion matrix -- with ``temperature`` 0 or no ``observed``: the (T, n_symbols)
    log-densities of :meth:`~topomap.core.refine.rounds.CloneRefinement.fit`, or a function
    returning them (called here, so only when a soft round runs)."""
    if temperature == 0 or observed is None:
        return None
    loglik = np.asarray(observed() if callable(observed) else observed, dtype=np.float64)
    if loglik.shape != (seq.T, seq.n_symbols):
        raise ValueError(f"observed: must be ({seq.T}, {seq.n_symbols}) log-densities, one row "
                         f"per step and a column per symbol, got shape {loglik.shape}")
    if np.isnan(loglik).any() or np.isposinf(loglik).any():
        raise ValueError("observed: the log-densities must be finite or -inf")
    return step_evidence(loglik, seq.sym, seq.n_symbols, seq.n_ids, temperature)


def observed_round(seq, labels, state_symbol, conf=None, *, evidence, spare: int = 0,
                   soft: SoftRounds = SoftRounds(), reading: Reading = Reading(), rng=None,
                   keep=None, exact_below: float | None = None) -> SoftFit:
    """A soft round (:func:`~topomap.core.refine.soft.soft_round`, the same arguments and
    result) with the per-step ``evidence`` (:func:`observed_evidence`) in place of the confusion
    matrix, which is handed on unchanged (``conf``, the identity where None).  Its record says
    ``"evidence": "observed"``; its ``misread`` is the share of the K-means steps EM explains by
    a clone of another symbol, and so is its ``conf_offdiag``, the map file's name for the
    misread rate of a round (a confusion-matrix round's, :func:`~.confusion.misread_rate`)."""
    ns, base = seq.n_symbols, episode_data(seq)
    rng = np.random.default_rng(0) if rng is None else rng
    state_symbol = np.asarray(state_symbol, dtype=np.int64)
    keep = np.ones(state_symbol.size, bool) if keep is None else np.asarray(keep, bool)
    if (int(keep.sum()) + spare * ns) * seq.T * 8 > MAX_BYTES:  # (clones, steps) evidence
        fit = soft_round(seq, labels, state_symbol, conf, spare=spare, soft=soft,
                         reading=reading, rng=rng, keep=keep,
                         exact_below=exact_below)  # needs no such table
        fit.info["observed"] = "over MAX_BYTES"
        return fit
    counts, clone_symbol = warm_counts(base, labels, state_symbol, keep, ns, seq.n_actions,
                                       spare, rng)
    S, T = clone_symbol.size, seq.T
    data = SoftData(np.arange(T, dtype=np.int64), base.u, base.has_next)  # each step its own read
    emit = np.ascontiguousarray(evidence[:, clone_symbol].T)
    cptr, cidx = soft_candidates(emit)
    # the first round corrects the readings, and stops once they settle; the later ones drain
    # the states the misreads left, which the readings do not show, and the last gives the map
    settle = reading.settle if exact_below is not None else 0.0
    trans, misread, monitor = _observed_em(seq, data, counts, emit, (cptr, cidx), clone_symbol,
                                           (soft, reading, settle), exact_below)
    conf = np.eye(seq.n_ids) if conf is None else conf
    info = {"evidence": "observed", "em_iterations": monitor.iter,
            "em_loglik": monitor.history[-1], "clones": int(S), "misread": misread}
    if (exact_below is not None and misread < exact_below
            and monitor.iter <= reading.detect_iter):
        return SoftFit(labels, state_symbol, conf, seq.sym, dict(info, stopped="exact"))
    path, log_p = decode(data, SoftModel(trans, emit, np.full(S, 1.0 / S), cptr, cidx))
    labels, state_symbol, _ = compact_labels(path, clone_symbol)
    new_sym = clone_symbol[path]
    info.update(viterbi_logp=log_p, corrected=float(np.mean(new_sym != seq.sym)),
                conf_offdiag=misread)
    return SoftFit(labels, state_symbol, conf, new_sym, info)


def _observed_em(seq, data, counts, emit, candidates, clone_symbol, settings, exact_below):
    """Baum-Welch on the transitions with the evidence ``emit`` fixed; returns the transitions,
    the misread share of the last E-step and the convergence monitor.  Stops as the
    confusion-matrix rounds do (``settings``, ``(soft, reading)``: ``soft.tol``, ``soft.rtol``,
    ``soft.max_iter``; with ``exact_below`` after ``reading.detect_iter`` iterations explaining
    fewer steps as misread)."""
    (s, r, settle), S, T, ns = settings, clone_symbol.size, seq.T, seq.n_symbols
    init, pseudo = np.full(S, 1.0 / S), s.row_prior / S
    monitor = ConvergenceMonitor(s.tol * T, s.max_iter, min_iter=2, rtol=s.rtol or None)
    trans = normalise_transitions(counts, pseudo)
    plain = np.flatnonzero(seq.sym < ns)
    other = clone_symbol[:, None] != seq.sym[None, plain]  # (S, plain steps)
    misread, read = 0.0, None
    while not monitor.converged and monitor.iter < s.max_iter:
        stats, ll = soft_estep(data, SoftModel(trans, emit, init, *candidates), clone_symbol,
                               prune=s.prune)  # no read tables: T read "symbols"
        monitor.report(ll)
        occ = stats.emit[:, plain]
        misread = float((occ * other).sum() / max(occ.sum(), 1e-300))
        trans = normalise_transitions(stats.trans, pseudo)
        if exact_below is not None and monitor.iter == r.detect_iter and misread < exact_below:
            break
        if settle:
            read, moved = _read_moved(stats.emit, clone_symbol, seq.n_ids, read)
            if moved < settle and monitor.iter >= 2:
                break
    return trans, misread, monitor


def _read_moved(occupancy, clone_symbol, n_ids: int, previous):
    """Every step's most probable symbol under the clone ``occupancy`` (S, T) of an E-step, and
    the share of steps where it is not ``previous``'s (None: 1.0)."""
    by_symbol = np.zeros((n_ids, occupancy.shape[1]))
    for c, k in enumerate(clone_symbol.tolist()):  # np.add.at's sums, a row at a time: the
        by_symbol[k] += occupancy[c]  # same bits in 0.3 ms, not 7 ms (74 clones x 10,000 steps)
    read = by_symbol.argmax(axis=0)
    return read, 1.0 if previous is None else float(np.mean(read != previous))
