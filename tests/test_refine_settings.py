"""The refinements' settings grouped by stage (topomap.core.refine.settings): small objects, each
field documented and checked by name; the names of before 0.3 still work with a warning, in
Python and in the config; map.json's text of a refinement is the one the version before wrote."""

import dataclasses
import inspect
import warnings

import numpy as np
import pytest
from sklearn.base import clone

from settings_helpers import field_docstrings
from topomap import MapLearner
from topomap.core.checks import ParameterError
from topomap.core.refine import settings as settings_module
from topomap.core.refine.methods import CSCGRefinement, EMRefinement
from topomap.core.refine.renamed import CSCG_RENAMED, EM_RENAMED, SOFT_FIELDS
from topomap.core.refine.settings import (CSCGRounds, Growth, HardRounds, Reading, SoftRounds,
                                          settings_of)
from topomap.core.refine.soft import SoftSettings

GROUPS = (HardRounds, CSCGRounds, Growth, SoftRounds, Reading)

#: map.json's ``info["refine"]`` as the version before the settings groups wrote it, for the
#: settings these tests give (each by its names of then and of now)
OLD_TEXT = {
    "em1": "EMRefinement(clone_factor=3, prefix=500, prefix_visits=20, max_rounds=4, "
           "guard=False, settings=EMSettings(row_prior=0.5, tol=0.0, max_iter=40, prune=0.0001, "
           "merge_threshold=6.63, split_z=3.09, spare=3, init_noise=1.0))",
    "em2": "EMRefinement(clone_factor=2, prefix=2000, prefix_visits=40, max_rounds=8, "
           "guard=True, budget='split', settle=0.01, accelerate='squarem', start='auto', "
           "first='rough', first_factor=2, first_iter=10, first_rtol=0.001, evidence='soft', "
           "soft=SoftSettings(rounds=2, detect=0.01, conf_warmup=10, stage_cap=10, "
           "read_share=0.0, observed=3.0, observed_in='all'), settings=EMSettings(row_prior=0.5,"
           " tol=1e-06, max_iter=50, prune=0.0001, merge_threshold=6.63, split_z=3.09, spare=2, "
           "init_noise=1.0))",
    "cscg1": "CSCGRefinement(clones_per_symbol=8, pseudocount=0.01, max_iter=30, tol=0.001, "
             "evidence='hard', soft=SoftSettings(rounds=1, observed=0.0))",
    "config_em": "EMRefinement(clone_factor=2, prefix=2000, prefix_visits=40, max_rounds=8, "
                 "guard=True, soft=SoftSettings(conf_warmup=10, stage_cap=10, observed=3.0), "
                 "settings=EMSettings(row_prior=0.5, tol=0.0, max_iter=40, prune=0.0001, "
                 "merge_threshold=6.63, split_z=3.09, spare=2, init_noise=1.0))",
}


# ---------------------------------------------------------------- the objects themselves
@pytest.mark.parametrize("cls", GROUPS)
def test_a_settings_object_fits_on_one_screen_and_documents_every_field(cls):
    """At most 60 lines (a screen) and 16 fields; every field followed by its docstring, which
    says what it does and, for a number, its unit in brackets (or what 0 / inf means)."""
    source = inspect.getsource(cls)
    assert len(source.splitlines()) <= 60 and len(dataclasses.fields(cls)) <= 16
    docs = field_docstrings(cls)
    assert set(docs) == {f.name for f in dataclasses.fields(cls)}
    for f in dataclasses.fields(cls):
        if f.type in ("int", "float"):
            assert "(" in docs[f.name] or "..." in docs[f.name], f.name


def test_every_default_lives_in_one_place():
    """The refinements' defaults are their settings objects' (no parameter repeats a field),
    and a knob of two stages is a field of each stage's object under one name."""
    for cls in (EMRefinement, CSCGRefinement):
        params = inspect.signature(cls).parameters
        fields = {f.name for group in cls._groups.values() for f in dataclasses.fields(group)}
        assert not fields & (set(params) - set(cls._groups))
        for name, group in cls._groups.items():
            assert params[name].default == group()
    shared = {f.name for f in dataclasses.fields(HardRounds)} & {
        f.name for f in dataclasses.fields(SoftRounds)}
    assert shared == {"row_prior", "tol", "max_iter", "accelerate", "prune", "spare"}
    assert (HardRounds().spare, SoftRounds().spare) == (2, 1)


@pytest.mark.parametrize("cls, value, message", [
    (HardRounds, {"max_iter": 0}, "hard.max_iter must be a positive integer, got 0"),
    (HardRounds, {"tol": "small"}, "hard.tol must be >= 0, got 'small'"),
    (Growth, {"first": "soon"}, "growth.first must be one of auto, rough, plain, got 'soon'"),
    (SoftRounds, {"prune_every": 1}, "soft.prune_every must be true or false, got 1"),
    (Reading, {"temperature": float("inf")},
     "reading.temperature must be >= 0 and finite, got inf"),
    (Reading, {"observed": 3.0}, "reading.observed is not a reading setting; the settings are "
                                 "detect, detect_iter"),
    (SoftRounds, Reading(), r"soft must be SoftRounds or a mapping of its fields, got Reading\("),
])
def test_a_bad_setting_is_refused_in_one_line_naming_its_group_and_field(cls, value, message):
    group = {HardRounds: "hard", Growth: "growth", SoftRounds: "soft", Reading: "reading"}[cls]
    with pytest.raises(ParameterError, match=f"^{message}") as err:
        settings_of(cls, value, group)
    assert "\n" not in str(err.value)


