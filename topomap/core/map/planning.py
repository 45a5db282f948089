"""Planning on a map: the most probable path from a state to a goal, with networkx.

The planning graph has one arc ``x -> x'`` for every pair seen at least once, weighted by
``-log max_u P(x'|x,u)`` and labelled with that action; :func:`plan` runs Dijkstra on it.
:meth:`~topomap.core.map.model.TopologicalMap.plan` calls :func:`plan`.
"""

from __future__ import annotations

from weakref import WeakKeyDictionary

import numpy as np

__all__ = ["plan", "planning_graph"]

#: the planning graphs built so far: map -> {min_prob: graph}.  A map never changes and is
#: hashed by identity, so its graphs stay right; they go when the map goes.
_GRAPHS: WeakKeyDictionary = WeakKeyDictionary()


def plan(m, start: int, goal, min_prob: float = 0.0) -> list[int]:
    """Actions of the most probable path on the map ``m`` from state ``start`` to ``goal`` (a
    state or an iterable of states, e.g. the GDS states; the nearest one is taken).

    The path maximises the product of ``max_u P(x'|x,u)`` over its arcs (networkx's Dijkstra on
    ``-log P``); each step's action is the one that makes its arc most probable.  Arcs are those
    observed at least once with a probability above ``min_prob``.  Returns ``[]`` when ``start``
    is a goal; raises ValueError when no goal can be reached.
    """
    import networkx as nx

    goals = {int(goal)} if isinstance(goal, (int, np.integer)) else {int(x) for x in goal}
    for s in goals | {int(start)}:
        if not 0 <= s < m.n_states:
            raise ValueError(f"state {s} is not a state of this map (0..{m.n_states - 1})")
    if not goals:
        raise ValueError("goal must name at least one state")
    if int(start) in goals:
        return []
    graph = planning_graph(m, min_prob)
    try:
        _, path = nx.multi_source_dijkstra(graph.reverse(copy=False), goals, int(start))
    except nx.NetworkXNoPath:
        raise ValueError(f"no goal state of {sorted(goals)} can be reached from state {start} "
                         f"through arcs with P(x'|x,u) > {min_prob}") from None
    path = path[::-1]
    return [graph.edges[x, y]["action"] for x, y in zip(path[:-1], path[1:])]


def planning_graph(m, min_prob: float):
    """The arcs :func:`plan` may use on the map ``m``, weighted by ``-log max_u P(x'|x,u)``
    (kept in :data:`_GRAPHS` for the map's lifetime: its tables never change)."""
    import networkx as nx

    cache = _GRAPHS.setdefault(m, {})
    if min_prob not in cache:
        P = np.where(m.transition_counts > 0, m.transition_probs, 0.0)
        best = P.argmax(axis=1)  # (S, S'): the action of each arc
        prob = np.take_along_axis(P, best[:, None, :], axis=1)[:, 0, :]
        graph = nx.DiGraph()
        graph.add_nodes_from(range(m.n_states))
        for x, y in zip(*np.nonzero(prob > min_prob)):
            graph.add_edge(int(x), int(y), weight=float(-np.log(prob[x, y])),
                           action=int(best[x, y]))
        cache[min_prob] = graph
    return cache[min_prob]
