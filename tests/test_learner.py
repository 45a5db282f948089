import dataclasses
import math

import numpy as np
import pytest

from topomap import MapLearner, TopologicalMap
from topomap.core.phase1.clustering import BICClusters, Cosine, FixedClusters, Standardized
from topomap.metrics import adjusted_rand, compound_states, evaluate, purity
from topomap.core.split.criteria import EntropyCriterion
from topomap.core.split.engine import merge_groups
from topomap.core.split.stopping import MinGain, TargetStates

from worlds import ring


def H(counts):
    """Plain-Python entropy in bits, independent of the package's code."""
    n = sum(counts)
    return -sum(c / n * math.log2(c / n) for c in counts if c)


# ---------------------------------------------------------------- the paper's method, by hand
def test_one_way_ring_split_has_gain_of_one_bit():
    # A -> B -> C -> D -> A with one action; B and D look alike.  Phase 1 merges them into one
    # state whose successor is C after A and A after C: H(x'|u) = 1 bit, and splitting by the
    # predecessor makes both halves deterministic, so the gain is exactly 1 bit.
    X, u, places = ring(n_steps=200, n_places=4, aliased=[(1, 3)], two_way=False)
    learner = MapLearner(n_clusters=3, n_states=4).fit(X, u)
    assert adjusted_rand(places, learner.labels_phase1_) < 1
    assert compound_states(places, learner.labels_phase1_) == 1
    (rec,) = learner.split_history_
    assert rec["n_groups"] == 2
    # instances exist for steps 1..T-2; the shares of A- and C-predecessors are 50/50 up to one
    n_kept, n_new = rec["n_steps_kept"], rec["n_steps_new"]
    assert abs(n_kept - n_new) <= 1
    assert rec["gain"] == pytest.approx(1.0, abs=0.01)
    assert adjusted_rand(places, learner.labels_) == 1.0


def test_two_way_ring_aliased_places_separated_exactly():
    X, u, places = ring(n_steps=600)
    learner = MapLearner(n_clusters=5, n_states=6, random_state=0).fit(X, u)
    before = evaluate(places, learner.labels_phase1_)
    after = evaluate(places, learner.labels_)
    assert before["n_states"] == 5 and before["compound_states"] == 1
    assert after == {"ari": 1.0, "nmi": 1.0, "purity": 1.0, "compound_states": 0,
                     "n_states": 6, "n_places": 6}


def test_merge_order_and_gain_match_hand_computation():
    # columns: (u=0,x'=0), (u=0,x'=1).  Groups 0 and 1 are nearly alike, group 2 differs.
    counts = np.array([[10, 0], [9, 1], [0, 10]])
    side = merge_groups(counts)
    assert side.tolist() == [False, False, True]
    _, gain = EntropyCriterion().propose(counts)
    expected = H([19, 11]) - (20 / 30 * H([19, 1]) + 10 / 30 * H([0, 10]))
    assert gain == pytest.approx(expected)


def test_merge_takes_least_weighted_increase_not_least_entropy():
    # Merging the two big identical-ish groups costs less in n*H than merging a tiny group
    # into one with a different distribution; four groups -> two.
    counts = np.array([[50, 50, 0], [48, 52, 0], [0, 0, 30], [0, 1, 29]])
    side = merge_groups(counts)
    assert side.tolist() == [False, False, True, True]


def test_ties_are_broken_by_index():
    counts = np.array([[5, 0], [5, 0], [5, 0]])  # every merge costs 0
    assert merge_groups(counts).tolist() == [False, False, True]


def test_gds_states_are_never_split():
    # Place 0 is a GDS visited from both neighbours and left to both: splitting it would gain,
    # but it must stay whole; the aliased pair still gets split.
    X, u, places = ring(n_steps=600)
    gds = np.where(places == 0, 0, -1)
    learner = MapLearner(n_clusters=4, n_states=6).fit(X, u, gds=gds)
    m = learner.map_
    gds_states = np.flatnonzero(m.state_gds >= 0)
    assert gds_states.size == 1
    assert all(r["state"] not in gds_states for r in learner.split_history_)
    assert set(learner.labels_[places == 0]) == {gds_states[0]}
    assert not np.isin(learner.labels_[places != 0], gds_states).any()
    assert adjusted_rand(places, learner.labels_) == 1.0


