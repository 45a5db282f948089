"""The refinements' settings under their names before 0.3, accepted until 0.4 with a
``FutureWarning`` naming the new one.

Until 0.3 :class:`~topomap.core.refine.methods.EMRefinement` took every knob of its hard rounds
and first stages as a parameter of its own (``EMRefinement(max_iter=40)``, the config's
``refine.max_iter``), :class:`~topomap.core.refine.methods.CSCGRefinement` its four, and one
:class:`SoftSettings` of 29 fields (``refine.soft.<key>``) held the soft rounds', the reading's
and two of the growth stages'.  :data:`EM_RENAMED` and :data:`CSCG_RENAMED` say where each went
(``"max_iter": "hard.max_iter"``, ``"soft.observed": "reading.temperature"``);
:func:`fold_renamed` moves values given under the old names to the new ones.  The file format
keeps the old names: :mod:`topomap.core.refine.provenance` writes them.
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping
from dataclasses import field, fields, make_dataclass, replace

from ..checks import ParameterError
from .settings import Growth, Reading, SoftRounds

__all__ = ["SoftSettings", "SOFT_FIELDS", "EM_RENAMED", "CSCG_RENAMED", "fold_renamed"]

#: every field of the old :class:`SoftSettings`, in its order, and where it lives now
SOFT_FIELDS = {
    "rounds": "soft.rounds", "min_steps": "soft.min_steps", "spare": "soft.spare",
    "max_iter": "soft.max_iter", "tol": "soft.tol", "row_prior": "soft.row_prior",
    "conf_diag": "reading.conf_diag", "conf_off": "reading.conf_off",
    "init_error": "reading.init_error", "floor": "reading.floor", "prune": "soft.prune",
    "detect": "reading.detect", "prune_every": "soft.prune_every",
    "clone_prior": "reading.clone_prior", "twin": "soft.twin", "twin_merge": "soft.twin_merge",
    "conf_warmup": "reading.conf_warmup", "detect_iter": "reading.detect_iter",
    "stage_cap": "growth.stage_cap", "stage_rtol": "growth.stage_rtol", "rtol": "soft.rtol",
    "accelerate": "soft.accelerate", "prune_loose": "soft.prune_loose",
    "loose_below": "soft.loose_below", "label_every": "soft.label_every",
    "label_tol": "soft.label_tol", "read_share": "reading.read_share",
    "observed": "reading.temperature", "observed_in": "reading.observed_in",
}

_SOFT_MOVED = {f"soft.{old}": new for old, new in SOFT_FIELDS.items() if new != f"soft.{old}"}

#: ``EMRefinement``'s old parameters (and old soft settings) and their new places
EM_RENAMED = {
    **{k: f"growth.{k}" for k in ("clone_factor", "prefix", "prefix_visits", "budget", "start",
                                  "first", "first_factor", "first_iter", "first_rtol")},
    **{k: f"hard.{k}" for k in ("max_rounds", "row_prior", "tol", "max_iter", "settle",
                                "prune", "merge_threshold", "split_z", "spare", "init_noise",
                                "accelerate")},
    **_SOFT_MOVED,
}

#: ``CSCGRefinement``'s; "" for an old soft setting it never used (it has no growth stages)
CSCG_RENAMED = {
    **{k: f"hard.{k}" for k in ("clones_per_symbol", "pseudocount", "max_iter", "tol")},
    **{old: ("" if new.startswith("growth.") else new) for old, new in _SOFT_MOVED.items()},
}


def _legacy_soft(self):
    warnings.warn("SoftSettings was split in 0.3 into SoftRounds (soft=, refine.soft), Reading "
                  "(reading=, refine.reading) and Growth's stage_cap and stage_rtol (growth=, "
                  "refine.growth); SoftSettings goes in 0.4", FutureWarning, stacklevel=3)


def _old_field(old: str, new: str):
    group, name = new.split(".")
    cls = {"soft": SoftRounds, "reading": Reading, "growth": Growth}[group]
    f = next(f for f in fields(cls) if f.name == name)
    return old, f.type, field(default=f.default)


SoftSettings = make_dataclass(
    "SoftSettings", [_old_field(old, new) for old, new in SOFT_FIELDS.items()], frozen=True,
    namespace={"__post_init__": _legacy_soft, "__module__": __name__, "__doc__": (
        "The soft settings before 0.3, all in one (deprecated): ``soft=SoftSettings(...)`` "
        "still works until 0.4, each field going where :data:`SOFT_FIELDS` says.")})


def _warn(owner: str, old: str, new: str, stacklevel: int) -> None:
    if new:
        msg = (f"{owner}: {old} was renamed {new} in 0.3 (the config's refine.{new}); the old "
               "name goes in 0.4")
    else:
        msg = f"{owner}: {old} has no effect (it never had) and goes in 0.4; leave it out"
    warnings.warn(msg, FutureWarning, stacklevel=stacklevel + 2)


def _set(current, cls, group: str, name: str, value, old: str):
    """``current`` (a ``cls`` or a mapping of its fields) with ``name`` set to ``value``, the
    value given under the old name ``old``; a :class:`ParameterError` if ``current`` sets it
    to another value already."""
    default = getattr(cls(), name)
    if isinstance(current, Mapping):
        given, out = current.get(name, default), {**current, name: value}
    elif isinstance(current, cls):
        given = getattr(current, name)
        out = {name: value} if current == cls() else replace(current, **{name: value})
    else:
        raise ParameterError(group, f"must be {cls.__name__} or a mapping of its fields, got "
                                    f"{current!r}")
    if given != default and given != value:
        raise ParameterError(old, f"is the old name of {group}.{name}: give {group}.{name} only")
    return out


def fold_renamed(owner: str, classes: dict, groups: dict, old: dict, renamed: dict, *,
                 stacklevel: int = 2) -> dict:
    """The settings groups of ``owner`` (a refinement's class name), given as ``groups``
    (``{"hard": ..., "soft": ...}``; ``classes``: the settings class of each), with the values
    given under old names moved to the new ones, a ``FutureWarning`` for each: ``old``, the old
    parameters given, and the old settings in ``groups["soft"]`` (a :class:`SoftSettings`, or a
    mapping with old keys).  ``renamed`` maps every old name to its new place
    (:data:`EM_RENAMED`).  Groups with nothing to move are returned as given (the same
    objects).  ``stacklevel``: the caller the warnings name, counted from the caller of this
    function (1)."""
    for name in old:
        if name not in renamed or "." in name:
            raise TypeError(f"{owner}.__init__() got an unexpected keyword argument {name!r}")
    moves = list(old.items())
    soft = groups.get("soft")
    if isinstance(soft, SoftSettings):
        soft = {f.name: getattr(soft, f.name) for f in fields(soft)
                if getattr(soft, f.name) != f.default}
    if isinstance(soft, Mapping) and any(f"soft.{k}" in renamed for k in soft):
        moves += [(f"soft.{k}", v) for k, v in soft.items() if f"soft.{k}" in renamed]
        soft = {k: v for k, v in soft.items() if f"soft.{k}" not in renamed}
    out = dict(groups, soft=soft) if soft is not groups.get("soft") else dict(groups)
    for old_name, value in moves:
        new = renamed[old_name]
        _warn(owner, old_name, new, stacklevel)
        if new:
            group, name = new.split(".")
            out[group] = _set(out[group], classes[group], group, name, value, old_name)
    return out

