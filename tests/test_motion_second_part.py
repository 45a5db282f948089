"""The default check's second held-out part: where the last quarter cannot tell the maps apart
beyond its noise, the quarter before it is held out and decides; small cases counted by hand."""

import numpy as np
import pytest

from topomap import MapLearner
from topomap.core.motion import check as check_mod
from topomap.core.motion.check import part_before_last, undecided


def test_undecided_is_a_gap_within_two_standard_errors_either_way():
    assert undecided({"gap": -0.1, "se": 0.06})      # -1.7 standard errors
    assert undecided({"gap": 0.19, "se": 0.1})       # +1.9
    assert undecided({"gap": 0.0, "se": 0.1})
    assert undecided({"gap": -0.2, "se": 0.1})       # -2.0: the places stay, not decided
    assert not undecided({"gap": -0.3, "se": 0.1})   # -3: the view clusters already
    assert not undecided({"gap": 0.2, "se": 0.1})    # +2: the places by the bar
    assert not undecided({"gap": 0.3, "se": 0.1})


def test_the_part_before_last_is_the_quarter_before_the_held_out_one():
    assert part_before_last(18000, 0.25) == (9000, 13500)  # the last is 13500-18000
    assert part_before_last(8000, 0.25) == (4000, 6000)
    assert part_before_last(100, 0.25) == (50, 75)
    assert part_before_last(100, 0.6) == (0, 40)  # the last 60: no 60 steps before it


def _walk(T=8000, seed=0):
    """A walk on [0, 2] of moves 0.01 +- 30 %, turning at the ends and at random, action 0
    right, 1 left, its view the angle pi x on a circle."""
    rng = np.random.default_rng(seed)
    x, d, u = np.empty(T), 1, np.empty(T, dtype=np.int64)
    x[0] = 0.1
    for t in range(T):
        d = -d if rng.random() < 0.01 else d
        nxt = x[t] + d * 0.01 * rng.uniform(0.7, 1.3)
        if not 0.0 <= nxt <= 2.0:
            d, nxt = -d, x[t] + -d * 0.01
        u[t] = 0 if d > 0 else 1
        if t + 1 < T:
            x[t + 1] = nxt
    Z = np.stack([np.cos(np.pi * x), np.sin(np.pi * x)], 1)
    return Z + rng.normal(0, 0.01, Z.shape), u


@pytest.mark.parametrize("last, second, chosen, asked", [
    # the last quarter: views nearer by 1.5 standard errors -- undecided; the one before: by 3
    ({"gap": -0.15, "se": 0.1}, {"gap": -0.3, "se": 0.1}, "views", True),
    # undecided, and the one before favours the places: they stay
    ({"gap": -0.15, "se": 0.1}, {"gap": 0.3, "se": 0.1}, "places", True),
    # undecided, the one before within its noise too: the places stay
    ({"gap": 0.15, "se": 0.1}, {"gap": -0.15, "se": 0.1}, "places", True),
    # the last quarter decides either way: no second part
    ({"gap": 0.3, "se": 0.1}, {"gap": -0.5, "se": 0.1}, "places", False),
    ({"gap": -0.3, "se": 0.1}, {"gap": 0.5, "se": 0.1}, "views", False),
])
def test_a_second_part_decides_only_where_the_last_cannot(monkeypatch, last, second, chosen,
                                                          asked):
    spans = []

    def figures(*args, span=None, **kw):  # the check's figures, per part held out
        spans.append(span)
        return dict(second if span is not None else last, learned=6000, held_out=2000,
                    places=1.0, views=1.0)

    monkeypatch.setattr(check_mod, "cross_fitted", figures)
    Z, u = _walk()  # no quarter of it is new ground: the coverage rule holds out the last
    learner = MapLearner(n_clusters=4, n_states=8, random_state=0).fit(Z, u)
    check = learner.motion_info_["check"]
    assert learner.motion_info_["chosen"] == chosen and check["rule"] == "coverage"
    assert spans == ([None, (4000, 6000)] if asked else [None])
    assert ("second" in check) == asked
    if asked:
        assert check["second"]["span"] == [4000, 6000]
    if asked and chosen == "views":  # the reason names the part that decided
        assert "steps 4000-6000" in learner.motion_info_["reason"]
