"""partial_fit when views still appear: the cluster count capped at the window's views and grown
as new views appear (topomap.core.online_codebook)."""

import warnings

import numpy as np
import pytest
from sklearn.metrics import adjusted_rand_score

from topomap import MapLearner
from topomap.core.online_codebook import Codebook


def corridor(cells):
    """A corridor of 8 cells, each showing a view of its own (a one-hot row): the steps of the
    walk through ``cells``, with action 0 for a step right and 1 for a step left."""
    cells = np.asarray(cells)
    u = np.where(np.diff(cells, append=cells[-1]) < 0, 1, 0)
    return np.eye(8)[cells], u


#: back and forth over cells 0-3 (views 0-3 only), then to the end of the corridor and back
FIRST = [0, 1, 2, 3, 2, 1] * 3 + [0, 1]          # 20 steps
LATER = [2, 3, 4, 5, 6, 7, 6, 5, 4, 3, 2, 1, 0, 1, 2, 3, 4, 5, 6, 7]  # 20 steps


def test_codebook_gives_new_views_symbols_by_first_appearance_up_to_the_count_asked():
    # two views known (symbols 0, 1), four asked for: two more may come; -0.0 is the view 0.0
    known = np.array([[0.0, 0.0], [1.0, 0.0]])
    book = Codebook.from_symbols(known, np.array([0, 1]), 2, limit=4)
    rows = np.array([[5.0, 5.0], [-0.0, 0.0], [3.0, 3.0], [5.0, 5.0], [3.4, 3.4], [9.0, 9.0]])
    sym, grown = book.assign(rows)
    # (5,5) first: symbol 2; (3,3): 3; then the count asked is reached: (3.4,3.4) and (9,9)
    # take their nearest means, (3,3) and (5,5)
    assert sym.tolist() == [2, 0, 3, 2, 3, 2]
    assert grown.size == 4 and book.size == 2  # the codebook before is left as it was
    np.testing.assert_array_equal(grown.means[2:], [[5.0, 5.0], [3.0, 3.0]])
    # nothing capped: every row takes its nearest mean, nothing grows
    plain = Codebook.from_symbols(known, np.array([0, 1]), 2)
    assert plain.views is None and plain.assign(rows)[1] is plain


def test_a_count_above_the_windows_views_is_capped_then_grown_as_views_appear():
    X, u = corridor(FIRST + LATER)
    learner = MapLearner(8, 8, window=16, refit_every=1000)
    with pytest.warns(UserWarning, match="n_clusters=8 is more than the 4 distinct observations"):
        learner.partial_fit(X[:20], u[:20], n_actions=2)  # its window: the last 16 steps
    assert learner.n_clusters_ == 4 and set(learner.map_.state_symbol) == {0, 1, 2, 3}
    assert learner.online_["clusters"] == {"asked": 8, "window": 4, "symbols": 4}
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # said once
        learner.partial_fit(X[20:], u[20:])
    # the four new views got symbols 4-7 in the order they appeared; the pass (20 new steps,
    # its window every view) learned a state for each: every step is in the state of its cell
    assert learner.online_["clusters"] == {"asked": 8, "window": 4, "symbols": 8}
    np.testing.assert_array_equal(learner._online.codebook.means[4:], np.eye(8)[4:])
    assert learner.online_["n_passes"] == 2 and learner.map_.n_states == 8
    assert adjusted_rand_score(FIRST + LATER, learner.labels_) == 1.0


def test_growth_stops_at_the_count_asked():
    # 6 asked: views 4 and 5 get symbols of their own, views 6 and 7 the nearest mean's
    X, u = corridor(FIRST + LATER)
    learner = MapLearner(6, 8, window=16, refit_every=1000)
    with pytest.warns(UserWarning, match="up to 6"):
        learner.partial_fit(X[:20], u[:20], n_actions=2)
    learner.partial_fit(X[20:], u[20:])
    assert learner.online_["clusters"]["symbols"] == 6
    assert learner._online.record.sym.max() == 5


def test_a_new_view_waits_for_the_next_pass():
    # the window holds every step (K-means runs at every pass, the count capped each time);
    # 5 steps after the pass at 20 bring views 4-6: no pass is due (20 new steps), so their
    # steps are labelled -1 until the next one, which learns them
    X, u = corridor(FIRST + LATER)
    learner = MapLearner(8, 8, window=100, refit_every=1000)
    with pytest.warns(UserWarning):
        learner.partial_fit(X[:20], u[:20], n_actions=2)
    learner.partial_fit(X[20:25], u[20:25])
    assert learner.online_["n_passes"] == 1
    assert learner.labels_[20:25].tolist() == [learner.labels_[2], learner.labels_[3], -1, -1, -1]
    learner.partial_fit(X[25:], u[25:])
    assert learner.online_["n_passes"] == 2 and learner.n_clusters_ == 8
    assert adjusted_rand_score(FIRST + LATER, learner.labels_) == 1.0


def test_the_gds_states_are_found_after_the_symbols_grew():
    # cell 0 is a GDS (id 5): its id comes after the symbols, so it moves up when they grow;
    # the steps at cell 0 after the growth are decoded to the GDS state
    cells = FIRST + [2, 3, 4, 5, 6] + [5, 4, 3, 2, 1, 0, 1, 2]
    X, u = corridor(cells)
    gds = np.where(np.asarray(cells) == 0, 5, -1)
    learner = MapLearner(7, 8, window=100, refit_every=1000)
    with pytest.warns(UserWarning, match="n_clusters=7 is more than the 3 distinct"):
        learner.partial_fit(X[:20], u[:20], gds[:20], n_actions=2)
    learner.partial_fit(X[20:25], u[20:25], gds[20:25])  # views 4-6 grow the symbols to 6
    learner.partial_fit(X[25:], u[25:], gds[25:])        # no pass: decoded with the map
    assert learner.online_["n_passes"] == 1 and learner.online_["clusters"]["symbols"] == 6
    gds_state = int(np.flatnonzero(learner.map_.state_gds == 5)[0])
    assert learner.labels_[np.flatnonzero(gds >= 0)].tolist() == [gds_state] * 5


def test_rows_that_never_repeat_are_not_capped():
    # a noisy sensor: every row is distinct, so the window holds more than the count asked
    X, u = corridor(FIRST)
    X = X + np.random.default_rng(0).normal(0, 0.01, X.shape)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        learner = MapLearner(4, 4, window=100).partial_fit(X, u, n_actions=2)
    assert "clusters" not in learner.online_ and learner._online.codebook.views is None


def test_a_failed_call_leaves_the_codebook_as_it_was():
    X, u = corridor(FIRST + LATER)
    learner = MapLearner(8, 8, window=16, refit_every=1000)
    with pytest.warns(UserWarning):
        learner.partial_fit(X[:20], u[:20], n_actions=2)
    book = learner._online.codebook
    learner.set_params(n_states=3)  # below the states of phase 1: the pass fails
    with pytest.raises(ValueError, match="n_states=3"):
        learner.partial_fit(X[20:], u[20:])
    assert learner._online.codebook is book and learner.online_["clusters"]["symbols"] == 4
