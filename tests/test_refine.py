"""The refinement, EM alone and the structure moves on small worlds whose answer is known."""

import numpy as np
import pytest
from sklearn.metrics import adjusted_rand_score

from topomap.core.checks import ParameterError
from topomap.core.refine.methods import CSCGRefinement, EMRefinement
from topomap.core.refine.sequence import SymbolSequence
from topomap.core.refine.settings import CSCGRounds, Growth, HardRounds, Reading, SoftRounds
from topomap.core.refine.structure import merge_states, same_partition, split_compounds
from topomap.core.stats import episode_masks
from topomap.worlds import GridRoom, RandomExplorer


def refine_fit(sym, u, lengths, n_actions, n_symbols, split_state_symbol, random_state=0,
               **params):
    """``refine="em"`` on a symbol sequence."""
    seq = SymbolSequence.build(sym, u, lengths, n_actions, n_symbols)
    return EMRefinement(**params).fit(seq, split_state_symbol, random_state)


def cscg_fit(sym, u, lengths, n_actions, n_symbols, random_state=0, **params):
    """``refine="cscg"`` on a symbol sequence."""
    seq = SymbolSequence.build(sym, u, lengths, n_actions, n_symbols)
    return CSCGRefinement(**params).fit(seq, None, random_state)


def ring_walk(T, symbols, seed=0):
    """Random walk on a ring of places (action 0: forward, 1: back); returns symbols, actions,
    places."""
    rng = np.random.default_rng(seed)
    n = len(symbols)
    u = rng.integers(0, 2, T)
    places = np.empty(T, dtype=np.int64)
    places[0] = 0
    for t in range(1, T):
        places[t] = (places[t - 1] + (1 if u[t - 1] == 0 else -1)) % n
    return np.asarray(symbols)[places], u, places


RING = [0, 1, 2, 3, 1, 4, 2, 5]  # places 1/4 and 2/6 look alike


ROOM = GridRoom(4, 3, 3, seed=1)


def grid_walk(T, seed=0):
    traj = ROOM.simulate(T, RandomExplorer(), np.random.default_rng(seed))
    return ROOM.place_symbols[traj.places], traj.actions, traj.places


@pytest.mark.parametrize("seed", range(3))
def test_refine_recovers_every_place_of_an_aliased_ring(seed):
    """The split is given as one state per symbol (it found nothing to split)."""
    sym, u, places = ring_walk(3000, RING, seed)
    fit = refine_fit(sym, u, [3000], 2, 6, np.arange(6), random_state=seed)
    assert adjusted_rand_score(places, fit.labels_) == 1.0 and fit.n_states_ == 8


@pytest.mark.parametrize("accelerate", ["none", "squarem"])
@pytest.mark.parametrize("seed", range(3))
def test_refine_recovers_every_cell_of_a_small_grid(seed, accelerate):
    """The split is given as many states per symbol as there are cells (its usual size)."""
    sym, u, places = grid_walk(4000, seed)
    fit = refine_fit(sym, u, [4000], 4, 3, ROOM.place_symbols, random_state=seed,
                     hard={"accelerate": accelerate})
    assert adjusted_rand_score(places, fit.labels_) == 1.0 and fit.n_states_ == 12


def test_accelerated_refinement_keeps_the_first_stage_plain():
    """``accelerate`` speeds the warm-started rounds only: the first stage, from random counts,
    runs the same EM iterations to the same labelling, so both fits start their growth from the
    same states."""
    sym, u, _ = grid_walk(4000, 0)
    plain, fast = (refine_fit(sym, u, [4000], 4, 3, ROOM.place_symbols, hard={"accelerate": a})
                   for a in ("none", "squarem"))
    assert plain.info_["stages"][0] == fast.info_["stages"][0]
    assert plain.info_["stages"][1:] != fast.info_["stages"][1:]  # the later rounds did change


def test_refine_respects_episodes():
    sym, u, places = ring_walk(3000, RING, 0)
    fit = refine_fit(sym, u, [1000, 1500, 500], 2, 6, np.arange(6))
    assert adjusted_rand_score(places, fit.labels_) == 1.0


