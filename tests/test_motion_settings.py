"""The continuous-motion settings grouped by stage (topomap.core.motion.settings): a handful of
fields at the top, two small groups, each field documented and checked by name; the flat names
of before 0.3 still work with a warning naming the new one, in Python and on the command line."""

import dataclasses
import inspect
import textwrap
import warnings

import pytest

from settings_helpers import field_docstrings
from topomap import MapLearner
from topomap.core.checks import ParameterError
from topomap.core.motion import odometry
from topomap.core.motion.renamed import MOTION_RENAMED
from topomap.core.motion.settings import (CheckSettings, MotionSettings, PlaceSettings,
                                          motion_settings)

#: the 22 fields of the flat MotionSettings before 0.3, in their order then
FLAT = ("mode", "min_run", "min_steps", "gates", "weight", "pull", "max_return", "holdout",
        "margin", "far", "n_init", "folds", "fallback_variance", "min_gain", "votes",
        "min_copies", "confidence", "block_runs", "min_purity", "loose_return", "loose_weight",
        "check")

#: the fields of the groups that have no flat name of before 0.3
SINCE_0_3 = ("graph_gate",)

#: a valid value other than the default for every old name
OTHER = {"gates": (2.0, 4.0), "weight": 0.7, "pull": 0.3, "max_return": 0.4,
         "loose_return": 0.3, "loose_weight": 0.6, "n_init": 2, "fallback_variance": 0.1,
         "holdout": 0.3, "margin": 0.8, "far": 3.0, "folds": 3, "min_gain": 0.05, "votes": 0,
         "min_copies": 2.0, "confidence": 1.5, "block_runs": 20.0, "min_purity": 0.1,
         "check": "crossfit"}


def _names(cls):
    return [f.name for f in dataclasses.fields(cls)]


def _warned(make):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        out = make()
    return out, [str(w.message) for w in caught if issubclass(w.category, FutureWarning)]


# ---------------------------------------------------------------- the objects themselves
def test_the_settings_are_a_handful_at_the_top_and_two_groups_by_stage():
    assert _names(MotionSettings) == ["mode", "min_run", "min_steps", "scan_odometry", "places",
                                      "check"]
    assert _names(PlaceSettings) == ["gates", "weight", "pull", "max_return", "loose_return",
                                     "loose_weight", "n_init", "fallback_variance", "graph_gate"]
    assert _names(CheckSettings) == ["rule", "holdout", "margin", "far", "folds", "min_gain",
                                     "votes", "min_copies", "confidence", "block_runs",
                                     "min_purity"]
    # every flat field of before has one place now; the groups' other fields came after 0.3
    top = {"mode", "min_run", "min_steps"}
    assert set(FLAT) == top | set(MOTION_RENAMED)
    assert sorted(MOTION_RENAMED.values()) == sorted(
        [f"places.{n}" for n in _names(PlaceSettings) if n not in SINCE_0_3]
        + [f"check.{n}" for n in _names(CheckSettings)])
    assert MotionSettings().places == PlaceSettings() and MotionSettings().check == CheckSettings()


@pytest.mark.parametrize("cls", [MotionSettings, PlaceSettings, CheckSettings])
def test_a_settings_object_fits_on_one_screen_and_documents_every_field(cls):
    """At most 60 lines of source and 12 fields, a repr of under 40 lines of 100 characters;
    every field followed by its docstring, a number's naming its unit in brackets."""
    source = inspect.getsource(cls)
    assert len(source.splitlines()) <= 60 and len(dataclasses.fields(cls)) <= 12
    assert len(textwrap.wrap(repr(cls()), 100)) < 40
    docs = field_docstrings(cls)
    assert set(docs) == set(_names(cls))
    for f in dataclasses.fields(cls):
        if f.type in ("int", "float", "tuple[float, ...]"):
            assert "(" in docs[f.name], f.name


