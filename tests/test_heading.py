"""The heading integrated from turn actions (topomap.core.phase1.heading) and the views turn loops
join (topomap.core.phase1.loops), on small rooms whose answers follow by hand."""

import json

import numpy as np
import pytest

from topomap import MapLearner
from topomap.core.checks import ParameterError
from topomap.core.phase1.heading import (MIN_GAIN, HeadedStates, Turns, head_states,
                                         heldout_gain, integrate, inverse_pairs, learn_turns,
                                         turn_orders)
from topomap.core.phase1.loops import join_loop_views, loop_pairs
from topomap.metrics import adjusted_rand

LEFT, RIGHT, FORWARD = 0, 1, 2
#: headings counter-clockwise: east, north, west, south
MOVES = np.array([[1, 0], [0, 1], [-1, 0], [0, -1]])


def view(x, y, d, size, mark):
    """What the agent sees in a ``size`` x ``size`` room: whether the cell ahead and the cell on
    its left are open, and whether it stands on the marked cell (``mark``, or None)."""
    def inside(dx, dy):
        return 0 <= x + dx < size and 0 <= y + dy < size
    ahead, left = MOVES[d], MOVES[(d + 1) % 4]
    return (int(inside(*ahead)) + 2 * int(inside(*left))
            + 4 * int(mark is not None and (x, y) == mark))


def walk(n_steps, size=2, mark=None, fail=0.0, seed=0, start=(0, 0, 0)):
    """A random walk over left / right / forward (forward only where the cell ahead is in the
    room): (views, actions, poses).  A turn is recorded but not made with probability ``fail``."""
    rng = np.random.default_rng(seed)
    x, y, d = start
    views, actions, poses = [], [], []
    for _ in range(n_steps):
        views.append(view(x, y, d, size, mark))
        poses.append((y * size + x) * 4 + d)
        can_move = 0 <= x + MOVES[d][0] < size and 0 <= y + MOVES[d][1] < size
        a = int(rng.integers(3 if can_move else 2))
        actions.append(a)
        if a == FORWARD:
            x, y = x + MOVES[d][0], y + MOVES[d][1]
        elif rng.random() >= fail:
            d = (d + (1 if a == LEFT else -1)) % 4
    views = np.unique(views, return_inverse=True)[1].ravel()
    return views.astype(np.int64), np.array(actions), np.array(poses)


def one_hot(views):
    return np.eye(int(views.max()) + 1)[views]


def test_integrate_turns_every_episode_from_zero():
    u = np.array([LEFT, LEFT, RIGHT, FORWARD, LEFT, RIGHT, RIGHT])
    h = integrate(u, np.array([5, 2]), (1, 3, 0), 4)
    # episode 1: 0, +1, +1, -1, 0 ; episode 2 starts at 0: 0, -1
    assert h.tolist() == [0, 1, 2, 1, 1, 0, 3]


def test_turns_of_order_four_and_a_move():
    sym, u, _ = walk(3000, mark=(1, 1))
    assert turn_orders(sym, u, [sym.size], 3) == [4, 4, 0]


def test_compass_moves_do_not_turn():
    """A walk of compass moves in a room whose cells have colours: no move repeated brings back
    the view it left, so nothing turns and the heading is not learned."""
    rng = np.random.default_rng(1)
    colour = rng.integers(0, 3, size=(6, 6))
    x = y = 0
    sym, u = [], []
    for _ in range(4000):
        sym.append(colour[x, y])
        ok = [a for a, (dx, dy) in enumerate(MOVES) if 0 <= x + dx < 6 and 0 <= y + dy < 6]
        a = int(rng.choice(ok))
        u.append(a)
        x, y = x + MOVES[a][0], y + MOVES[a][1]
    turns, info = learn_turns(np.array(sym), np.array(u), np.array([4000]), 4)
    assert turns is None and info["orders"] == [0, 0, 0, 0]
    assert "no action" in info["reason"]


def test_learned_turns_are_the_rotations():
    """Left then right brings the view back, so left and right are opposite quarter turns; the
    learned heading is the true one up to the start and the direction the headings are counted
    in."""
    sym, u, poses = walk(4000, mark=(1, 1))
    turns, info = learn_turns(sym, u, np.array([sym.size]), 3)
    assert info["inverse"] == [[LEFT, RIGHT], [RIGHT, LEFT]]
    assert turns.n_headings == 4 and turns.steps == (1, 3, 0)
    assert [g["steps"] for g in info["gains"]] == [[1, 3, 0]] and turns.gain > MIN_GAIN
    h = integrate(u, [u.size], turns.steps, 4)
    assert np.array_equal(h, (poses % 4 - poses[0] % 4) % 4)  # left is +1: counter-clockwise