def test_cscg_nearly_recovers_the_ring():
    """EM alone with CSCG's recipe (20 clones per symbol here, its 70 by default: the same
    answer on this ring at a tenth of the time); it may leave a duplicate or two."""
    sym, u, places = ring_walk(3000, RING, 1)
    fit = cscg_fit(sym, u, [3000], 2, 6, random_state=1, hard={"clones_per_symbol": 20})
    assert adjusted_rand_score(places, fit.labels_) > 0.9


def test_gds_ids_keep_one_state():
    """A symbol id past n_symbols is a GDS: one clone, one state."""
    sym, u, places = ring_walk(3000, [0, 1, 2, 3, 1, 4, 2, 6], 2)  # id 6 = GDS of place 7
    fit = refine_fit(sym, u, [3000], 2, 6, np.arange(6), random_state=2)
    assert np.sum(fit.state_symbol_ == 6) == 1
    assert adjusted_rand_score(places, fit.labels_) == 1.0


@pytest.mark.parametrize("a, b, same", [
    ([0, 0, 1, 1, 2], [7, 7, 3, 3, 9], True),     # renamed
    ([0, 1, 0, 1], [1, 0, 1, 0], True),           # names swapped
    ([-2, -2, 5, 5], [0, 0, 1, 1], True),         # any integers
    ([0, 0, 1, 1], [5, 6, 5, 6], False),          # as many groups, crossed: 4 pairs
    ([0, 0, 1, 1], [0, 0, 0, 0], False),          # two groups joined
    ([0, 0, 0, 0], [0, 0, 1, 1], False),          # one group cut
    ([0, 1, 1, 2], [0, 1, 2, 2], False),          # one step moved: 4 pairs, 3 groups each
])
def test_same_partition_hand_cases(a, b, same):
    assert same_partition(np.array(a), np.array(b)) is same


def test_same_partition_is_equality_of_the_groups():
    """Against the definition: the same set of groups of steps, on small random labellings."""
    rng = np.random.default_rng(0)
    for _ in range(300):
        a = rng.integers(0, 4, 7)
        b = rng.permutation(9)[a] if rng.random() < 0.5 else rng.integers(0, 4, 7)
        groups = [{frozenset(np.flatnonzero(x == v).tolist()) for v in np.unique(x)}
                  for x in (a, b)]
        assert same_partition(a, b) == (groups[0] == groups[1])


def test_merge_joins_duplicates_of_one_place():
    """Duplicate every place: each visit goes to one of two copies at random."""
    sym, u, places = ring_walk(4000, RING, 3)
    labels = places * 2 + np.random.default_rng(0).integers(0, 2, places.size)
    _, has_next = episode_masks(places.size, [places.size])
    merged, merged_symbol = merge_states(labels, np.repeat(RING, 2), u, has_next, 6.63)
    assert same_partition(merged, places) and merged_symbol.size == 8


def test_merge_keeps_places_that_allow_different_moves():
    """Two wall cells of one symbol that no shared move tells apart stay two states."""
    sym, u, places = grid_walk(4000, 0)
    _, has_next = episode_masks(places.size, [places.size])
    merged, _ = merge_states(places, ROOM.place_symbols, u, has_next, 6.63)
    assert same_partition(merged, places)


def test_split_separates_a_compound_state():
    sym, u, places = ring_walk(4000, RING, 4)
    labels = np.where(places == 4, 1, places)  # places 1 and 4 folded into state 1
    has_prev, has_next = episode_masks(places.size, [places.size])
    state_symbol = np.array([0, 1, 2, 3, -9, 4, 2, 5])
    split, split_symbol = split_compounds(labels, state_symbol, u, has_prev, has_next, 2, z=3.09)
    assert split_symbol.size == 9
    assert adjusted_rand_score(places, split) > 0.99


# ---------------------------------------------------------------- through the learner and the map
def noisy(sym, n_symbols, seed=0):
    """One-hot observations of the symbols, with sensor noise."""
    rng = np.random.default_rng(seed)
    return np.eye(n_symbols)[sym] + rng.normal(0, 0.01, (len(sym), n_symbols))