def test_a_group_given_as_a_mapping_is_that_group():
    s = MotionSettings(places={"gates": [2.0, 4.0]}, check={"rule": "crossfit"})
    assert s.places == PlaceSettings(gates=(2.0, 4.0))
    assert s.check == CheckSettings(rule="crossfit")
    assert motion_settings({"places": {"gates": [2.0, 4.0]}, "check": {"rule": "crossfit"}}) == s
    assert hash(s) == hash(MotionSettings(places=PlaceSettings(gates=(2.0, 4.0)),
                                          check=CheckSettings(rule="crossfit")))


def test_defaults_the_code_repeats_are_the_settings_own():
    sig = inspect.signature
    assert sig(odometry.action_vectors).parameters["max_return"].default == \
        PlaceSettings().max_return
    assert sig(odometry.odometric_positions).parameters["pull"].default == PlaceSettings().pull


@pytest.mark.parametrize("value, message", [
    ({"check": {"holdout": 1.0}}, r"motion.check.holdout must be a number in \[0, 1\), got 1.0"),
    ({"check": {"rule": "cross"}}, "motion.check.rule must be one of bootstrap, coverage, crossfit, folds, got "
                                   "'cross'"),
    ({"places": {"gates": []}}, r"motion.places.gates must be a non-empty list of positive "
                                r"numbers, got \(\)"),
    ({"places": {"pull": 2.0}}, "motion.places.pull must be at most 1, got 2.0"),
    ({"places": {"graph_gate": -1.0}}, "motion.places.graph_gate must be a number >= 0, got -1.0"),
    ({"check": {"holdot": 0.3}}, "motion.check.holdot is not a motion.check setting; the "
                                 "settings are rule, holdout"),
    ({"check": 0.3}, "motion.check must be CheckSettings or a mapping of its fields, got 0.3"),
    ({"min_run": 0}, "motion.min_run must be a positive number, got 0"),
])
def test_a_bad_setting_is_refused_in_one_line_naming_its_group_and_field(value, message):
    with pytest.raises(ParameterError, match=f"^{message}") as err:
        motion_settings(value)
    assert "\n" not in str(err.value)
    with pytest.raises(ParameterError, match=f"^{message}"):
        MapLearner(motion=value).check_params()


# ---------------------------------------------------------------- the names of before 0.3
@pytest.mark.parametrize("old", sorted(OTHER))
def test_an_old_name_warns_naming_the_new_one_and_sets_it(old):
    new = MOTION_RENAMED[old]
    group, name = new.split(".")
    expected = MotionSettings(**{group: {name: OTHER[old]}})
    assert getattr(getattr(expected, group), name) == OTHER[old]
    text = (f"motion.{old} was renamed motion.{new} in 0.3 (the config's learner.motion.{new}); "
            "the old name goes in 0.4")
    made, messages = _warned(lambda: MotionSettings(**{old: OTHER[old]}))
    assert made == expected and messages == [text]
    checked, messages = _warned(lambda: motion_settings({old: OTHER[old]}))
    assert checked == expected and messages == [text]


def test_old_names_join_the_groups_given_and_refuse_a_second_value():
    s, messages = _warned(lambda: MotionSettings(holdout=0.3, check="crossfit", weight=0.7,
                                                 places=PlaceSettings(pull=0.3)))
    assert s == MotionSettings(places={"weight": 0.7, "pull": 0.3},
                               check={"rule": "crossfit", "holdout": 0.3})
    assert len(messages) == 3
    with pytest.raises(ParameterError, match="^motion.holdout is the old name of "
                                             "motion.check.holdout: give motion.check.holdout "
                                             "only$"):
        MotionSettings(holdout=0.3, check={"holdout": 0.2})
    with pytest.raises(ParameterError, match="^motion.weight is the old name of "
                                             "motion.places.weight"):
        motion_settings({"weight": 0.6, "places": {"weight": 0.5}})
    # the same value twice is one value
    assert _warned(lambda: motion_settings({"weight": 0.6, "places": {"weight": 0.6}}))[0] == \
        MotionSettings(places={"weight": 0.6})