def test_the_learner_and_the_config_name_a_bad_setting_by_its_config_key():
    learner = MapLearner(refine=EMRefinement(hard={"max_iter": 0}))
    with pytest.raises(ParameterError, match="^refine.hard.max_iter must be a positive integer"):
        learner.check_params()
    from topomap.app.compose.command_line import compose
    from topomap.app.run.experiment import check_and_build

    cfg = compose(["refine=em", "refine.reading.floor=0.0"])
    with pytest.raises(ValueError, match=r"^refine.reading.floor must be in \(0, 1\), got 0.0"):
        check_and_build(cfg)


# ---------------------------------------------------------------- the names of before 0.3
def test_every_old_name_has_a_place_now():
    """Every old parameter and soft setting goes to a field of a group of its refinement (the
    old SoftSettings' stage caps to nowhere on CSCG, which never had growth stages)."""
    for cls, renamed in ((EMRefinement, EM_RENAMED), (CSCGRefinement, CSCG_RENAMED)):
        for old, new in renamed.items():
            if not new:
                assert cls is CSCGRefinement and old in ("soft.stage_cap", "soft.stage_rtol")
                continue
            group, name = new.split(".")
            assert name in {f.name for f in dataclasses.fields(cls._groups[group])}, old
    assert {f.name for f in dataclasses.fields(SoftSettings)} == set(SOFT_FIELDS)
    assert len(SOFT_FIELDS) == 29 and len([k for k in EM_RENAMED if "." not in k]) == 20


def _warned(make):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        out = make()
    return out, [str(w.message) for w in caught if w.category is FutureWarning]


@pytest.mark.parametrize("text, old, new", [
    ("em1", dict(max_iter=40, tol=0.0, spare=3, clone_factor=3, prefix=500, prefix_visits=20,
          max_rounds=4, guard=False),
     dict(hard={"max_iter": 40, "tol": 0.0, "spare": 3, "max_rounds": 4},
          growth={"clone_factor": 3, "prefix": 500, "prefix_visits": 20}, guard=False)),
    ("em2", dict(budget="split", settle=0.01, accelerate="squarem", start="auto", first="rough",
          first_factor=2, first_iter=10, first_rtol=0.001, evidence="soft",
          soft={"rounds": 2, "conf_warmup": 10, "stage_cap": 10, "observed": 3.0,
                "observed_in": "all", "read_share": 0.0, "detect": 0.01}),
     dict(hard={"settle": 0.01, "accelerate": "squarem"}, evidence="soft",
          growth={"budget": "split", "start": "auto", "first": "rough", "first_factor": 2,
                  "first_iter": 10, "first_rtol": 0.001, "stage_cap": 10},
          soft={"rounds": 2}, reading={"conf_warmup": 10, "temperature": 3.0,
                                       "observed_in": "all", "read_share": 0.0,
                                       "detect": 0.01})),
])
def test_old_python_names_warn_and_set_the_new_ones(text, old, new):
    """Each old name warns once, naming its new place; the refinement is the one the new names
    give (the same parameters, so the same fit and the same clone), and map.json's text is the
    version before's for those settings."""
    em, messages = _warned(lambda: EMRefinement(**old))
    moved = [k for k in old if k not in ("evidence", "guard", "soft")] + [
        f"soft.{k}" for k in old.get("soft", {}) if k != "rounds"]
    assert len(messages) == len(moved)
    for name, message in zip(moved, messages):
        assert message.startswith(f"EMRefinement: {name} was renamed {EM_RENAMED[name]} in 0.3")
        assert f"refine.{EM_RENAMED[name]}" in message
    assert em.settings() == EMRefinement(**new).settings()
    assert sorted(em.get_params()) == ["evidence", "growth", "guard", "hard", "reading", "soft"]
    assert clone(em).settings() == em.settings()
    assert em.provenance() == EMRefinement(**new).provenance()
    assert em.provenance() == OLD_TEXT[text]


def test_old_cscg_names_and_an_old_soft_settings_object_still_work():
    cscg, messages = _warned(lambda: CSCGRefinement(
        clones_per_symbol=8, pseudocount=0.01, max_iter=30, tol=1e-3, evidence="hard",
        soft=SoftSettings(rounds=1, observed=0.0, stage_cap=3)))
    assert cscg.provenance() == OLD_TEXT["cscg1"]  # its stage cap never did anything
    assert cscg.settings().hard == CSCGRounds(8, 0.01, 30, 1e-3)
    assert any(m.startswith("SoftSettings was split in 0.3") for m in messages)
    assert any("soft.stage_cap has no effect" in m for m in messages)
    assert any("soft.observed was renamed reading.temperature" in m for m in messages)


