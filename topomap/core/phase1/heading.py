"""A heading integrated from the actions: phase 1's states as (symbol, heading) pairs where turn
actions rotate the view.

An egocentric view depends on where the agent faces.  In a room that looks the same turned by
90 degrees, the four rotated copies of a pose show the same views, and a map over the views
alone merges them (MiniGrid Empty-16x16 cannot pass ARI 0.47 that way).  Turn actions change a
latent heading by a fixed step, and in a world where turns never fail the heading integrated
from the actions since the walk began is exact, up to the heading the walk began with.  So a
(symbol, heading) pair tells the rotated copies apart, and phase 1 starts from one state per
pair instead of one per symbol (:func:`head_states`).  Everything is learned from the symbols
and the actions (:func:`learn_turns`); the true heading is never needed, and a learned map
decodes a new walk without it (the heading is carried by the map's states and transitions).

**Which actions turn.**  A turn of order ``k`` (``k`` turns make a full circle) brings the agent
back to its pose after ``k`` repetitions, so the symbol after a run of ``k`` equal actions is the
symbol before it.  For every action and ``k`` = 1 .. :data:`MAX_ORDER`, among the windows of
``k`` repetitions inside an episode (at least :data:`MIN_WINDOWS` of them), the share whose two
end symbols agree is compared with the share of all ``k``-step windows that agree by chance:
``kappa = (share - chance) / (1 - chance)``.  The action's order is the first ``k`` with
``kappa >= MIN_AGREEMENT``; an action of order 1 leaves the view as it is and one of no order
moves the agent: neither turns the heading.

**How far each turns.**  With turn orders ``k_a`` a circle has ``n = lcm(k_a)`` headings and
turn ``a`` rotates by ``j * n / k_a`` for some ``j`` prime to ``k_a`` (left and right: ``+1``
and ``-1`` or ``+1`` and ``+1``).  Two turns of which one then the other brings the view back
as an order's cycle does (:func:`inverse_pairs`) rotate by opposite steps.  Every hypothesis
left, up to a renaming of the headings, is integrated (every episode from heading 0, each later one turned to agree best with the ones
before it) and scored by the information a step's symbol gives about its heading on steps it
was not counted on (:func:`heldout_gain`): where the heading is part of the place, a symbol seen
at one place comes with one heading.  The best hypothesis is kept when its gain is at least
:data:`MIN_GAIN` nats per step and its heading keeps its origin: no block of the walk agrees
better with the rest turned, or no more than :data:`MAX_DRIFTING` (:func:`drifting_blocks`;
``heading="on"``: whatever the two tests say; ``"off"``: never tried).  A heading that drifts (turns that sometimes fail) is left
out: turns failing 0.1 % of the time move 3 or 4 of 10 blocks of a 4,000-step walk, 1 % or more
give a negative gain; a heading that keeps its origin moves none on every walk measured but
FourRooms' seed 1, whose rooms look alike turned (one block).

Measured (K-means symbols of the benchmark walks, seed 0): MiniGrid FourRooms 10,000 steps and
Empty-16x16 50,000 steps find left and right of order 4 (kappa 0.72 and 1.0) and the opposite
rotations, gain 0.29 and 0.16 nats (the same turns 0.02 / 0.07; with 1 % of the turns failing
-0.31 / -0.03); the paper's office, gridroom, the random graph and the arena's logs find no turn.
With ``refine="em"`` (medians of seeds 0-2, ``benchmarks/notes/worlds.md``): FourRooms 50,000
steps ARI 0.953 (0.689 without the heading), Empty-16x16 50,000 steps 0.925 (0.547); the split
alone maps Empty-8x8 exactly (0.716 without).
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np

from .loops import join_loop_views

__all__ = ["MODES", "MAX_ORDER", "MIN_WINDOWS", "MIN_AGREEMENT", "MIN_GAIN", "DECIDE_STEPS",
           "MAX_DRIFTING", "FOLD_BLOCKS", "Turns", "HeadedStates", "turn_orders", "inverse_pairs", "integrate",
           "heldout_gain", "drifting_blocks", "learn_turns", "head_states", "phase1_states"]

#: ``MapLearner(heading=...)``: ``"auto"`` where the data support it, ``"on"`` wherever an
#: action turns, ``"off"`` never
MODES = ("auto", "on", "off")
#: the longest cycle of one action tried, in repetitions (a 45-degree turn: 8)
MAX_ORDER = 8
#: windows of ``k`` repetitions an action needs before its order ``k`` is judged (a random walk
#: of 2,000 steps over three actions holds about 25 runs of four equal actions)
MIN_WINDOWS = 20
#: the agreement beyond chance (kappa) of a turn's cycle: MiniGrid's turns of order 4 reach 0.72
#: (FourRooms, where K-means cuts some views in two) to 1.0; the compass moves of gridroom at
#: most 0.32
MIN_AGREEMENT = 0.5
#: the held-out information (nats per step) a step's symbol must give about its heading: the
#: right rotations give 0.16-0.29 on the MiniGrid rooms, a heading whose turns fail 1 % of the
#: time -0.03 to -0.31
MIN_GAIN = 0.01
#: the steps the decision looks at (the first ones): enough for any order and gain above, and
#: 10^7-step logs pay no more than 10^5
DECIDE_STEPS = 100_000
#: blocks of the walk (of :data:`FOLD_BLOCKS`) that may agree better with the rest turned: a
#: room that looks like another room turned by 90 degrees moves one block where the turns never
#: fail (FourRooms 10,000 steps, seed 1: by 465 nats), turns failing 0.1 % of the time move 3
#: or 4 on every walk of the tests' 2 x 2 room (6 seeds), 0.2-0.5 % 1 to 10
MAX_DRIFTING = 1
#: the held-out gain counts on every other of this many blocks of the steps and scores the rest,
#: then the other way round
FOLD_BLOCKS = 10


@dataclass(frozen=True)
class Turns:
    """What each action does to a heading of ``n_headings`` values: ``steps[a]`` headings turned
    by action ``a`` (0: not a turn); ``gain`` the held-out nats of :func:`heldout_gain`."""

    n_headings: int
    steps: tuple
    gain: float


def _episodes(T: int, lengths) -> np.ndarray:
    return np.repeat(np.arange(len(lengths)), lengths)


def _agreement(sym, episode, k: int, windows=None) -> tuple[int, float]:
    """``(n, share)``: of the steps ``t`` (those in ``windows``, a mask, or all) whose step
    ``t + k`` lies in their episode, how many there are and the share with the same symbol."""
    same_episode = episode[k:] == episode[:-k]
    ok = same_episode if windows is None else same_episode & windows
    n = int(ok.sum())
    return n, (float(np.mean(sym[k:][ok] == sym[:-k][ok])) if n else 0.0)


def turn_orders(sym, u, lengths, n_actions: int) -> list[int]:
    """The order of every action as a turn (module docstring), 0 for an action that does not
    turn.  ``sym`` (T,) the phase-1 states (symbols, then GDS ids), ``u`` (T,) the actions."""
    sym, u = np.asarray(sym), np.asarray(u)
    episode = _episodes(sym.size, lengths)
    chance = {}
    orders = []
    for a in range(n_actions):
        runs = np.concatenate([[0], np.cumsum(u == a)])
        order = 0
        for k in range(1, min(MAX_ORDER, sym.size - 1) + 1):
            windows = (runs[k:] - runs[:-k])[:sym.size - k] == k
            n, share = _agreement(sym, episode, k, windows)
            if n < MIN_WINDOWS:
                break
            if k not in chance:
                chance[k] = _agreement(sym, episode, k)[1]
            if chance[k] < 1 and (share - chance[k]) / (1 - chance[k]) >= MIN_AGREEMENT:
                order = k
                break
        orders.append(order if order >= 2 else 0)
    return orders


def integrate(u, lengths, steps, n_headings: int) -> np.ndarray:
    """(T,) the heading of every step: 0 at the start of each episode, then turned by
    ``steps[u[t]]`` (mod ``n_headings``) after every step ``t``."""
    u = np.asarray(u, dtype=np.int64)
    turned = np.concatenate([[0], np.cumsum(np.asarray(steps, dtype=np.int64)[u])])
    starts = np.cumsum(np.concatenate([[0], lengths]))[:-1]
    before = np.repeat(turned[starts], lengths)
    return ((turned[:-1] - before) % n_headings).astype(np.int64)


def _align(sym, heading, lengths, n_headings: int, n_ids: int) -> np.ndarray:
    """``heading`` with every episode after the first turned by the offset that makes its
    (symbol, heading) pairs agree most with those of the episodes before it."""
    if len(lengths) == 1:
        return heading
    out = heading.copy()
    counts = np.zeros((n_ids, n_headings))
    start = 0
    for i, length in enumerate(lengths):
        s, h = sym[start:start + length], heading[start:start + length]
        if i:
            scores = [counts[s, (h + o) % n_headings].sum() for o in range(n_headings)]
            out[start:start + length] = (h + int(np.argmax(scores))) % n_headings
        np.add.at(counts, (s, out[start:start + length]), 1.0)
        start += length
    return out


def heldout_gain(sym, heading, n_headings: int, n_ids: int, blocks: int = FOLD_BLOCKS) -> float:
    """The mean over the steps of ``log p(h | symbol) - log p(h)`` (nats), each step's
    probabilities counted on the other half of ``blocks`` interleaved blocks of the steps (one
    pseudo-step of the heading's marginal smooths every symbol's counts, one of the uniform
    the marginal): about 0 for a heading the symbols say nothing about, below 0 where the
    halves disagree, up to ``log n_headings`` where every symbol comes with one heading."""
    sym, heading = np.asarray(sym), np.asarray(heading)
    T = sym.size
    half = (np.arange(T) * blocks // max(T, 1)) % 2
    total = 0.0
    for f in (0, 1):
        train, test = half != f, half == f
        counts = np.zeros((n_ids, n_headings))
        np.add.at(counts, (sym[train], heading[train]), 1.0)
        marginal = (counts.sum(axis=0) + 1.0) / (train.sum() + n_headings)
        s, h = sym[test], heading[test]
        p = (counts[s, h] + marginal[h]) / (counts[s].sum(axis=1) + 1.0)
        total += float(np.sum(np.log(p) - np.log(marginal[h])))
    return total / max(T, 1)


def drifting_blocks(sym, heading, n_headings: int, n_ids: int,
                    blocks: int = FOLD_BLOCKS) -> int:
    """How many of ``blocks`` consecutive blocks of the steps agree better with the rest when
    their headings are turned (by the offset that makes their (symbol, heading) pairs likeliest
    under the other blocks' counts, smoothed as in :func:`heldout_gain`): 0 for a heading that
    keeps its origin, more where turns that failed moved it."""
    sym, heading = np.asarray(sym), np.asarray(heading)
    block = np.arange(sym.size) * blocks // max(sym.size, 1)
    moved = 0
    for b in range(blocks):
        rest, own = block != b, block == b
        counts = np.zeros((n_ids, n_headings))
        np.add.at(counts, (sym[rest], heading[rest]), 1.0)
        marginal = (counts.sum(axis=0) + 1.0) / (rest.sum() + n_headings)
        s, total = sym[own], counts[sym[own]].sum(axis=1) + 1.0
        score = [np.log((counts[s, h] + marginal[h]) / total).sum()
                 for h in ((heading[own] + o) % n_headings for o in range(n_headings))]
        moved += int(np.argmax(score) != 0)
    return moved


def inverse_pairs(sym, u, lengths, orders) -> list[tuple[int, int]]:
    """The pairs ``(a, b)`` of two different turns (``orders``) of which ``a`` then ``b`` brings
    back the view it left, judged as an action's order is (:data:`MIN_AGREEMENT` beyond chance
    on at least :data:`MIN_WINDOWS` windows): ``b`` undoes ``a``."""
    sym, u = np.asarray(sym), np.asarray(u)
    episode = _episodes(sym.size, lengths)
    n_all, chance = _agreement(sym, episode, 2)
    pairs = []
    for a, b in itertools.permutations([a for a, k in enumerate(orders) if k], 2):
        windows = (u[:-2] == a) & (u[1:-1] == b) if sym.size > 2 else np.zeros(0, bool)
        n, share = _agreement(sym, episode, 2, windows)
        if n >= MIN_WINDOWS and chance < 1 and (share - chance) / (1 - chance) >= MIN_AGREEMENT:
            pairs.append((a, b))
    return pairs


def _hypotheses(orders, inverse=()) -> list[tuple[int, tuple]]:
    """``(n, steps)`` for every way the turns of ``orders`` may rotate a circle of
    ``n = lcm(orders)`` headings, one per renaming of the headings (module docstring), in which
    every pair of ``inverse`` turns rotates by opposite steps."""
    turns = [k for k in orders if k]
    n = math.lcm(*turns)
    units = [c for c in range(1, n) if math.gcd(c, n) == 1]
    options = [[j * n // k for j in range(1, k) if math.gcd(j, k) == 1] if k else [0]
               for k in orders]
    seen = []
    for steps in itertools.product(*options):
        if any((steps[a] + steps[b]) % n for a, b in inverse):
            continue
        canon = min(tuple(c * s % n for s in steps) for c in units)
        if canon not in seen:
            seen.append(canon)
    return [(n, steps) for steps in seen]


def learn_turns(sym, u, lengths, n_actions: int, mode: str = "auto") -> tuple:
    """``(turns, info)``: the :class:`Turns` the data support (None where no action turns or,
    with ``mode="auto"``, the best hypothesis's gain is below :data:`MIN_GAIN` or its heading
    drifts, :func:`drifting_blocks`), and what was measured: ``orders`` (each action's, 0: not
    a turn), ``gains`` (each hypothesis's), ``drifting_blocks`` and ``reason`` where none is
    used.  Judged on the first :data:`DECIDE_STEPS` steps."""
    sym, u = np.asarray(sym, dtype=np.int64), np.asarray(u, dtype=np.int64)
    lengths = np.asarray(lengths, dtype=np.int64)
    if sym.size > DECIDE_STEPS:
        ends = np.cumsum(lengths)
        k = int(np.searchsorted(ends, DECIDE_STEPS))
        lengths = np.append(lengths[:k], DECIDE_STEPS - (ends[k - 1] if k else 0))
        sym, u = sym[:DECIDE_STEPS], u[:DECIDE_STEPS]
    orders = turn_orders(sym, u, lengths, n_actions)
    info = {"orders": orders}
    if not any(orders):
        return None, dict(info, reason="no action returns the view when repeated")
    n_ids = int(sym.max()) + 1
    best = None
    gains = []
    info["inverse"] = [list(p) for p in inverse_pairs(sym, u, lengths, orders)]
    for n, steps in _hypotheses(orders, info["inverse"]) or _hypotheses(orders):
        h = _align(sym, integrate(u, lengths, steps, n), lengths, n, n_ids)
        gain = heldout_gain(sym, h, n, n_ids)
        gains.append({"n_headings": n, "steps": list(steps), "gain": gain})
        if best is None or gain > best.gain:
            best = Turns(n, steps, gain)
    info["gains"] = gains
    if mode == "auto" and best.gain < MIN_GAIN:
        return None, dict(info, reason=f"the symbols tell too little of the heading: "
                                       f"{best.gain:.4f} < {MIN_GAIN} nats per step")
    h = _align(sym, integrate(u, lengths, best.steps, best.n_headings), lengths,
               best.n_headings, n_ids)
    info["drifting_blocks"] = drifting_blocks(sym, h, best.n_headings, n_ids)
    if mode == "auto" and info["drifting_blocks"] > MAX_DRIFTING:
        return None, dict(info, reason=f"the heading drifts: {info['drifting_blocks']} of "
                                       f"{FOLD_BLOCKS} blocks of the walk agree better turned")
    return best, info


@dataclass(frozen=True)
class HeadedStates:
    """Phase 1's (symbol, heading) pairs: ``view[p]`` and ``pair_heading[p]`` of pair ``p``,
    ``heading`` (T,) every step's heading, ``n_symbols`` the K-means symbols.  Ids of the pairs'
    alphabet -- the symbol ids a refinement sees -- are the pairs ``0..P-1``, then the GDS ids
    (``P + g``); :meth:`emitted` gives back the K-means symbols (``n_symbols + g``)."""

    turns: Turns
    heading: np.ndarray
    view: np.ndarray
    pair_heading: np.ndarray
    n_symbols: int

    @property
    def n_pairs(self) -> int:
        return int(self.view.size)

    def emitted(self, ids) -> np.ndarray:
        """The K-means symbol (or ``n_symbols + g`` for GDS ``g``) of pair-alphabet ids."""
        ids = np.asarray(ids, dtype=np.int64)
        P = self.n_pairs
        return np.where(ids < P, self.view[np.minimum(ids, P - 1)], ids - P + self.n_symbols)

    def symbol_rows(self) -> np.ndarray:
        """(n_symbols,) a pair of every symbol (the first): the phase-1 state whose observation
        model, tied to the symbol, is the symbol's."""
        return np.searchsorted(self.view, np.arange(self.n_symbols))

    def observed(self, loglik) -> np.ndarray:
        """(T, P) log-densities of the pairs, from ``loglik`` (T, n_symbols) those of the first
        ``T`` steps under the symbols: each step's under its pair's symbol where the pair has the
        step's heading, -inf elsewhere (the heading is integrated, not read)."""
        out = np.asarray(loglik)[:, self.view]
        heading = self.heading[:out.shape[0]]
        return np.where(self.pair_heading[None, :] == heading[:, None], out, -np.inf)

    def record(self, action_names=None) -> dict:
        """What map.json keeps as ``info["heading"]``."""
        names = action_names or [str(a) for a in range(len(self.turns.steps))]
        return {"n_headings": int(self.turns.n_headings),
                "turns": {str(names[a]): int(s) for a, s in enumerate(self.turns.steps) if s},
                "gain": round(float(self.turns.gain), 6), "pairs": self.n_pairs}


def head_states(labels, ns: int, u, lengths, turns: Turns) -> tuple:
    """``(pair_labels, headed)``: every step's phase-1 state as its (symbol, heading) pair
    (``labels``: the symbols ``0..ns-1``, then GDS states ``ns + g``, which stay one state each
    and become ``P + g``) and the :class:`HeadedStates`.  Pairs are numbered by symbol, then
    heading."""
    labels = np.asarray(labels, dtype=np.int64)
    lengths = np.asarray(lengths, dtype=np.int64)
    n = turns.n_headings
    heading = _align(labels, integrate(u, lengths, turns.steps, n), lengths, n,
                     int(labels.max()) + 1)
    plain = labels < ns
    pairs, index = np.unique(labels[plain] * n + heading[plain], return_inverse=True)
    out = np.empty_like(labels)
    out[plain] = index.ravel()
    out[~plain] = labels[~plain] - ns + pairs.size
    return out, HeadedStates(turns, heading, pairs // n, pairs % n, int(ns))


def phase1_states(mode: str, labels, ns: int, data, told=None) -> tuple:
    """``(labels, ns, symbol, headed, info)``: phase 1's state of every step, the symbols, the
    symbol of every state before the GDS ones -- the (symbol, heading) pairs where ``mode`` and
    the data say so (:func:`learn_turns`; the symbols a turn loop links joined first,
    :func:`~topomap.core.phase1.loops.join_loop_views`; :func:`head_states`), else ``labels``
    and ``ns`` as they are and the symbols ``0..ns-1`` -- with the :class:`HeadedStates` (None:
    no heading) and what was decided (``used``, ``reason`` when not, the measurements).
    ``data``: the fit's ``u``, ``lengths``, ``n_actions``, ``gds`` and ``action_names``;
    ``told``: a told number of states, which the pairs and the GDS states must not pass."""
    plain = (labels, ns, np.arange(ns), None)
    if mode == "off":
        return (*plain, {"used": False, "reason": "heading='off'"})
    turns, info = learn_turns(labels, data.u, data.lengths, data.n_actions, mode)
    if turns is None:
        return (*plain, dict(info, used=False))
    joined_labels, joined_ns, joined = join_loop_views(labels, ns, data.u, data.lengths, turns)
    pair_labels, headed = head_states(joined_labels, joined_ns, data.u, data.lengths, turns)
    n_gds = int(np.unique(data.gds[data.gds >= 0]).size)
    if told is not None and headed.n_pairs + n_gds > told:
        return (*plain, dict(info, used=False, reason=f"{headed.n_pairs} (symbol, heading) "
                                                      f"pairs are more than the {told} states"))
    return pair_labels, joined_ns, headed.view, headed, dict(
        info, used=True, joined_views=joined, **headed.record(data.action_names))