def test_gds_state_stays_whole_even_when_it_is_the_only_candidate():
    X, u, places = ring(n_steps=300, aliased=[])
    gds = np.where(places == 2, 0, -1)
    learner = MapLearner(n_clusters=5, stop=MinGain(0.0, max_states=20)).fit(X, u, gds=gds)
    assert all(learner.map_.state_gds[r["state"]] < 0 for r in learner.split_history_)
    assert (learner.map_.state_parent[learner.map_.state_gds >= 0] == -1).all()


def test_entropies_behave_as_the_paper_says():
    X, u, places = ring(n_steps=800, n_places=8, aliased=[(1, 5), (3, 7)])
    learner = MapLearner(n_clusters=6, n_states=10).fit(X, u)
    e = learner.entropies_
    assert len(e) == len(learner.split_history_) + 1 >= 2
    for prev, cur in zip(e, e[1:]):
        assert cur["H_o"] == pytest.approx(prev["H_o"], abs=1e-9)
        assert cur["H_u"] + cur["H_x"] <= prev["H_u"] + prev["H_x"] + 1e-9
    # the record agrees with entropies recomputed from scratch on the final map
    final = learner.map_.entropies()
    assert final["H_o"] == pytest.approx(learner.map_phase1_.entropies()["H_o"])
    for key in ("H_o", "H_u", "H_x"):
        assert final[key] == pytest.approx(e[-1][key])


def test_maps_record_what_the_learner_knew_when_it_made_them():
    X, u, _ = ring(n_steps=800, n_places=8, aliased=[(1, 5), (3, 7)])
    learner = MapLearner(n_clusters=6, n_states=10).fit(X, u)
    m1, m = learner.map_phase1_, learner.map_
    assert m1.entropy_history == learner.entropies_[:1] and m1.split_history == []
    assert m.entropy_history == learner.entropies_ and m.split_history == learner.split_history_
    assert m1.info == {"covariance_type": "diag"}
    assert m.info["stop_reason"] == learner.stop_reason_ and m.info["n_clusters"] == 6
    with pytest.raises(dataclasses.FrozenInstanceError):
        m.info = {}
    with pytest.raises(ValueError, match=r"states\[\*\]\.count must be one integer"):
        dataclasses.replace(m, state_counts=m.state_counts[:-1])
    changed = dataclasses.replace(m, info={"note": 1})
    assert changed.info == {"note": 1} and "note" not in m.info
    assert m.state_gds_ is m.state_gds  # the names the README once showed still read
    assert np.array_equal(m.action_probs_, m.action_probs)
    assert np.array_equal(m.transition_probs_, m.transition_probs)


def test_probability_tables_sum_to_one():
    X, u, _ = ring(n_steps=300)
    m = MapLearner(n_clusters=5, n_states=7).fit(X, u).map_
    assert np.allclose(m.action_probs.sum(axis=1), 1)
    assert np.allclose(m.transition_probs.sum(axis=2), 1)
    assert m.transition_probs.shape == (7, 2, 7) and m.action_probs.shape == (7, 2)
    assert m.state_probs.sum() == pytest.approx(1)


def test_same_seed_gives_identical_map(tmp_path):
    X, u, _ = ring(n_steps=400, noise=0.2)
    for seed in (0, 0):
        MapLearner(n_clusters=5, n_states=8, random_state=seed).fit(X, u).map_.save(
            tmp_path / f"m{len(list(tmp_path.iterdir()))}.json")
    a, b = sorted(tmp_path.iterdir())
    assert a.read_bytes() == b.read_bytes()


def test_no_transition_is_counted_across_episodes():
    X, u, _ = ring(n_steps=300)
    lengths = [100, 120, 80]
    m = MapLearner(n_clusters=5, n_states=6).fit(X, u, lengths=lengths).map_
    assert m.transition_counts.sum() == 300 - 3
    assert m.action_counts.sum() == 300


