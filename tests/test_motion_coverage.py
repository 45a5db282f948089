"""The coverage check: a part of a continuous log in places the rest of it seldom visits, held
out beside the last quarter; small cases whose answer is counted by hand."""

import numpy as np
import pytest

from topomap import MapLearner
from topomap.core.motion import MotionSettings
from topomap.core.motion.coverage import novel_span, novelty
from topomap.core.motion.crossfit import split_span


def test_novelty_counts_the_steps_in_places_the_rest_seldom_visits():
    # place 0 only in the first half, place 1 in both, place 2 nine steps in, one out
    places = np.array([0, 0, 0, 0, 1, 1, 2, 2, 2, 2, 2, 2, 2, 2, 2,   # steps 0-14
                       1, 1, 1, 2, 3, 3, 3, 3, 3, 3])                 # steps 15-24
    # 0:15 holds 4 steps of place 0 (all its steps), 2 of place 1 (2 of 5), 9 of place 2 (9
    # of 10: one outside, a tenth -- at RARE 0.1 still new): 13 of 15 steps in new places
    assert novelty(places, 0, 15) == pytest.approx(13 / 15)
    assert novelty(places, 0, 15, rare=0.05) == pytest.approx(4 / 15)
    # 15:25: place 3 (6 of 6) new; place 1 (3 of 5 inside) and place 2 (1 of 10) not
    assert novelty(places, 15, 25) == pytest.approx(6 / 10)


def test_the_novel_span_is_the_most_novel_part_but_the_last():
    places = np.repeat([0, 1, 2, 2, 3, 3, 1, 1], 10)  # four quarters of 20 steps
    # quarter 0: place 0 new (10 steps), place 1 has 10 of its 30 steps there: 0.5
    # quarter 1: place 2, all its steps: 1.0; quarter 2: place 3 alone: 1.0 (a tie: the earlier)
    assert novelty(places, 0, 20) == pytest.approx(0.5)
    assert novel_span(places, 0.25) == (20, 40)
    assert novel_span(places, 0.25, share=1.01) is None
    # the last quarter is held out already: never named, however new its ground
    last_new = np.repeat([0, 0, 0, 1], 20)
    assert novel_span(last_new, 0.25) is None


def test_a_span_splits_the_episodes_it_cuts_through():
    learned, held = split_span([10, 30, 20], 25, 45)
    np.testing.assert_array_equal(learned, [10, 15, 15])  # 0:10, 10:25 | 45:60
    np.testing.assert_array_equal(held, [15, 5])         # 25:40, 40:45
    learned, held = split_span([60], 0, 15)
    np.testing.assert_array_equal(learned, [45])
    np.testing.assert_array_equal(held, [15])


def _line(T=8000, seed=0, period=1.0, first=0):
    """A walk on [0, 2] (its first ``first`` steps on [2, 3], a stretch of the line the rest
    never comes back to: it then walks left into [0, 2]), views repeating every ``period``,
    action 0 right, 1 left."""
    rng = np.random.default_rng(seed)
    x, d = np.empty(T), 1
    x[0] = 2.1 if first else 0.1
    u = np.empty(T, dtype=np.int64)
    for t in range(T):
        lo, hi = (2.0, 3.0) if t < first else (0.0, 2.0)
        leaving = t >= first and x[t] > hi
        if leaving:
            d = -1
        elif rng.random() < 0.01:
            d = -d
        nxt = x[t] + d * 0.01 * rng.uniform(0.9, 1.1)
        if not leaving and not lo <= nxt <= hi:
            d = -d
            nxt = x[t] + d * 0.01
        u[t] = 0 if d > 0 else 1
        if t + 1 < T:
            x[t + 1] = nxt
    Z = np.stack([np.cos(2 * np.pi * x / period), np.sin(2 * np.pi * x / period)], 1)
    return Z + rng.normal(0, 0.01, Z.shape), u, x


def test_the_held_out_span_of_the_last_quarter_is_the_default_fold():
    from topomap.core.motion.check import _cut
    from topomap.core.motion.crossfit import cross_fitted
    from topomap.core.motion.learn import pooled_variances
    from topomap.core.map.model import TopologicalMap

    Z, u, _ = _line()
    st = MotionSettings()

    def build(X, u, labels, lengths, pooled=False):
        S = int(labels.max()) + 1
        m = TopologicalMap.from_labels(X, u, labels, lengths=lengths,
                                       state_symbol=np.arange(S), state_gds=np.full(S, -1),
                                       state_parent=np.full(S, -1), n_actions=2)
        return pooled_variances(m, X, labels, 1e-6, 0.01) if pooled else m

    whole, info, _ = _cut(st, Z, u, [len(u)], 8, 2, n_init=1, random_state=0)
    kw = dict(n_init=1, random_state=0, weight=info["weight"])
    last = cross_fitted(st, Z, Z, u, [len(u)], 8, 2, build, starts=1, **kw)
    span = cross_fitted(st, Z, Z, u, [len(u)], 8, 2, build, starts=1, span=(6000, 8000), **kw)
    assert last == span and last["learned"] == 6000
    first = cross_fitted(st, Z, Z, u, [len(u)], 8, 2, build, starts=1, span=(0, 2000), **kw)
    assert (first["learned"], first["held_out"]) == (6000, 2000) and first != last


def test_the_coverage_rule_checks_a_part_only_where_one_is_new_ground():
    Z, u, x = _line()  # the walk covers the line again and again: no quarter is new ground
    learner = MapLearner(n_clusters=4, n_states=8, random_state=0,
                         motion={"check": {"rule": "coverage"}}).fit(Z, u)
    check = learner.motion_info_["check"]
    assert learner.motion_info_["chosen"] == "places" and check["rule"] == "coverage"
    assert "span" not in check
    # the first quarter on [2, 3], alike in view to [0, 1] and [1, 2], the rest never there:
    # the last quarter keeps the places (bootstrap), the first, held out, gives them up
    Z, u, x = _line(first=2000)
    assert x[:2000].min() >= 2.0 - 0.02 and x[2200:].max() <= 2.0
    kw = dict(n_clusters=4, n_states=8, random_state=0)
    kept = MapLearner(**kw, motion={"check": {"rule": "bootstrap"}}).fit(Z, u)
    assert kept.motion_info_["chosen"] == "places" and "span" not in kept.motion_info_["check"]
    with pytest.warns(UserWarning, match="steps 0-2000 of the log"):
        learner = MapLearner(**kw, motion={"check": {"rule": "coverage"}}).fit(Z, u)
    check = learner.motion_info_["check"]
    assert check["span"] == [0, 2000] and check["held_out"] == 2000 and check["gap"] < 0
    assert learner.motion_info_["chosen"] == "views"
