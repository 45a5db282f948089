"""The continuous-motion settings under their names before 0.3, accepted until 0.4 with a
``FutureWarning`` naming the new one.

Until 0.3 :class:`~topomap.core.motion.settings.MotionSettings` held all its 22 settings flat
(``MotionSettings(holdout=0.3)``, the config's ``learner.motion.holdout``; ``check`` was the
check's rule).  :data:`MOTION_RENAMED` says where each went (``"holdout": "check.holdout"``,
``"check": "check.rule"``); :func:`fold_motion` moves values given under the old names to the
new ones, and :func:`moved_override` does it for a command line's key.
"""

from __future__ import annotations

import dataclasses
import re
import warnings
from collections.abc import Mapping

from ..checks import ParameterError

__all__ = ["MOTION_RENAMED", "fold_motion", "moved_override"]

#: every flat setting of before 0.3 that moved into a group, and where it lives now
MOTION_RENAMED = {
    **{k: f"places.{k}" for k in ("gates", "weight", "pull", "max_return", "loose_return",
                                  "loose_weight", "n_init", "fallback_variance")},
    **{k: f"check.{k}" for k in ("holdout", "margin", "far", "folds", "min_gain", "votes",
                                 "min_copies", "confidence", "block_runs", "min_purity")},
    "check": "check.rule",
}


def _is_old(key: str, value) -> bool:
    """Whether ``key=value`` of a motion mapping is a setting under its old name (``check`` is,
    given the rule as text; as a group it is the new name)."""
    return key in MOTION_RENAMED and (key != "check" or isinstance(value, str))


def _warning(old: str, new: str) -> str:
    return (f"motion.{old} was renamed motion.{new} in 0.3 (the config's learner.motion.{new}); "
            "the old name goes in 0.4")


def _set(group, name: str, value, old: str, new: str):
    """``group`` (absent, a mapping or a settings object) with ``name`` set to ``value``; a
    :class:`ParameterError` naming the old key where ``group`` sets it to another value."""
    if group is None:
        return {name: value}
    if isinstance(group, Mapping):
        given, out = group.get(name, value), {**group, name: value}
    elif dataclasses.is_dataclass(group) and not isinstance(group, type):
        given = getattr(group, name)
        if given == getattr(type(group)(), name):
            given = value
        out = dataclasses.replace(group, **{name: value})
    else:
        return group  # not a group: its own check names it
    if given != value:
        raise ParameterError(f"motion.{old}", f"is the old name of motion.{new}: give "
                             f"motion.{new} only")
    return out


def fold_motion(value: Mapping, stacklevel: int = 2) -> dict:
    """``value`` (the fields of a ``MotionSettings``) with the settings given under their old
    names moved into their groups, a ``FutureWarning`` for each (``stacklevel``: the caller it
    names, counted from this function's caller); ``value`` itself where none is old."""
    old = [(k, v) for k, v in value.items() if _is_old(k, v)]
    if not old:
        return value
    out = {k: v for k, v in value.items() if not _is_old(k, v)}
    for key, v in old:
        new = MOTION_RENAMED[key]
        warnings.warn(_warning(key, new), FutureWarning, stacklevel=stacklevel + 1)
        group, name = new.split(".")
        out[group] = _set(out.get(group), name, v, key, new)
    return out


_OLD_KEY = re.compile(r"^([+~]*)learner\.motion\.(\w+)(=.*)?$", re.DOTALL)


def moved_override(word: str) -> str:
    """A command line's word with an old key (``learner.motion.holdout=0.3``) under its new one
    (``learner.motion.check.holdout=0.3``), with a ``FutureWarning``; any other word as it is."""
    match = _OLD_KEY.match(word)
    if match is None or match.group(2) not in MOTION_RENAMED:
        return word
    prefix, old, rest = match.groups()
    new = MOTION_RENAMED[old]
    warnings.warn(f"learner.motion.{old} was renamed learner.motion.{new} in 0.3; the old key "
                  "goes in 0.4", FutureWarning, stacklevel=3)
    return f"{prefix}learner.motion.{new}{rest or ''}"
