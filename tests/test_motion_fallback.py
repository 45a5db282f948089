"""A continuous log whose places give way to the view clusters says so: a warning naming why,
and ``motion_info_["reason"]``."""

import warnings

import numpy as np
import pytest

from topomap import MapLearner
from topomap.core.motion.learn import ContinuousFallbackWarning, fallback_reason


def _line(T=8000, seed=0, period=1.0):
    """A walk on [0, 2] turning at the ends and at random; action 0 moves right, 1 left; the
    view of x repeats with ``period`` (1: the two halves look alike; 2: every view differs)."""
    rng = np.random.default_rng(seed)
    x, d = np.empty(T), 1
    x[0] = 0.1
    u = np.empty(T, dtype=np.int64)
    for t in range(T):
        if rng.random() < 0.01:
            d = -d
        nxt = x[t] + d * 0.01 * rng.uniform(0.7, 1.3)
        if not 0.0 <= nxt <= 2.0:
            d = -d
            nxt = x[t] + d * 0.01
        u[t] = 0 if d > 0 else 1
        if t + 1 < T:
            x[t + 1] = nxt
    phase = 2 * np.pi * x / period
    Z = np.stack([np.cos(phase), np.sin(phase)], 1)
    return Z + rng.normal(0, 0.01, Z.shape), u


def test_places_kept_say_nothing():
    Z, u = _line(period=1.0)
    with warnings.catch_warnings():
        warnings.simplefilter("error", ContinuousFallbackWarning)
        learner = MapLearner(n_clusters=4, n_states=8, random_state=0).fit(Z, u)
    assert learner.motion_info_["chosen"] == "places" and "reason" not in learner.motion_info_


def test_the_check_that_prefers_the_view_clusters_is_named_with_its_shares():
    Z, u = _line(period=2.0)  # every view at one place: positions add nothing
    with pytest.warns(ContinuousFallbackWarning, match="held-out check") as caught:
        learner = MapLearner(n_clusters=16, n_states=32, random_state=0,
                             motion={"check": {"rule": "folds"}}).fit(Z, u)
    info = learner.motion_info_
    assert info["chosen"] == "views"
    shares = info["check"]["mean_misplaced"]
    assert f"{shares['places']:.3f}" in info["reason"] and f"{shares['views']:.3f}" in info["reason"]
    assert info["reason"] in str(caught[0].message)


def test_commands_that_learn_no_odometry_are_named():
    Z, u = _line(period=1.0)
    unrelated = np.random.default_rng(1).integers(0, 4, u.size)  # commands apart from the moves
    with pytest.warns(ContinuousFallbackWarning, match="no odometry could be learned"):
        learner = MapLearner(n_clusters=4, n_states=8, random_state=0).fit(Z, unrelated)
    assert learner.motion_info_["odometry"] is False
    assert learner.motion_info_["reason"].startswith("no odometry could be learned")


def test_fallback_reason_of_a_check_given_as_words_is_those_words():
    assert fallback_reason({"chosen": "views", "odometry": True,
                            "check": "the places cut across the view clusters"}) == \
        "the places cut across the view clusters"
    assert fallback_reason({"chosen": "places"}) is None


def test_a_run_reports_why_its_map_is_the_view_clusters():
    """The command's summary line and metrics.json's ``motion`` carry the learner's reason."""
    from topomap.app.cli import _summary
    from topomap.app.run.experiment import _motion

    Z, u = _line(period=1.0)
    unrelated = np.random.default_rng(1).integers(0, 4, u.size)
    with pytest.warns(ContinuousFallbackWarning):
        fell_back = MapLearner(n_clusters=4, n_states=8, random_state=0).fit(Z, unrelated)
    motion = _motion(fell_back)
    assert motion == {"chosen": "views", "reason": fell_back.motion_info_["reason"]}
    line = _summary({"n_states": {"final": 8}, "motion": motion}, None)
    assert line.endswith(f"the map is the view clusters, not places: {motion['reason']}")
    kept = MapLearner(n_clusters=4, n_states=8, random_state=0).fit(Z, u)
    assert _motion(kept) == {"chosen": "places", "reason": None}
    assert "view clusters" not in _summary({"n_states": {"final": 8}, "motion": _motion(kept)}, None)
    assert _motion(MapLearner(n_clusters=2, n_states=3).fit(Z[::50], u[::50])) is None