def test_a_fit_under_old_names_is_the_fit_under_new_ones():
    import numpy as np

    rng = np.random.default_rng(0)
    x = np.cumsum(rng.choice([-1.0, 1.0], 1500)) * 0.1
    X = np.column_stack([np.cos(x), np.sin(x)]) + 0.01 * rng.standard_normal((1500, 2))
    u = (np.diff(x, append=x[-1]) > 0).astype(int)
    kw = dict(n_clusters=4, n_states=8, random_state=0)
    old, _ = _warned(lambda: MapLearner(motion={"mode": "continuous", "holdout": 0.3,
                                                "weight": 0.7}, **kw).fit(X, u))
    new = MapLearner(motion={"mode": "continuous", "check": {"holdout": 0.3},
                             "places": {"weight": 0.7}}, **kw).fit(X, u)
    assert hasattr(old, "motion_info_")  # the continuous path ran
    recorded = dataclasses.asdict(motion_settings(new.motion))
    del recorded["scan_odometry"]  # recorded only where off (the maps of before keep their bytes)
    assert old.map_.info["motion"] == recorded
    assert old.map_.info["motion"]["check"]["holdout"] == 0.3
    assert old.map_.to_dict() == new.map_.to_dict()


# ---------------------------------------------------------------- the config
def _learner_motion(overrides):
    from topomap.app.compose.command_line import compose
    from topomap.app.run.experiment import _as_dict

    return _as_dict(compose(overrides))["learner"]["motion"]


def test_the_config_shows_the_groups_and_goes_round_to_the_same_settings():
    motion = _learner_motion([])
    assert list(motion) == ["mode", "min_run", "min_steps", "scan_odometry", "places", "check"]
    assert motion_settings(motion) == MotionSettings()
    assert not set(motion) & (set(MOTION_RENAMED) - {"check"})
    given = _learner_motion(["learner.motion.check.rule=crossfit",
                             "learner.motion.places.gates=[2.0,4.0]",
                             "learner.motion.check.holdout=0.3"])
    assert motion_settings(given) == MotionSettings(places={"gates": (2.0, 4.0)},
                                                    check={"rule": "crossfit", "holdout": 0.3})


def test_old_config_keys_warn_and_set_the_new_keys():
    old, messages = _warned(lambda: _learner_motion(
        ["learner.motion.holdout=0.3", "learner.motion.check=crossfit",
         "learner.motion.gates=[2.0,4.0]"]))
    new = _learner_motion(["learner.motion.check.holdout=0.3",
                           "learner.motion.check.rule=crossfit",
                           "learner.motion.places.gates=[2.0,4.0]"])
    assert old == new
    assert ("learner.motion.check was renamed learner.motion.check.rule in 0.3; the old key goes "
            "in 0.4") in messages and len(messages) == 3
    with pytest.raises(ValueError, match="^learner.motion.holdout is the old key of "
                                         "learner.motion.check.holdout: give "
                                         "learner.motion.check.holdout only$"):
        _learner_motion(["learner.motion.holdout=0.3", "learner.motion.check.holdout=0.2"])


@pytest.mark.parametrize("override, message", [
    ("learner.motion.check.holdout=abc", "learner.motion.check.holdout=abc is not a number"),
    ("learner.motion.check.holdot=0.3", "unknown config key 'learner.motion.check.holdot'; did "
                                        "you mean learner.motion.check.holdout?"),
])
def test_a_bad_config_key_of_a_group_is_named_in_one_line(override, message):
    with pytest.raises(ValueError, match=f"^{message}"):
        _learner_motion([override])


def test_a_bad_config_value_is_named_by_its_key():
    from topomap.app.compose.command_line import compose
    from topomap.app.run.experiment import check_and_build

    with pytest.raises(ParameterError, match=r"^motion.check.holdout must be a number in \[0, "
                                             r"1\), got 1.0$"):
        check_and_build(compose(["learner.motion.check.holdout=1.0"]))
