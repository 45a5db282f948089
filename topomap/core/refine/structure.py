"""Structure moves on a hard labelling: merge forward-bisimilar states, split compound ones.

Both act on what a Viterbi pass gives, a state per step (``labels``) and the symbol id each state
emits (``state_symbol``), and both decide with G tests (log-likelihood ratio tests) on counts:

* :func:`bisimilar_blocks` / :func:`merge_states` -- duplicates of one place (two states of one
  symbol whose futures agree on the data) become one state, so more data never leaves several
  states for one place (the slow tail of CSCG's EM does this one clone at a time);
* :func:`split_compounds` -- a state holding two places is split by the paper's criterion
  (Section 3.3), the predecessor groups merged bottom-up into two halves, when the halves differ
  significantly in what follows them.

Evidence from actions: the explorer picks among the *executable* actions, so a state that never
takes an action another state of its symbol takes often may be a different place (two wall cells
folded into one state differ in which moves they allow, not in where a shared move leads).  But
Viterbi decoding also divides one place's visits by the action taken next (a clone without counts
for an action never gets a step that takes it), so differing supports separate two states only
when their predecessors differ too.  Action *frequencies* are never compared, for that reason.
"""

from __future__ import annotations

import numpy as np

from ..split.engine import SplitEngine, merge_groups

__all__ = ["bisimilar_blocks", "merge_states", "merge_leftovers", "split_compounds",
           "same_partition"]


def _g_statistic(c1: dict, c2: dict) -> float:
    """G statistic (log-likelihood ratio) that two count dicts come from one distribution."""
    n1, n2 = sum(c1.values()), sum(c2.values())
    g = 0.0
    for key in c1.keys() | c2.keys():
        a, b = c1.get(key, 0.0), c2.get(key, 0.0)
        pooled = (a + b) / (n1 + n2)
        if a > 0:
            g += a * np.log(a / (n1 * pooled))
        if b > 0:
            g += b * np.log(b / (n2 * pooled))
    return 2.0 * g


def _support_differs(acts1: dict, acts2: dict, alpha: float = 1e-6) -> bool:
    """Whether one state never took an action the other takes so often that never seeing it in
    the first state's visits has probability below ``alpha``: the two allow different moves."""
    n1, n2 = sum(acts1.values()), sum(acts2.values())
    for a in acts1.keys() ^ acts2.keys():
        n_without, q = (n2, acts1[a] / n1) if a in acts1 else (n1, acts2[a] / n2)
        if q >= 1.0 or n_without * np.log1p(-q) < np.log(alpha):
            return True
    return False


def _compatible(sig1, sig2, threshold: float) -> bool:
    """Whether two states' signatures ``(successors, predecessors)`` agree.

    For every action both took, the G test must not reject one distribution of the block reached.
    If one state never takes an action the other often takes (:func:`_support_differs`), they are
    one place only if they are also reached alike (G test on the predecessor distributions): a
    place whose visits Viterbi divided by the action taken next has duplicates with different
    supports but the same predecessors, two places that allow different moves do not.
    """
    (succ1, pred1), (succ2, pred2) = sig1, sig2
    if any(_g_statistic(succ1[a], succ2[a]) > threshold for a in succ1.keys() & succ2.keys()):
        return False
    acts1 = {a: sum(c.values()) for a, c in succ1.items()}
    acts2 = {a: sum(c.values()) for a, c in succ2.items()}
    return not _support_differs(acts1, acts2) or _g_statistic(pred1, pred2) <= threshold