def test_target_state_count_is_reached_and_stop_rules_are_swappable():
    X, u, _ = ring(n_steps=600, n_places=8, aliased=[(1, 5), (3, 7)])
    assert MapLearner(n_clusters=6, n_states=9).fit(X, u).map_.n_states == 9
    # min_gain: each aliased pair has four distinct neighbours, so splitting it gains 1 bit
    # (H(x'|u) drops from 1 to 0); every other state is already deterministic (gain 0)
    learner = MapLearner(n_clusters=6, stop=MinGain(0.5)).fit(X, u)
    assert learner.map_.n_states == 8
    assert all(r["gain"] >= 0.5 for r in learner.split_history_)
    assert learner.stop_reason_ == "stopping rule"


def test_the_old_names_criterion_and_stopping_still_work_with_a_warning():
    from sklearn.base import clone

    X, u, _ = ring(n_steps=600, n_places=8, aliased=[(1, 5), (3, 7)])
    new = MapLearner(n_clusters=6, split=EntropyCriterion(), stop=MinGain(0.5)).fit(X, u)
    with pytest.warns(FutureWarning, match="stopping= was renamed stop="):
        old = MapLearner(n_clusters=6, criterion=EntropyCriterion(), stopping=MinGain(0.5))
    old.fit(X, u)
    assert np.array_equal(old.labels_, new.labels_)
    assert old.map_.info["stopping"] == new.map_.info["stopping"] == repr(MinGain(0.5))
    # get_params lists the new names only; a clone keeps the values given under the old ones
    assert "criterion" not in old.get_params() and "stopping" not in old.get_params()
    assert isinstance(clone(old).get_params()["stop"], MinGain)
    with pytest.warns(FutureWarning, match="criterion= was renamed split="):
        assert MapLearner().set_params(criterion="entropy").get_params()["split"] == "entropy"
    with pytest.raises(ValueError, match="^stopping is the deprecated name of stop: give stop"):
        MapLearner(stop=MinGain(0.5), stopping=MinGain(0.5))
    with pytest.raises(TypeError, match="unexpected keyword argument 'stoping'"):
        MapLearner(stoping=MinGain(0.5))


def test_reevaluating_only_neighbours_of_a_split_changes_nothing(monkeypatch):
    rng = np.random.default_rng(3)
    succ = rng.integers(0, 40, size=(40, 5))
    symbol = rng.integers(0, 12, 40)
    u = rng.integers(0, 5, 3000)
    p = np.zeros(3000, dtype=int)
    for t in range(1, 3000):
        p[t] = succ[p[t - 1], u[t - 1]]
    X = np.eye(12)[symbol[p]] + rng.normal(0, 0.01, (3000, 12))
    fast = MapLearner(n_clusters=12, n_states=40).fit(X, u, lengths=[1000, 2000])
    monkeypatch.setattr(MapLearner, "_recompute_all", True)
    full = MapLearner(n_clusters=12, n_states=40).fit(X, u, lengths=[1000, 2000])
    assert full.split_history_ == fast.split_history_
    assert np.array_equal(full.labels_, fast.labels_)


# ---------------------------------------------------------------- phase-1 components
def blobs(n=60, seed=0):
    rng = np.random.default_rng(seed)
    centres = np.array([[0, 0], [5, 0], [0, 5]])
    X = np.repeat(centres, n, axis=0) + rng.normal(0, 0.3, (3 * n, 2))
    return X, np.repeat(np.arange(3), n)


def test_bic_policy_finds_three_blobs():
    X, truth = blobs()
    policy = BICClusters(min_ns=1, max_ns=6)
    ns, details = policy.choose(X, 0)
    assert ns == 3 and min(details["bic"], key=details["bic"].get) == 3
    assert sorted(details["bic"]) == [1, 2, 3, 4, 5, 6]


def test_cosine_metric_groups_scaled_copies():
    rng = np.random.default_rng(1)
    dirs = np.array([[1.0, 0.0], [0.0, 1.0]])
    which = rng.integers(2, size=100)
    X = dirs[which] * rng.uniform(0.5, 5, (100, 1))
    u = rng.integers(2, size=100)
    labels = MapLearner(n_clusters=2, n_states=2, metric="cosine").fit(X, u).labels_
    assert adjusted_rand(which, labels) == 1.0
    assert np.allclose(np.linalg.norm(Cosine().fit_transform(X), axis=1), 1)