def test_set_params_takes_the_old_names_too_and_refuses_two_values_for_one_setting():
    em, messages = _warned(lambda: EMRefinement().set_params(max_iter=40,
                                                             soft={"conf_warmup": 10}))
    assert em.get_params()["hard"] == {"max_iter": 40}
    assert em.get_params()["reading"] == {"conf_warmup": 10} and em.get_params()["soft"] == {}
    assert len(messages) == 2
    with pytest.raises(ParameterError, match="^max_iter is the old name of hard.max_iter: give "
                                             "hard.max_iter only"):
        EMRefinement(max_iter=40, hard={"max_iter": 30})
    with pytest.raises(TypeError, match="unexpected keyword argument 'max_iters'"):
        EMRefinement(max_iters=40)
    with pytest.warns(FutureWarning):  # the same value twice is one value
        assert EMRefinement(max_iter=40, hard={"max_iter": 40}).settings().hard.max_iter == 40


def test_a_fit_under_old_names_is_the_fit_under_new_ones():
    from test_soft_refine import RING, _ring_walk, _seq

    seq = _seq(*_ring_walk(misread=0.06, seed=1)[:3])
    with pytest.warns(FutureWarning):
        old = EMRefinement(max_iter=30, soft={"conf_warmup": 2, "rounds": 2}).fit(seq, RING, 0)
    new = EMRefinement(hard={"max_iter": 30}, reading={"conf_warmup": 2},
                       soft={"rounds": 2}).fit(seq, RING, 0)
    np.testing.assert_array_equal(old.labels_, new.labels_)
    assert old.info_ == new.info_ and old.settings_ == new.settings_


def test_the_old_soft_settings_class_and_its_checker_still_work():
    with pytest.warns(FutureWarning, match="SoftSettings was split in 0.3"):
        old = SoftSettings(conf_warmup=10, observed=2.0)
    assert (old.rounds, old.conf_warmup, old.observed) == (3, 10, 2.0)
    from topomap.core.refine.soft import soft_settings

    with pytest.warns(FutureWarning, match="soft_settings goes in 0.4"):
        with pytest.raises(ParameterError, match="^soft.floor must be in"):
            soft_settings({"floor": 2.0})


# ---------------------------------------------------------------- the config
def _made(overrides):
    from topomap.app.compose.command_line import compose
    from topomap.app.compose.registry import Registry
    from topomap.app.run.experiment import _as_dict

    registry = Registry.load(entry_points_group=None)
    return registry.make("refine", _as_dict(compose(overrides, registry))["refine"])


def test_old_config_keys_warn_and_set_the_new_keys_typed_as_the_new_keys():
    """``refine.tol=0`` is ``refine.hard.tol=0``, the float 0.0 (as the old typed key gave),
    so map.json's text is the version before's; each old key warns, naming the new one."""
    old = ["refine=em", "refine.tol=0", "refine.max_iter=40", "refine.first_rtol=inf",
           "refine.soft.observed=3", "refine.soft.conf_warmup=10", "refine.soft.stage_cap=10"]
    new = ["refine=em", "refine.hard.tol=0", "refine.hard.max_iter=40",
           "refine.reading.temperature=3", "refine.reading.conf_warmup=10",
           "refine.growth.stage_cap=10"]
    em, messages = _warned(lambda: _made(old))
    assert em.provenance() == _made(new).provenance() == OLD_TEXT["config_em"]
    assert ("refine.soft.observed was renamed refine.reading.temperature in 0.3; the old key "
            "goes in 0.4") in messages
    assert "refine.max_iter was renamed refine.hard.max_iter in 0.3; the old key goes in 0.4" \
        in messages and len(messages) == 6
    with pytest.raises(ValueError, match="^refine.max_iter is the old key of "
                                         "refine.hard.max_iter: give refine.hard.max_iter only"):
        _made(["refine=em", "refine.max_iter=40", "refine.hard.max_iter=30"])


def test_old_config_keys_belong_to_their_component():
    from topomap.app.compose.command_line import compose

    with pytest.raises(ValueError, match="refine.clone_factor is not a key of refine=cscg: it "
                                         "belongs to refine=em"):
        compose(["refine=cscg", "refine.clone_factor=3"])
    with pytest.raises(ValueError, match="unknown config key 'refine.maxiter'"):
        compose(["refine=em", "refine.maxiter=3"])
    cscg, messages = _warned(lambda: _made(["refine=cscg", "refine.max_iter=30"]))
    assert cscg.settings().hard.max_iter == 30 and len(messages) == 1


def test_the_config_shows_the_groups_and_no_old_key():
    from topomap.app.compose.command_line import compose

    refine = compose(["refine=em"]).refine
    assert list(refine) == ["component", "evidence", "guard", "hard", "growth", "soft",
                            "reading"]
    assert not set(refine) & {k for k in EM_RENAMED if "." not in k}
    assert settings_module.Reading().temperature == refine.reading.temperature == 6.0
