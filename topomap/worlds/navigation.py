"""Using a learned map to find the way: localise, plan, act in the world, re-plan.

A world's *place graph* (:class:`PlaceGraph`) is its true topology: the place each action leads
to from each place, and what the robot sees at each place.  :class:`Navigation` runs episodes in
it with a learned :class:`~topomap.TopologicalMap`: the robot starts at a random place, walks a
few random steps to localise (forward filtering, :meth:`TopologicalMap.step_belief`), is given a
random goal place, and then at every step plans on the map from its most probable state
(:meth:`TopologicalMap.plan`), takes the plan's first action in the world, sees the result and
re-localises, until it stands at the goal or runs out of steps.  Success rate and path length
against the world's true shortest path measure how usable the map is.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import numpy as np

from ..core.checks import ParameterError, check_count
from ..core.map.model import TopologicalMap

__all__ = ["PlaceGraph", "place_graph", "largest_component", "explored_graph", "state_places",
           "Navigation"]


@dataclass
class PlaceGraph:
    """A world's true topology.

    Attributes
    ----------
    successors : (n_ids, A) int -- the place action ``a`` leads to from place ``p`` (-1: ``a`` is
        not executable there)
    observations : (n_ids, D) float -- the noise-free observation at each place
    gds : (n_ids,) int -- the GDS recognised at each place (-1: none)
    places : (P,) int -- the ids that are places (all others are unused rows)
    """

    successors: np.ndarray
    observations: np.ndarray
    gds: np.ndarray
    places: np.ndarray

    def distances_to(self, goal: int) -> np.ndarray:
        """Fewest actions from every place id to ``goal`` (-1: unreachable), by breadth-first
        search over the reversed graph."""
        n = self.successors.shape[0]
        dist = np.full(n, -1, dtype=np.int64)
        sources, _ = np.nonzero(self.successors >= 0)
        into = [[] for _ in range(n)]
        for p, q in zip(sources.tolist(), self.successors[self.successors >= 0].tolist()):
            into[q].append(p)
        dist[goal] = 0
        todo = deque([goal])
        while todo:
            q = todo.popleft()
            for p in into[q]:
                if dist[p] < 0:
                    dist[p] = dist[q] + 1
                    todo.append(p)
        return dist


def place_graph(world) -> PlaceGraph:
    """The :class:`PlaceGraph` of a world (``world.place_graph()``), or a ValueError naming the
    world when it has none."""
    build = getattr(world, "place_graph", None)
    if build is None:
        raise ValueError(f"navigation needs a world with a place graph; {type(world).__name__} "
                         "has none")
    return build()


def largest_component(successors, ids) -> np.ndarray:
    """The ids of the largest strongly connected part of the graph: the places a robot can go
    between in both directions (navigation starts and goals are drawn from them)."""
    import networkx as nx

    graph = nx.DiGraph()
    graph.add_nodes_from(ids)
    for p in ids:
        graph.add_edges_from((p, int(q)) for q in successors[p] if q >= 0)
    best = max(nx.strongly_connected_components(graph), key=lambda c: (len(c), -min(c)))
    return np.array(sorted(best), dtype=np.int64)


def explored_graph(n_ids: int, n_actions: int, start, step, observe, gds) -> PlaceGraph:
    """A place graph found by breadth-first search from the place ids ``start``:
    ``step(p) -> [next place id or -1 per action]``, ``observe(p)``, ``gds(p)``."""
    succ = np.full((n_ids, n_actions), -1, dtype=np.int64)
    seen, todo = set(start), deque(start)
    obs, marks = {}, {}
    while todo:
        p = todo.popleft()
        succ[p] = step(p)
        obs[p], marks[p] = observe(p), gds(p)
        for q in succ[p][succ[p] >= 0].tolist():
            if q not in seen:
                seen.add(q)
                todo.append(q)
    places = largest_component(succ, sorted(seen))
    first = obs[int(places[0])]
    observations = np.zeros((n_ids, first.size))
    gds_of = np.full(n_ids, -1, dtype=np.int64)
    for q in places.tolist():
        observations[q], gds_of[q] = obs[q], marks[q]
    return PlaceGraph(succ, observations, gds_of, places)


def state_places(labels, places, n_states: int) -> np.ndarray:
    """The place each map state stands for: the most frequent true place of its steps (-1 for a
    state without steps)."""
    labels, places = np.asarray(labels), np.asarray(places)
    out = np.full(n_states, -1, dtype=np.int64)
    table = {}
    for s, p in zip(labels.tolist(), places.tolist()):
        table.setdefault(s, {}).setdefault(p, 0)
        table[s][p] += 1
    for s, counts in table.items():
        out[s] = max(sorted(counts), key=counts.get)
    return out


@dataclass
class _Episode:
    success: bool
    steps: int
    shortest: int
    goal_in_map: bool


class Navigation:
    """Measure navigation on a learned map in the world it was learned in.

    Parameters
    ----------
    episodes : int
        Navigation episodes (start and goal drawn at random).
    localise_steps : int
        Random steps the robot walks first, to localise, before it is given its goal.
    step_factor : float
        Step limit of an episode: ``step_factor * shortest + 10`` actions.
    seed : int
        Seeds the starts, goals, random steps and sensor noise of the episodes.
    """

    def __init__(self, episodes: int = 100, localise_steps: int = 10, step_factor: float = 3.0,
                 seed: int = 0):
        self.episodes = check_count(episodes, "episodes")
        self.localise_steps = check_count(localise_steps, "localise_steps", minimum=0)
        if not step_factor >= 1:
            raise ParameterError("step_factor", f"must be >= 1, got {step_factor!r}")
        self.step_factor, self.seed = float(step_factor), int(seed)

    def evaluate(self, m: TopologicalMap, labels, places, world, noise=None) -> dict:
        """Run the episodes; returns success rate, mean path length over successes, mean ratio
        of path length to the true shortest path, and the counts."""
        graph = place_graph(world)
        where = state_places(labels, places, m.n_states)
        rng = np.random.default_rng(self.seed)
        runs = [self._episode(m, graph, where, noise, rng) for _ in range(self.episodes)]
        won = [r for r in runs if r.success]
        return {
            "episodes": len(runs), "success_rate": len(won) / max(len(runs), 1),
            "mean_steps": float(np.mean([r.steps for r in won])) if won else None,
            "mean_shortest": float(np.mean([r.shortest for r in won])) if won else None,
            "path_ratio": float(np.mean([r.steps / r.shortest for r in won])) if won else None,
            "goals_missing_from_map": sum(not r.goal_in_map for r in runs),
        }

    def _episode(self, m, graph: PlaceGraph, where, noise, rng) -> _Episode:
        p = int(rng.choice(graph.places))
        belief = m.step_belief(None, 0, self._see(graph, p, noise, rng), int(graph.gds[p]))
        for _ in range(self.localise_steps):
            a = int(rng.choice(np.flatnonzero(graph.successors[p] >= 0)))
            p, belief = self._act(m, graph, p, a, belief, noise, rng)
        goal, dist = self._goal(graph, p, rng)
        goal_states = np.flatnonzero(where == goal)
        limit = int(self.step_factor * dist[p] + 10)
        shortest, steps = int(dist[p]), 0
        while p != goal and steps < limit and goal_states.size:
            a = self._choose(m, graph, p, belief, goal_states, rng)
            p, belief = self._act(m, graph, p, a, belief, noise, rng)
            steps += 1
        return _Episode(p == goal, steps, shortest, bool(goal_states.size))

    @staticmethod
    def _goal(graph: PlaceGraph, p: int, rng):
        """A random goal other than ``p`` that can be reached from it, and the distances to it."""
        for _ in range(1000):
            goal = int(rng.choice(graph.places))
            dist = graph.distances_to(goal)
            if goal != p and dist[p] > 0:
                return goal, dist
        raise ValueError("no place can be reached from the robot's place; is the world connected?")

    @staticmethod
    def _see(graph: PlaceGraph, p: int, noise, rng) -> np.ndarray:
        o = graph.observations[p][None]
        return (o if noise is None else noise.apply(o, rng))[0]

    def _act(self, m, graph, p, a, belief, noise, rng):
        q = int(graph.successors[p, a])
        return q, m.step_belief(belief, a, self._see(graph, q, noise, rng), int(graph.gds[q]))

    @staticmethod
    def _choose(m, graph: PlaceGraph, p: int, belief, goal_states, rng) -> int:
        """The first action of the plan from the most probable state; a random executable action
        when that is not executable here or no goal state can be reached on the map."""
        executable = np.flatnonzero(graph.successors[p] >= 0)
        try:
            plan = m.plan(int(np.argmax(belief)), goal_states)
        except ValueError:
            plan = []
        if plan and plan[0] in executable:
            return int(plan[0])
        return int(rng.choice(executable))

    def __repr__(self) -> str:
        return (f"Navigation(episodes={self.episodes}, localise_steps={self.localise_steps}, "
                f"step_factor={self.step_factor}, seed={self.seed})")