def test_standardized_metric_scales_features():
    X = np.column_stack([np.arange(10.0), 1000 * np.arange(10.0), np.ones(10)])
    Z = Standardized().fit_transform(X)
    assert np.allclose(Z[:, :2].std(axis=0), 1) and np.allclose(Z[:, 2], 0)


def test_fixed_policy_and_learner_with_bic():
    X, truth = blobs()
    u = np.zeros(len(X), dtype=int)
    policy = BICClusters(1, 6)
    before = vars(policy).copy()
    learner = MapLearner(clusters=policy, n_states=3).fit(X, u)
    # n_states=3 and no GDS leave room for at most 3 clusters: 4..6 are not searched
    assert learner.n_clusters_ == 3 and sorted(learner.cluster_choice_["bic"]) == [1, 2, 3]
    assert vars(policy) == before  # fitting never changes a parameter
    assert FixedClusters(4).choose(X, 0) == 4


# ---------------------------------------------------------------- metrics by hand
def test_metrics_on_a_hand_example():
    states = [0, 0, 0, 1, 1, 2]
    places = [5, 5, 6, 6, 6, 7]
    assert purity(places, states) == pytest.approx(5 / 6)
    assert compound_states(places, states) == 1
    assert compound_states(places, states, min_share=0.4) == 0
    assert adjusted_rand(states, states) == 1.0


def test_metrics_take_the_true_labels_first_as_scikit_learn_does():
    """Purity and compound states are not symmetric: one state holding two places is impure,
    one place cut into two states is pure; the keywords name which is which."""
    places = [0, 0, 1, 1, 2, 2]
    states = [0, 0, 0, 0, 1, 2]  # state 0 holds places 0 and 1; place 2 is cut in two states
    assert purity(places, states) == pytest.approx(4 / 6)
    assert purity(labels_true=places, labels_pred=states) == pytest.approx(4 / 6)
    assert purity(states, places) == pytest.approx(5 / 6)  # the places measured by the states
    places, states = places + [3, 3], states + [3, 4]  # place 3 cut in two states as well
    assert compound_states(labels_true=places, labels_pred=states) == 1  # state 0
    assert compound_states(labels_true=states, labels_pred=places) == 2  # places 2 and 3
    assert evaluate(labels_true=places, labels_pred=states)["n_states"] == 5
    assert evaluate(places, states)["n_places"] == 4


# ---------------------------------------------------------------- the fitted map
def test_predict_recovers_training_labels_and_score_prefers_true_actions():
    X, u, places = ring(n_steps=600)
    learner = MapLearner(n_clusters=5, n_states=6).fit(X, u)
    m = learner.map_
    X2, u2, places2 = ring(n_steps=300, seed=7)
    pred = m.predict(X2, u2)
    assert adjusted_rand(places2, pred) == 1.0
    assert m.score(X2, u2) > m.score(X2, 1 - u2)
    assert np.isfinite(m.score(X2, u2))


def test_save_load_roundtrip_and_graph_exports(tmp_path):
    import networkx as nx

    X, u, _ = ring(n_steps=400)
    m = MapLearner(n_clusters=5, n_states=6).fit(X, u, action_names=["fwd", "back"]).map_
    m.save(tmp_path / "map.json")
    m2 = TopologicalMap.load(tmp_path / "map.json")
    assert np.array_equal(m2.transition_counts, m.transition_counts)
    assert np.allclose(m2.means, m.means) and np.allclose(m2.covariances, m.covariances)
    assert m2.split_history == m.split_history and m2.action_names == ["fwd", "back"]
    assert np.array_equal(m2.predict(X, u), m.predict(X, u))
    G = m.to_networkx(min_prob=0.8)
    assert G.number_of_nodes() == 6
    for a, b, d in G.edges(data=True):
        assert all(m.transition_probs[a, act, b] > 0.8 for act in d["actions"])
        assert set(d["action_names"]) <= {"fwd", "back"}
    # on a clean ring every state has exactly one successor per action
    assert G.number_of_edges() == 12
    m.to_graphml(tmp_path / "map.graphml", min_prob=0.8)
    assert nx.read_graphml(tmp_path / "map.graphml").number_of_edges() == 12