@pytest.mark.parametrize("fail", [0.001, 0.005, 0.05])
def test_failing_turns_are_left_out(fail):
    """Turns that fail make the integrated heading drift: one failure in 1,000 or 200 turns moves
    blocks of the walk, one in 20 leaves the symbols nothing to tell of it; it is not used."""
    sym, u, _ = walk(4000, mark=(1, 1), fail=fail)
    turns, info = learn_turns(sym, u, np.array([sym.size]), 3)
    assert info["orders"] == [4, 4, 0]  # the turns still close their circles mostly
    assert turns is None
    assert ("drifts" if fail < 0.01 else "too little") in info["reason"]
    sym, u, _ = walk(4000, mark=(1, 1))
    assert learn_turns(sym, u, np.array([sym.size]), 3)[1]["drifting_blocks"] == 0


def test_heldout_gain():
    rng = np.random.default_rng(0)
    sym = rng.integers(0, 8, 4000)
    tied = sym % 4  # every symbol comes with one heading
    free = rng.integers(0, 4, 4000)
    assert heldout_gain(sym, tied, 4, 8) > 0.9 * np.log(4)
    assert heldout_gain(sym, free, 4, 8) < 0


def test_later_episodes_are_turned_to_agree():
    """Two walks through the same room, the second begun facing west: their integrated headings
    both start at 0, and the second is turned by 2 to agree with the first."""
    a, ua, pa = walk(2000, mark=(1, 1), seed=1)
    b, ub, pb = walk(2000, mark=(1, 1), seed=2, start=(0, 0, 2))
    sym, u, poses = np.concatenate([a, b]), np.concatenate([ua, ub]), np.concatenate([pa, pb])
    turns = Turns(4, (1, 3, 0), 1.0)
    labels, headed = head_states(sym, int(sym.max()) + 1, u, [2000, 2000], turns)
    assert np.array_equal(headed.heading, poses % 4)  # both walks began at heading 0 = east


def test_pairs_tell_the_rotated_copies_apart():
    """In a 2 x 2 room every cell is a corner: four views, each seen at four poses, rotated
    copies of each other.  With the heading every pose is a (view, heading) pair of its own."""
    sym, u, poses = walk(3000)
    assert np.unique(sym).size == 4 and np.unique(poses).size == 16
    labels, headed = head_states(sym, 4, u, [sym.size], Turns(4, (1, 3, 0), 1.0))
    assert headed.n_pairs == 16 and adjusted_rand(poses, labels) == 1.0
    assert sorted(np.bincount(headed.view).tolist()) == [4, 4, 4, 4]


def test_headed_states_translate_ids():
    headed = HeadedStates(Turns(2, (1, 1, 0), 1.0), heading=np.array([0, 1, 1]),
                          view=np.array([0, 0, 2, 5]), pair_heading=np.array([0, 1, 1, 0]),
                          n_symbols=6)
    # pairs 0..3 emit their symbols; ids from 4 on are GDS ids, after the 6 symbols
    assert headed.emitted([0, 1, 2, 3, 4, 5]).tolist() == [0, 0, 2, 5, 6, 7]
    assert headed.symbol_rows()[[0, 2, 5]].tolist() == [0, 2, 3]
    loglik = np.arange(18, dtype=float).reshape(3, 6)
    out = headed.observed(loglik)
    assert out.shape == (3, 4)
    assert out[0].tolist() == [0.0, -np.inf, -np.inf, 5.0]  # step 0 has heading 0
    assert out[2].tolist() == [-np.inf, 12.0, 14.0, -np.inf]


def test_loops_join_a_view_cut_in_two():
    """Symbol 3 is read at random as 3 or 4 at the poses of view 3: the turn loops (left-right,
    right-left, four lefts) link the two, and only them."""
    sym, u, _ = walk(4000, mark=(1, 1))
    rng = np.random.default_rng(5)
    cut = np.where((sym == 3) & (rng.random(sym.size) < 0.5), sym.max() + 1, sym)
    ns = int(cut.max()) + 1
    turns = Turns(4, (1, 3, 0), 1.0)
    first, last = loop_pairs(cut, u, [cut.size], turns)
    assert first.size > 0 and np.all((first == last) | (np.minimum(first, last) == 3))
    joined, n, k = join_loop_views(cut, ns, u, [cut.size], turns)
    assert (n, k) == (ns - 1, 1) and np.array_equal(joined, sym)