def test_the_learner_refines_the_split_and_keeps_it_beside():
    from topomap import MapLearner

    sym, u, places = ring_walk(3000, RING, 0)
    split = MapLearner(n_clusters=6, n_states=6).fit(noisy(sym, 6), u)
    learner = MapLearner(n_clusters=6, n_states=6, refine="em", refined_size="free").fit(
        noisy(sym, 6), u)
    assert adjusted_rand_score(places, split.labels_) < 0.9  # the split alone cannot tell them
    assert adjusted_rand_score(places, learner.labels_) == 1.0 and learner.map_.n_states == 8
    assert np.array_equal(learner.labels_split_, split.labels_)
    assert learner.map_split_.n_states == 6 and learner.map_.info["refine"].startswith("EMRef")
    assert learner.entropies_[-1]["stage"] == "refined"
    assert set(learner.timings_) == {"phase1", "phase2", "refine"}


def test_a_refined_map_saved_and_loaded_scores_the_same(tmp_path):
    from topomap import MapLearner, TopologicalMap

    sym, u, places = ring_walk(2000, RING, 1)
    X = noisy(sym, 6, 1)
    m = MapLearner(n_clusters=6, n_states=6, refine="em").fit(X, u).map_
    twin = TopologicalMap.load(m.save(tmp_path / "map.json"))
    held_sym, held_u, _ = ring_walk(500, RING, 9)
    Xh = noisy(held_sym, 6, 9)
    assert twin.score(Xh, held_u) == m.score(Xh, held_u)
    assert np.array_equal(twin.predict(Xh, held_u), m.predict(Xh, held_u))


def test_gds_states_stay_fixed_through_refinement():
    from topomap import MapLearner

    sym, u, places = ring_walk(3000, RING, 2)
    gds = np.where(places == 7, 0, -1)  # place 7 (the only one showing symbol 5) is a GDS
    learner = MapLearner(n_clusters=5, n_states=6, refine="em", refined_size="free").fit(
        noisy(sym, 6, 2), u, gds=gds)
    m = learner.map_
    (gds_state,) = np.flatnonzero(m.state_gds == 0)
    assert np.all(learner.labels_[gds == 0] == gds_state)
    assert not np.any(learner.labels_[gds < 0] == gds_state)
    assert adjusted_rand_score(places, learner.labels_) == 1.0


def test_unknown_refinements_are_refused():
    from topomap import MapLearner

    sym, u, _ = ring_walk(300, RING, 0)
    with pytest.raises(ValueError, match="refine 'magic' is unknown; choose None or one of cscg, em"):
        MapLearner(n_clusters=6, n_states=6, refine="magic").fit(noisy(sym, 6), u)


def test_the_string_none_is_none_with_a_warning():
    """``refine=None`` is "no refinement" in Python; the config's option name ``"none"`` still
    works for one release, warning, and gives the map ``refine=None`` gives."""
    from topomap import MapLearner

    sym, u, _ = ring_walk(300, RING, 0)
    X = noisy(sym, 6)
    plain = MapLearner(n_clusters=6, n_states=8, refine=None).fit(X, u)
    with pytest.warns(FutureWarning, match='refine="none" is refine=None'):
        old = MapLearner(n_clusters=6, n_states=8, refine="none").fit(X, u)
    assert np.array_equal(old.labels_, plain.labels_)
    assert not hasattr(old, "refine_info_")


class _Fragments:
    """A refinement that cuts every phase-1 state in two by the parity of the step: noise."""

    name = "fragments"

    def __init__(self, guard):
        self.guard = guard

    def fit(self, seq, split_state_symbol, random_state):
        self.labels_ = 2 * seq.sym + np.arange(seq.sym.size) % 2
        self.state_symbol_ = np.repeat(np.arange(seq.n_ids), 2)
        return self


class _OldFragments(_Fragments):
    """The same, written to the contract before 0.3: ``fit`` returns a ``CloneFit``."""

    def fit(self, seq, split_state_symbol, random_state):
        from topomap.core.refine.methods import CloneFit

        super().fit(seq, split_state_symbol, random_state)
        return CloneFit(self.labels_, self.state_symbol_)