# ---------------------------------------------------------------- bad input
@pytest.mark.parametrize("mutate, match", [
    (lambda X, u: (np.where(np.arange(len(X))[:, None] == 3, np.nan, X), u), "NaN or inf"),
    (lambda X, u: (np.where(np.arange(len(X))[:, None] == 3, np.inf, X), u), "NaN or inf"),
    (lambda X, u: (X, u[:-1]), "actions has .* entries"),
    (lambda X, u: (X[:2], u[:2]), "at least 3"),
    (lambda X, u: (X, np.where(np.arange(len(u)) == 5, -1, u)), "actions must be >= 0"),
    (lambda X, u: (X, u + 0.5), "actions must hold integers"),
])
def test_bad_input_is_named(mutate, match):
    X, u, _ = ring(n_steps=50)
    X, u = mutate(X, u)
    with pytest.raises(ValueError, match=match):
        MapLearner(n_clusters=3, n_states=5).fit(X, u)


def test_bad_settings_are_named():
    X, u, _ = ring(n_steps=50)
    with pytest.raises(ValueError, match="^n_states=4 is below the 5 states"):
        MapLearner(n_clusters=5, n_states=4).fit(X, u)
    with pytest.raises(ValueError, match="^stop.n_states=4 is below the 5 states"):
        MapLearner(n_clusters=5, stop=TargetStates(4)).fit(X, u)
    with pytest.raises(ValueError, match="^n_clusters=60 is more than the 50 distinct"):
        MapLearner(n_clusters=60, n_states=70).fit(X, u)
    with pytest.raises(ValueError, match="^clusters.ns=60 is more than the 50 distinct"):
        MapLearner(clusters=FixedClusters(60), n_states=70).fit(X, u)
    with pytest.raises(ValueError, match="^n_clusters must be a positive integer, got 0"):
        MapLearner(n_clusters=0).fit(X, u)
    with pytest.raises(ValueError, match="^phase1='fast' is unknown"):
        MapLearner(n_clusters=3, phase1="fast").fit(X, u)
    with pytest.raises(ValueError, match="gds ids must be -1"):
        MapLearner(n_clusters=3, n_states=5).fit(X, u, gds=np.full(50, -2))
    with pytest.raises(ValueError, match="gds id 3 is out of range"):
        MapLearner(n_clusters=3, n_states=5).fit(X, u, gds=np.full(50, 3), gds_names=["a"])
    with pytest.raises(ValueError, match="lengths sum to 40"):
        MapLearner(n_clusters=3, n_states=5).fit(X, u, lengths=[20, 20])
    with pytest.raises(ValueError, match="metric 'manhattan' is unknown"):
        MapLearner(n_clusters=3, metric="manhattan").fit(X, u)
    with pytest.raises(ValueError, match="^n_states must be a positive integer"):
        TargetStates(0)
    with pytest.raises(ValueError, match="^min_gain"):
        MinGain(-1)


def test_learner_is_a_scikit_learn_estimator():
    from sklearn.base import clone

    X, u, places = ring(n_steps=300)
    learner = MapLearner(n_clusters=5, n_states=6, reg_covar=1e-2, random_state=3)
    params = learner.get_params()
    assert params["n_clusters"] == 5 and params["reg_covar"] == 1e-2
    twin = clone(learner).set_params(n_states=6)
    learner.fit(X, u)
    assert learner.get_params() == params  # fit never changes the parameters
    assert learner.n_features_in_ == X.shape[1]
    assert np.array_equal(twin.fit(X, u).labels_, learner.labels_)
    assert clone(learner).get_params()["n_states"] == 6 and not hasattr(clone(learner), "labels_")


def test_min_gain_has_a_default_cap_of_three_times_the_initial_states():
    rng = np.random.default_rng(0)
    X = np.eye(3)[rng.integers(3, size=3000)] + rng.normal(0, 0.01, (3000, 3))
    u = rng.integers(4, size=3000)  # noise: every split gains a little
    rule = MinGain(min_gain=0.0)
    before = vars(rule).copy()
    learner = MapLearner(n_clusters=3, stop=rule).fit(X, u)
    assert learner.map_.n_states == 9 and learner.stop_reason_ == "stopping rule"
    assert vars(rule) == before  # the parameter is not changed by fit
    capped = MapLearner(n_clusters=3, stop=MinGain(0.0, max_states=5)).fit(X, u)
    assert capped.map_.n_states == 5