def test_learner_pairs_and_plain_views():
    """The learner's phase 1 holds one state per (view, heading) pair with the heading, one per
    view without; the maps decode a walk as usual."""
    sym, u, poses = walk(3000, mark=(1, 1))
    X = one_hot(sym)
    n_views = X.shape[1]
    on = MapLearner(n_clusters=n_views, n_states=16, heading="auto", random_state=0).fit(X, u)
    off = MapLearner(n_clusters=n_views, n_states=16, heading="off", random_state=0).fit(X, u)
    pairs = np.unique(sym * 4 + poses % 4).size
    assert on.heading_["used"] and on.heading_["turns"] == {"0": 1, "1": 3}
    assert on.map_phase1_.n_states == pairs and off.map_phase1_.n_states == n_views
    assert adjusted_rand(poses, on.labels_) == 1.0 > adjusted_rand(poses, off.labels_)
    assert json.loads(json.dumps(on.map_.info["heading"]))["n_headings"] == 4
    assert "heading" not in off.map_.info
    assert on.n_clusters_ == n_views
    assert on.predict(X[:50], u[:50]).shape == (50,)


def test_learner_refined_with_heading():
    sym, u, poses = walk(3000, mark=(1, 1))
    m = MapLearner(n_clusters=int(sym.max()) + 1, n_states=16, refine="em",
                   random_state=0).fit(one_hot(sym), u)
    assert m.heading_["used"] and m.map_.n_states == 16
    assert adjusted_rand(poses, m.labels_) == 1.0
    # every refined state emits the K-means symbol of its steps, as the split's states do
    symbols = m.map_split_.state_symbol[m.labels_split_]
    assert adjusted_rand(sym, symbols) == 1.0
    assert np.array_equal(m.map_.state_symbol[m.labels_], symbols)


def test_symmetric_room_needs_heading_on():
    """The 2 x 2 room without a mark looks the same turned by 90 degrees: the views say nothing
    of the heading, so ``auto`` leaves it out and ``on`` uses it."""
    sym, u, poses = walk(3000)
    X = one_hot(sym)
    auto = MapLearner(n_clusters=4, n_states=16, random_state=0).fit(X, u)
    on = MapLearner(n_clusters=4, n_states=16, heading="on", random_state=0).fit(X, u)
    assert not auto.heading_["used"] and "too little" in auto.heading_["reason"]
    assert on.heading_["used"] and adjusted_rand(poses, on.labels_phase1_) == 1.0


def test_told_size_below_pairs_keeps_the_views():
    sym, u, _ = walk(3000, mark=(1, 1))
    m = MapLearner(n_clusters=int(sym.max()) + 1, n_states=9, random_state=0).fit(one_hot(sym), u)
    assert not m.heading_["used"] and "more than the 9 states" in m.heading_["reason"]


def test_no_turns_same_map():
    """Where no action turns, ``auto`` fits the map ``off`` fits, field for field."""
    rng = np.random.default_rng(3)
    X = rng.normal(size=(1500, 3)) + np.repeat(np.eye(3) * 4, 500, axis=0)
    u = rng.integers(0, 2, 1500)
    a = MapLearner(n_clusters=3, n_states=5, refine="em", motion="discrete",
                   random_state=0).fit(X, u)
    b = MapLearner(n_clusters=3, n_states=5, refine="em", heading="off", motion="discrete",
                   random_state=0).fit(X, u)
    assert not a.heading_["used"]
    assert json.dumps(a.map_.to_dict()) == json.dumps(b.map_.to_dict())


def test_bad_heading_names_the_parameter():
    with pytest.raises(ParameterError, match="^heading must be one of auto, on, off"):
        MapLearner(heading="yes").fit(np.zeros((10, 2)), np.zeros(10, dtype=int))


def test_partial_fit_learns_the_heading_as_fit_does():
    """Passes on every step seen pair the views with the heading as ``fit`` does; once steps
    leave the window, the codebook's symbols are the views the pairs were made of."""
    sym, u, poses = walk(3000, mark=(1, 1))
    X, n_views = one_hot(sym), int(sym.max()) + 1
    kw = dict(n_clusters=n_views, n_states=16, random_state=0)
    online = MapLearner(**kw)
    for rows in np.array_split(np.arange(sym.size), 3):
        online.partial_fit(X[rows], u[rows])
    assert online.heading_["used"] and online.map_phase1_.n_states == np.unique(
        sym * 4 + poses % 4).size
    assert adjusted_rand(poses, online.labels_) == 1.0
    small = MapLearner(**kw, window=1000, refit_every=500)
    for rows in np.array_split(np.arange(sym.size), 6):
        small.partial_fit(X[rows], u[rows])
    assert small.heading_["used"]
    assert adjusted_rand(poses[-1000:], small.labels_[-1000:]) == 1.0