def test_an_old_style_refinement_still_works_and_warns():
    from topomap import MapLearner

    sym, u, _ = ring_walk(3000, RING, 0)
    X = noisy(sym, 6)
    new = MapLearner(n_clusters=6, n_states=8, refine=_Fragments(False), refined_size="free")
    old = MapLearner(n_clusters=6, n_states=8, refine=_OldFragments(False), refined_size="free")
    with pytest.warns(FutureWarning, match="returned a CloneFit"):
        old.fit(X, u)
    assert np.array_equal(old.labels_, new.fit(X, u).labels_) and old.map_.n_states == 12


def test_soft_settings_reach_the_refinement_and_the_map_file_label():
    """A warm-up longer than Baum-Welch's iterations (30 at most) never learns the confusion
    matrix: every soft round ends with the one it started from.  The ring is deterministic, so
    no two symbols follow one state and action of the hard labelling and that start is the
    identity (``init_error`` goes to the pairs that do); a learned matrix has off-diagonal mass
    from its prior."""
    from topomap import MapLearner

    sym, u, _ = ring_walk(3000, RING, 0)
    learner = MapLearner(n_clusters=6, n_states=6, refine=EMRefinement(
        evidence="soft", soft={"rounds": 1},
        reading={"conf_warmup": 100, "observed_in": "auto"})).fit(noisy(sym, 6), u)
    rounds = learner.refine_info_["soft_rounds"]
    assert len(rounds) == 2  # one soft round and a hard one after it, then the last soft round
    assert [r["conf_offdiag"] for r in rounds] == [0.0, 0.0]
    assert ("soft=SoftSettings(rounds=1, conf_warmup=100, observed_in='auto')"
            in learner.map_.info["refine"])
    learned = MapLearner(n_clusters=6, n_states=6, refine=EMRefinement(  # the matrix first
        evidence="soft", soft={"rounds": 1}, reading={"observed_in": "auto"})).fit(noisy(sym, 6), u)
    assert 0.0 < learned.refine_info_["soft_rounds"][0]["conf_offdiag"] < 0.1


def test_the_learner_refines_a_clone_and_never_changes_its_refine():
    from topomap import MapLearner

    sym, u, _ = ring_walk(3000, RING, 0)
    refine = EMRefinement(hard={"max_rounds": 3})
    learner = MapLearner(n_clusters=6, n_states=6, refine=refine).fit(noisy(sym, 6), u)
    assert learner.refine is refine and not hasattr(refine, "labels_")
    assert learner.map_.info["refine"] == refine.provenance()


@pytest.mark.parametrize("guard", [True, False])
def test_the_guard_keeps_the_split_map_when_refinement_only_fragments_it(guard):
    from topomap import MapLearner

    sym, u, places = ring_walk(3000, RING, 0)
    learner = MapLearner(n_clusters=6, n_states=8, refine=_Fragments(guard),
                         refined_size="free").fit(noisy(sym, 6), u)
    if guard:  # 12 parity halves explain nothing more and cost parameters: BIC is worse
        info = learner.refine_info_
        assert info["kept"] == "split" and info["bic"]["refined"] > info["bic"]["split"]
        assert learner.map_ is learner.map_split_ and learner.map_.n_states == 8
    else:
        assert learner.map_.n_states == 12 and "kept" not in learner.refine_info_


@pytest.mark.parametrize("guard", [True, False])
def test_the_map_kept_records_the_refinement(guard):
    from topomap import MapLearner

    sym, u, places = ring_walk(3000, RING, 0)
    learner = MapLearner(n_clusters=6, n_states=8, refine=_Fragments(guard),
                         refined_size="free").fit(noisy(sym, 6), u)
    m = learner.map_
    assert m.info["refine_info"] == learner.refine_info_ and "_Fragments" in m.info["refine"]
    assert m.entropy_history == learner.entropies_
    if guard:
        assert m is learner.map_split_ and "refined_from" not in m.info
    else:
        assert m.entropy_history[-1]["stage"] == "refined" and len(m.info["refined_from"]) == 12
        assert "refine" not in learner.map_split_.info
        assert learner.map_split_.entropy_history == learner.entropies_[:-1]


def test_the_guard_keeps_a_refinement_that_recovers_the_places():
    from topomap import MapLearner

    sym, u, places = ring_walk(3000, RING, 0)
    learner = MapLearner(n_clusters=6, n_states=6, refine="em", refined_size="free").fit(
        noisy(sym, 6), u)
    info = learner.refine_info_
    assert info["kept"] == "refined" and info["bic"]["refined"] < info["bic"]["split"]


