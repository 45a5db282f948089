"""The duplicates of a place that the greedy pass of ``bisimilar_blocks`` leaves apart, merged by
``merge_leftovers`` -- on a walk built by hand, whose answer is known."""

import numpy as np

from topomap.core.refine.structure import merge_leftovers, merge_states

# states (symbol): Z (8) enters P; P (0) -a0-> I (7), -a1-> E (2) -a0-> F (4); A1 (0) -a0-> H (6),
# -a1-> C (2) -a0-> G (5); B1 (1) -a0-> A1; the duplicates B2 (1) -a0-> A2 (0) -a1-> C, seen 3 times
Z, P, I, E, F, A1, H, C, G, B1, A2, B2 = range(12)
SYMBOL = np.array([8, 0, 7, 2, 4, 0, 6, 2, 5, 1, 0, 1])
WALKS = ([[(Z, 0), (P, 0), (I, 0)]] * 15 + [[(Z, 0), (P, 1), (E, 0), (F, 0)]] * 15
         + [[(A1, 0), (H, 0)]] * 15 + [[(A1, 1), (C, 0), (G, 0)]] * 15
         + [[(B1, 0), (A1, 1), (C, 0), (G, 0)]] * 10 + [[(B2, 0), (A2, 1), (C, 0), (G, 0)]] * 3)


def _steps():
    labels = np.array([s for walk in WALKS for s, _ in walk])
    u = np.array([a for walk in WALKS for _, a in walk])
    has_next = np.concatenate([[True] * (len(walk) - 1) + [False] for walk in WALKS])
    return labels, u, has_next


def _together(labels, merged, a, b) -> bool:
    return merged[np.flatnonzero(labels == a)[0]] == merged[np.flatnonzero(labels == b)[0]]


def test_merge_states_leaves_the_duplicates_apart():
    # first pass: A2, seen under a1 only, joins P's group (a1 leads to symbol 2 from both); the
    # second splits it off (E and C differ), and B2 from B1 (A2 and A1 now differ): nothing merged
    labels, u, has_next = _steps()
    merged, symbol = merge_states(labels, SYMBOL, u, has_next, 6.63)
    assert symbol.size == 12


def test_merge_leftovers_merges_the_chain_of_duplicates():
    # A2 agrees with A1 (a1 leads to C from both; a0, never taken, is missing by chance in 3
    # visits), so it merges; B2 then agrees with B1 (a0 leads to the merged A); P stays apart
    labels, u, has_next = _steps()
    merged, symbol = merge_leftovers(labels, SYMBOL, u, has_next, 6.63)
    assert symbol.size == 10
    assert _together(labels, merged, A1, A2) and _together(labels, merged, B1, B2)
    assert not _together(labels, merged, P, A1) and not _together(labels, merged, E, C)
    assert sorted(symbol.tolist()) == sorted(np.delete(SYMBOL, [A2, B2]).tolist())