def _signatures(x, a, y, block, shared):
    """Signature of every state in a block of several (``shared`` (S,) bool; None elsewhere):
    ``(succ, pred)`` with ``succ[a][block of x'] = count`` over its outgoing transitions and
    ``pred[(block of x_prev, a)] = count`` over its incoming ones.  A triple is coded as one
    integer whose order is the triple's lexicographic order, so every dict is filled in that
    order."""
    sig = [({}, {}) if s else None for s in shared.tolist()]
    n_a, n_b = int(a.max()) + 1 if a.size else 1, int(block.max()) + 1
    key, cnt = np.unique((x * n_a + a) * n_b + block[y], return_counts=True)
    keep = shared[key // (n_a * n_b)]
    key, cnt = key[keep], cnt[keep]
    for s, act, b, c in zip((key // (n_a * n_b)).tolist(), (key // n_b % n_a).tolist(),
                            (key % n_b).tolist(), cnt.tolist()):
        sig[s][0].setdefault(act, {})[b] = float(c)
    key, cnt = np.unique((y * n_b + block[x]) * n_a + a, return_counts=True)
    keep = shared[key // (n_b * n_a)]
    key, cnt = key[keep], cnt[keep]
    for s, b, act, c in zip((key // (n_b * n_a)).tolist(), (key // n_a % n_b).tolist(),
                            (key % n_a).tolist(), cnt.tolist()):
        sig[s][1][(b, act)] = float(c)
    return sig


def _add_signature(total, sig) -> None:
    """Add one state's signature to a group's running total, in place."""
    for act, succ in sig[0].items():
        acc = total[0].setdefault(act, {})
        for b, c in succ.items():
            acc[b] = acc.get(b, 0.0) + c
    for key, c in sig[1].items():
        total[1][key] = total[1].get(key, 0.0) + c


def _split_block(members, sig, threshold):
    """Greedy grouping of one block's states (most visited first) into mutually compatible groups;
    returns a group index per member (in the order given)."""
    order = sorted(range(len(members)), key=lambda i: -sum(sig[members[i]][1].values()))
    groups, totals = np.empty(len(members), dtype=np.int64), []
    for i in order:
        s = sig[members[i]]
        g = next((k for k, tot in enumerate(totals) if _compatible(s, tot, threshold)), None)
        if g is None:
            g = len(totals)
            totals.append(({}, {}))
        _add_signature(totals[g], s)
        groups[i] = g
    return groups


def bisimilar_blocks(labels, state_symbol, u, has_next, threshold: float) -> np.ndarray:
    """Coarsest partition of the states into blocks of forward-bisimilar states on the data.

    Moore-style partition refinement: blocks start as the symbols (GDS states are symbols of their
    own); a block is split while its states disagree about the block reached under some action
    they both took (G test at ``threshold``, e.g. 6.63 = chi-square(1) at 1 %) or, being reached
    differently, about which actions they allow (:func:`_compatible`).  Returns the block of every
    state (``0..n-1``).
    """
    S = state_symbol.size
    t = np.flatnonzero(has_next)
    x, a, y = labels[t], u[t], labels[t + 1]
    block = np.unique(state_symbol, return_inverse=True)[1].ravel()
    while True:
        n_old = int(block.max()) + 1
        size = np.bincount(block, minlength=n_old)
        sig = _signatures(x, a, y, block, size[block] > 1)
        order = np.argsort(block, kind="stable")  # the states of every block, ascending
        first = np.concatenate([[0], np.cumsum(size)])
        new = np.empty(S, dtype=np.int64)
        n_blocks = 0
        for b in range(n_old):
            members = order[first[b]:first[b + 1]]
            if members.size == 1:  # a block of one state stays one block
                new[members] = n_blocks
                n_blocks += 1
                continue
            groups = _split_block(members.tolist(), sig, threshold)
            new[members] = n_blocks + groups
            n_blocks += int(groups.max()) + 1
        if n_blocks == n_old:
            return new
        block = new


def merge_states(labels, state_symbol, u, has_next, threshold: float):
    """Merge forward-bisimilar states (:func:`bisimilar_blocks`); returns the merged labels and
    the symbol of every merged state."""
    blocks = bisimilar_blocks(labels, state_symbol, u, has_next, threshold)
    merged_symbol = np.empty(int(blocks.max()) + 1, dtype=np.int64)
    merged_symbol[blocks] = state_symbol
    return blocks[labels], merged_symbol


def merge_leftovers(labels, state_symbol, u, has_next, threshold: float):
    """:func:`merge_states`, then every state merged into the largest other state of its symbol
    whose signature under the merged states agrees with its own (:func:`_compatible`), smallest
    first, and :func:`merge_states` again, until no state merges.  The greedy grouping of
    :func:`bisimilar_blocks` can put a small duplicate of a place, seen under few actions, with
    another place at its first pass and leave it alone once that group splits; its neighbours'
    duplicates then stay apart as well (a chain no pass merges).  Returns the merged labels and
    the symbol of every merged state."""
    labels, state_symbol = merge_states(labels, state_symbol, u, has_next, threshold)
    t = np.flatnonzero(has_next)
    for _ in range(state_symbol.size):  # every pass but the last merges a state
        S = state_symbol.size
        sig = _signatures(labels[t], u[t], labels[t + 1], np.arange(S), np.ones(S, bool))
        size = np.bincount(labels, minlength=S)
        target, touched = np.arange(S), np.zeros(S, bool)
        by_size = np.argsort(-size, kind="stable")  # the largest first
        for x in by_size[::-1].tolist():
            if touched[x]:
                continue
            for y in by_size.tolist():
                if size[y] < size[x] or (size[y] == size[x] and y >= x):
                    break
                if (state_symbol[y] == state_symbol[x] and not touched[y]
                        and _compatible(sig[x], sig[y], threshold)):
                    target[x], touched[x], touched[y] = y, True, True
                    break
        if not touched.any():
            return labels, state_symbol
        keep = target == np.arange(S)
        rename = np.cumsum(keep) - 1
        labels, state_symbol = rename[target[labels]], state_symbol[keep]
        labels, state_symbol = merge_states(labels, state_symbol, u, has_next, threshold)
    return labels, state_symbol


def same_partition(a, b) -> bool:
    """Whether two labellings of the same steps group them identically (up to renaming): as
    many distinct (a, b) pairs as distinct labels on either side.  The pairs are counted as one
    integer each (``rank of a`` x ``labels of b`` + ``rank of b``), 0.6 ms on 10,000 steps against
    7 ms for numpy's row-wise ``unique``."""
    ua, ia = np.unique(np.ravel(a), return_inverse=True)
    ub, ib = np.unique(np.ravel(b), return_inverse=True)
    if ua.size != ub.size:
        return False
    return np.unique(ia.astype(np.int64) * ub.size + ib).size == ua.size


def _chi2_quantile(df: int, z: float) -> float:
    """Upper quantile of chi-square(df) at the standard-normal score ``z`` (3.09: p = 0.001),
    by the Wilson-Hilferty approximation."""
    h = 2.0 / (9.0 * df)
    return df * (1.0 - h + z * np.sqrt(h)) ** 3


def _g_test(rows: np.ndarray):
    """G statistic and degrees of freedom of "the rows of a (2 x columns) count table come from one
    distribution" (columns empty in both rows are ignored)."""
    rows = rows[:, rows.sum(axis=0) > 0].astype(np.float64)
    n = rows.sum(axis=1, keepdims=True)
    if rows.shape[1] < 2 or (n == 0).any():
        return 0.0, 0
    expected = n * rows.sum(axis=0) / n.sum()
    nz = rows > 0
    return 2.0 * float((rows[nz] * np.log(rows[nz] / expected[nz])).sum()), rows.shape[1] - 1


def _best_split(engine: SplitEngine, q: int, z: float):
    """The paper's split of state ``q`` (predecessor groups merged bottom-up into two halves) if
    the halves differ significantly (normal score ``z``) in ``(u, x')``; ``None`` otherwise.
    Returns the predecessor keys ``x[t-1] * A + u[t-1]`` of the smaller half."""
    if engine.tables[q][1].sum() < 2:
        return None
    counts, keys, _ = engine.count_matrix(q)
    if keys.size < 2:
        return None
    side = merge_groups(counts)
    g, df = _g_test(np.stack([counts[~side].sum(axis=0), counts[side].sum(axis=0)]))
    if df == 0 or g <= _chi2_quantile(df, z):
        return None
    if counts[side].sum() > counts[~side].sum():
        side = ~side
    return keys[side]


def split_compounds(labels, state_symbol, u, has_prev, has_next, n_actions: int, *,
                    z: float, splittable=None):
    """Split every state that holds two places, once, by the paper's criterion.

    A state is split when the two predecessor-defined halves of its steps (Section 3.3 of the
    paper) differ significantly in what follows them, the pair (action, next state): G test at
    the normal score ``z`` (e.g. 3.09: p = 0.001; ``inf`` never splits); the action is evidence, as in
    the paper's ``H(u|x)``.  All proposals are computed on the input labelling; a step moves to the
    new state when its predecessor key is in the smaller half.  ``splittable`` (S,) bool excludes
    states (GDS).  Returns ``(labels, state_symbol)`` with new states appended.
    """
    S = state_symbol.size
    splittable = np.ones(S, dtype=bool) if splittable is None else splittable
    engine = SplitEngine(labels, u, S, n_actions, has_prev, has_next)
    out, symbols = labels.copy(), list(state_symbol)
    for q in np.flatnonzero(splittable).tolist():
        keys = _best_split(engine, q, z)
        if keys is None:
            continue
        steps = np.flatnonzero((labels == q) & has_prev)
        key = labels[steps - 1] * n_actions + u[steps - 1]
        out[steps[np.isin(key, keys)]] = len(symbols)
        symbols.append(symbols[q])
    return out, np.asarray(symbols, dtype=np.int64)