@pytest.mark.parametrize("refine", ["em", "cscg"])
def test_a_refined_map_is_the_same_bytes_for_the_same_seed(refine, tmp_path):
    """Nothing run-dependent (such as CPU seconds) reaches map.json."""
    from topomap import MapLearner

    sym, u, _ = ring_walk(2000, RING, 3)
    X = noisy(sym, 6, 3)
    component = "em" if refine == "em" else CSCGRefinement(hard={"clones_per_symbol": 4,
                                                                   "max_iter": 30})
    paths = [MapLearner(n_clusters=6, n_states=6, refine=component, random_state=1).fit(X, u)
             .map_.save(tmp_path / f"map{i}.json") for i in range(2)]
    assert paths[0].read_bytes() == paths[1].read_bytes()


# ---------------------------------------------------------------- the components themselves
def test_the_refinements_store_their_parameters_as_given():
    from sklearn.base import clone

    growth, hard = {"prefix": np.int64(3000)}, HardRounds(tol=0)
    em = EMRefinement(growth=growth, hard=hard, guard=False)
    assert em.growth is growth and em.hard is hard and em.guard is False
    params = em.get_params()
    assert params == {"evidence": "auto", "guard": False, "hard": hard, "growth": growth,
                      "soft": SoftRounds(), "reading": Reading()}
    twin = clone(em)
    assert twin is not em and twin.get_params() == params
    assert type(em.settings().growth.prefix) is np.int64 and em.settings().hard.tol == 0
    assert CSCGRefinement(hard={"clones_per_symbol": 5}).set_params(
        reading={"floor": 0.5}).get_params() == {
        "hard": {"clones_per_symbol": 5}, "evidence": "auto", "soft": SoftRounds(),
        "reading": {"floor": 0.5}}


def test_the_repr_is_the_estimators_and_the_provenance_the_form_map_json_stores():
    assert repr(EMRefinement()) == "EMRefinement()"
    assert repr(EMRefinement(growth={"prefix": 500}, soft={"rounds": 2})) == (
        "EMRefinement(growth={'prefix': 500}, soft={'rounds': 2})")
    # the defaults' text: info["refine"] of the reference configs' maps written before the
    # settings were grouped by stage (benchmarks/reference_maps.py), the same bytes since
    assert EMRefinement().provenance() == (
        "EMRefinement(clone_factor=2, prefix=2000, prefix_visits=40, max_rounds=8, guard=True, "
        "settings=EMSettings(row_prior=0.5, tol=1e-06, max_iter=50, prune=0.0001, "
        "merge_threshold=6.63, split_z=3.09, spare=2, init_noise=1.0))")
    assert CSCGRefinement().provenance() == (
        "CSCGRefinement(clones_per_symbol=70, pseudocount=0.002, max_iter=1000, tol=0.0)")
    assert CSCGRefinement(hard={"clones_per_symbol": 4, "tol": 0}).provenance() == (
        "CSCGRefinement(clones_per_symbol=4, pseudocount=0.002, max_iter=1000, tol=0.0)")
    # a stopping rule switched on is named, and only then
    assert ("guard=True, settle=0.01, settings=EMSettings(row_prior=0.5, tol=1e-06, max_iter=50, "
            "prune=" in EMRefinement(hard={"settle": 0.01}).provenance())
    assert "guard=True, accelerate='squarem', settings=EMSettings(" in EMRefinement(
        hard={"accelerate": "squarem"}).provenance()
    # the soft rounds', the reading's and the growth caps' settings changed from their defaults
    # are named, by their names of before 0.3 and in the old SoftSettings' order
    assert ("evidence='soft', soft=SoftSettings(conf_warmup=10), settings=EMSettings("
            in EMRefinement(evidence="soft", reading={"conf_warmup": 10}).provenance())
    assert ("guard=True, soft=SoftSettings(rounds=2, conf_diag=5.0, stage_cap=10, "
            "observed=0.0), settings=EMSettings(" in EMRefinement(
                reading={"temperature": 0.0, "conf_diag": 5.0}, growth={"stage_cap": 10},
                soft={"rounds": 2}).provenance())
    assert CSCGRefinement(soft=SoftRounds(rounds=1)).provenance().endswith(
        "tol=0.0, soft=SoftSettings(rounds=1))")


