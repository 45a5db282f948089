"""The figures say what the map is: the map that replaced the split named as such, the arcs of a
map whose steps mostly stay in their state drawn as the moves between states, self-loops in the
legend, the explorer named as the run chose it."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from topomap import TopologicalMap
from topomap.app.plots.common import MIN_LEAVING_SHARE, STAYING, map_arcs
from topomap.app.plots.curves import plot_entropy, plot_mapping
from topomap.app.plots.run import final_stage
from topomap.app.plots.style import pyplot


def _map(labels, n_actions=1):
    labels = np.asarray(labels)
    S = int(labels.max()) + 1
    X = np.random.default_rng(0).normal(size=(labels.size, 2)) + labels[:, None]
    return TopologicalMap.from_labels(X, np.zeros(labels.size, dtype=int), labels,
                                      state_symbol=np.arange(S), state_gds=np.full(S, -1),
                                      state_parent=np.full(S, -1), n_actions=n_actions)


def test_a_map_that_mostly_stays_draws_the_moves_between_its_states():
    """0 x10, 1 x10, 0 x10, 2 x10, 0 x10: 45 of the 49 moves stay (92 %); the 4 moves between
    states are 0->1, 1->0, 0->2, 2->0: state 0 leaves to 1 and 2 half the time each."""
    arcs = map_arcs(_map([0] * 10 + [1] * 10 + [0] * 10 + [2] * 10 + [0] * 10), 0.8)
    assert STAYING == 0.5 and MIN_LEAVING_SHARE == 0.1
    assert arcs.staying == pytest.approx(45 / 49)
    assert sorted(arcs.between) == [(0, 1), (0, 2), (1, 0), (2, 0)] and arcs.loops == []
    assert arcs.title(3) == ("3 states, 4 arcs where >= 10% of the moves out of a state go "
                             "(steps stay in their state 92% of the time)")


def test_a_map_that_moves_every_step_draws_its_likely_transitions_and_loops():
    """0 1 2 0 1 2 ... and a final 2 2: every transition is certain but 2 -> (0 or 2)."""
    arcs = map_arcs(_map([0, 1, 2] * 10 + [2, 2]), 0.8)
    assert arcs.staying < 0.5
    assert sorted(arcs.between) == [(0, 1), (1, 2), (2, 0)]
    assert arcs.title(3) == "3 states, 3 arcs with P(x'|x,u) > 0.8"
    # 0 1 2 3 4, then 5 six times: 5 of the 11 moves stay, P(5 -> 5) = 5/6 > 0.8
    loops = map_arcs(_map(([0, 1, 2, 3, 4] + [5] * 6) * 4), 0.8)
    assert loops.staying == pytest.approx(20 / 43) and loops.loops == [5]
    assert loops.title(6) == "6 states, 5 arcs and 1 self-loop with P(x'|x,u) > 0.8"


@pytest.mark.parametrize("info, said", [
    ({"chosen": "places"}, "the places (views and motion), in place of the split"),
    ({"chosen": "views"}, "the view clusters, in place of the split (the places lost the check)"),
    (None, "after the refinement"),
])
def test_the_map_that_replaced_the_split_is_named(info, said):
    assert final_stage(SimpleNamespace(motion_info_=info)) == said


def test_the_places_are_drawn_apart_from_the_split_in_the_entropy_figure():
    """32 -> 64 states by splits, then the places at 64: the places' point is right of the
    split's last, past a dashed line, and named."""
    entries = [dict(n_states=n, H_u=1.0, H_x=2.0 - n / 100) for n in range(32, 65)]
    entries.append(dict(n_states=64, H_u=1.5, H_x=0.5, stage="places"))
    learner = SimpleNamespace(entropies_=entries, motion_info_={"chosen": "places"})
    fig, ax = pyplot().subplots()
    plot_entropy(ax, learner)
    split_x = ax.lines[0].get_xdata()
    assert list(split_x) == list(range(32, 65))  # the places' point is not on the split's line
    places_x = [line.get_xdata()[0] for line in ax.lines[4:7]]
    assert min(places_x) > 64
    labels = ax.get_legend_handles_labels()[1]
    assert "the places (views and motion), in place of the split (64 states)" in labels
    assert ax.get_title() == "entropies after each split, then the places (views and motion)"


def test_the_mapping_figure_names_the_explorer_as_the_run_chose_it():
    fig, ax = pyplot().subplots()
    curve = [{"steps": 250, "ari": 0.1, "heldout_ari": 0.1}]
    plot_mapping(ax, curve, "explorer=active")
    assert ax.get_title() == "mapping while exploring: explorer=active"
    plot_mapping(ax, curve, "HistoryExplorer(update_every=250)")
    assert ax.get_title() == "mapping while exploring: HistoryExplorer"


def test_states_scattered_over_the_floor_are_drawn_at_a_graph_layout():
    """101 steps along a 1 m line.  Four states, one per quarter: each lies 1/16 m from its mean
    in the median, 0.06 of the extent's diagonal, below SCATTERED = 0.1: nodes at their means.
    Two states taking turns: each spreads over the whole line, 1/4 m from its mean (0.25):
    nodes at a layout of the graph, and the title says why."""
    from topomap.app.plots.common import SCATTERED, node_positions, scatter_of_states

    x = np.linspace(0, 1, 101)
    P = np.column_stack([x, np.zeros_like(x)])
    quarters = np.minimum((x * 4).astype(int), 3)
    turns = np.arange(101) % 2
    assert SCATTERED == 0.1
    means, how = node_positions(_map(quarters), quarters, P)
    assert how == "mean position"
    assert scatter_of_states(quarters, P, means) == pytest.approx(1 / 16, abs=0.01)
    _, how = node_positions(_map(turns), turns, P)
    assert how.startswith("graph layout: the states' steps scatter over the floor (2")
    _, how = node_positions(_map(turns), turns, P, places=turns)  # discrete places: means
    assert how == "mean position"