@pytest.mark.parametrize("cls, params, message", [
    (EMRefinement, dict(growth={"clone_factor": 0}),
     "growth.clone_factor must be a positive integer, got 0"),
    (EMRefinement, dict(growth={"prefix": 2.5}),
     "growth.prefix must be a positive integer, got 2.5"),
    (EMRefinement, dict(hard={"max_rounds": True}),
     "hard.max_rounds must be a positive integer, got True"),
    (EMRefinement, dict(hard={"max_iter": 0}), "hard.max_iter must be a positive integer, got 0"),
    (EMRefinement, dict(growth={"prefix_visits": -1}),
     "growth.prefix_visits must be a non-negative integer, got -1"),
    (EMRefinement, dict(hard={"spare": -2}), "hard.spare must be a non-negative integer, got -2"),
    (EMRefinement, dict(hard={"row_prior": 0.0}), "hard.row_prior must be > 0, got 0.0"),
    (EMRefinement, dict(hard={"tol": -1e-3}), "hard.tol must be >= 0, got -0.001"),
    (EMRefinement, dict(hard={"prune": 1.0}), r"hard.prune must be in \[0, 1\), got 1.0"),
    (EMRefinement, dict(hard={"settle": -0.1}), r"hard.settle must be in \[0, 1\], got -0.1"),
    (EMRefinement, dict(hard={"init_noise": "x"}), "hard.init_noise must be >= 0, got 'x'"),
    (EMRefinement, dict(hard={"accelerate": "fast"}),
     "hard.accelerate must be one of auto, none, squarem, got 'fast'$"),
    (CSCGRefinement, dict(hard={"clones_per_symbol": 0}),
     "hard.clones_per_symbol must be a positive integer"),
    (CSCGRefinement, dict(hard={"max_iter": 0}), "hard.max_iter must be a positive integer, got 0"),
    (CSCGRefinement, dict(hard={"pseudocount": float("nan")}),
     "hard.pseudocount must be > 0, got nan"),
    (CSCGRefinement, dict(hard=CSCGRounds(tol=-1.0)), "hard.tol must be >= 0, got -1.0"),
    (EMRefinement, dict(reading={"conf_warmup": -1}),
     "reading.conf_warmup must be a non-negative integer, got -1"),
    (CSCGRefinement, dict(reading={"floor": 0.0}), r"reading.floor must be in \(0, 1\), got 0.0"),
    (EMRefinement, dict(soft={"warmup": 3}), "soft.warmup is not a soft setting; the settings "
                                              "are rounds, spare"),
    (EMRefinement, dict(soft=3), "soft must be SoftRounds or a mapping of its fields, got 3"),
    (EMRefinement, dict(growth=Growth(budget="all")),
     "growth.budget must be one of split, evidence, got 'all'"),
    (EMRefinement, dict(evidence="fuzzy"), "evidence must be one of auto, soft, hard"),
])
def test_bad_parameters_are_refused_by_name(cls, params, message):
    """Checked by ``check_params`` (and ``fit``), not by ``__init__``; the error names the
    group and its field, in one line; the app says it as its config key
    (``refine.hard.max_iter``)."""
    refinement = cls(**params)  # stored as given
    with pytest.raises(ParameterError, match=f"^{message}") as err:
        refinement.check_params()
    assert err.value.param.split(".")[0] == next(iter(params))
    assert "refine." not in str(err.value) and "\n" not in str(err.value)
    assert str(err.value.renamed(f"refine.{err.value.param}")).startswith("refine.")


def test_parameters_set_after_construction_are_checked_by_fit():
    sym, u, _ = ring_walk(300, RING, 0)
    seq = SymbolSequence.build(sym, u, [300], 2, 6)
    with pytest.raises(ParameterError, match="growth.clone_factor must be a positive integer"):
        EMRefinement().set_params(growth={"clone_factor": 0}).fit(seq, np.arange(6))
    with pytest.raises(ParameterError, match="hard.pseudocount must be > 0"):
        CSCGRefinement().set_params(hard=CSCGRounds(pseudocount=-1.0)).fit(seq)


def test_a_sequence_head_keeps_the_episodes_it_covers():
    seq = SymbolSequence.build(np.arange(10) % 3, np.zeros(10), [4, 6], 1, 3)
    head = seq.head(7)
    assert head.T == 7 and head.lengths.tolist() == [4, 3] and head.n_ids == seq.n_ids
    assert seq.head(10) is seq
    has_prev, has_next = head.masks()
    assert has_prev.tolist() == [False, True, True, True, False, True, True]
    assert has_next.tolist() == [True, True, True, False, True, True, False]


def test_em_started_from_the_places_keeps_them():
    """A warm start from the right labelling of the ring: every state one place, so EM's
    rounds have nothing to move, merge or split."""
    sym, u, places = ring_walk(3000, RING, seed=0)
    seq = SymbolSequence.build(sym, u, [3000], 2, 6)
    fit = EMRefinement().fit(seq, np.arange(6), 0, init=(places, np.asarray(RING)))
    assert fit.info_["warm_start"] and fit.info_["stages"][0][0] == 3000
    assert fit.n_states_ == 8 and same_partition(fit.labels_, places)


def test_em_started_from_one_state_per_symbol_finds_the_aliased_places():
    """A warm start that has not told the aliased places apart (each symbol one state): the
    spare clones and the split test of the rounds on all steps separate them."""
    sym, u, places = ring_walk(3000, RING, seed=1)
    seq = SymbolSequence.build(sym, u, [3000], 2, 6)
    fit = EMRefinement().fit(seq, np.arange(6), 0, init=(sym, np.arange(6)))
    assert fit.n_states_ == 8 and adjusted_rand_score(places, fit.labels_) == 1.0


@pytest.mark.parametrize("init, message", [
    ((np.zeros(5, int), np.zeros(1, int)), "5 labels for 8 steps"),
    ((np.full(8, 3), np.arange(3)), "labels must be states 0..2"),
    ((np.zeros(8, int), np.zeros(1, int)), "does not emit the symbol"),
])
def test_a_bad_warm_start_is_refused_in_one_line(init, message):
    seq = SymbolSequence.build([0, 1, 2, 0, 1, 2, 0, 1], np.zeros(8, int), [8], 1, 3)
    with pytest.raises(ValueError, match=message):
        EMRefinement().fit(seq, np.arange(3), 0, init=init)


def _other(value):
    """A value of the same kind as ``value`` and different from it."""
    if isinstance(value, bool):
        return not value
    if isinstance(value, str):
        return value + "-other"
    if isinstance(value, float) and value == float("inf"):
        return 1.0
    return type(value)(value * 2 + 1)


@pytest.mark.parametrize("group", ["hard", "growth", "soft", "reading"])
def test_every_refine_setting_changed_from_its_default_is_in_the_maps_provenance(group):
    from dataclasses import fields, replace

    from topomap.core.refine.provenance import cscg_provenance, em_provenance
    from topomap.core.refine.settings import (
        CSCGRounds, Growth, HardRounds, Reading, RefineSettings)
    em = RefineSettings(hard=HardRounds(), soft=SoftRounds(), reading=Reading(), growth=Growth())
    cscg = RefineSettings(hard=CSCGRounds(), soft=SoftRounds(), reading=Reading())
    for settings, provenance in ((em, em_provenance), (cscg, cscg_provenance)):
        value = getattr(settings, group)
        if value is None:
            continue
        base = provenance(settings, "auto", True) if provenance is em_provenance else \
            provenance(settings, "auto")
        for f in fields(value):
            changed = replace(settings, **{group: replace(value, **{
                f.name: _other(getattr(value, f.name))})})
            text = provenance(changed, "auto", True) if provenance is em_provenance else \
                provenance(changed, "auto")
            assert text != base, f"{group}.{f.name} changed leaves the provenance as it was"


def test_settings_the_old_form_has_no_name_for_are_written_by_their_new_names():
    text = EMRefinement(growth={"cycle_start": "soft"}, reading={"settle": 0.0}).provenance()
    assert "changed=(growth.cycle_start='soft', reading.settle=0.0), settings=EMSettings(" in text
