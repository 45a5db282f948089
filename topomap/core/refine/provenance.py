"""The text map.json stores as ``info["refine"]``: a built-in refinement and its settings in the
file's fixed form.

The form is part of the file format and predates the settings groups of
:mod:`topomap.core.refine.settings`, so it keeps the names of before 0.3: ``refine=em``'s
hard-round knobs as ``settings=EMSettings(...)`` (a label, not a class), its first-stage knobs
flat, and every soft-round, reading and growth-cap setting changed from its default as one
``soft=SoftSettings(...)`` (:data:`~topomap.core.refine.renamed.SOFT_FIELDS` gives the old
names and their order).  A setting the old form has no name for (``growth.cycle_start``,
``reading.settle``), changed from its default, is written last by its new name, as
``changed=(growth.cycle_start='soft')``, so that every setting that changes a map is in its file.
The same effective settings give the same text as before 0.3.
"""

from __future__ import annotations

from dataclasses import fields

from .renamed import SOFT_FIELDS
from .settings import Growth, HardRounds, RefineSettings

__all__ = ["em_provenance", "cscg_provenance", "soft_provenance", "changed_provenance"]

#: the knobs of every EM round, in the order ``settings=EMSettings(...)`` lists them
EM_ROUND = ("row_prior", "tol", "max_iter", "prune", "merge_threshold", "split_z", "spare",
            "init_noise")

#: the growth settings written only when changed, in the order they are written
_FIRST = ("first", "first_factor", "first_iter", "first_rtol")

#: the settings the old form writes by its own names (``<group>.<field>``)
_OLD_FORM = frozenset(
    [f"hard.{k}" for k in (*EM_ROUND, "settle", "accelerate", "max_rounds", "clones_per_symbol",
                           "pseudocount")]
    + [f"growth.{k}" for k in (*_FIRST, "budget", "start", "clone_factor", "prefix",
                               "prefix_visits")]
    + list(SOFT_FIELDS.values()))


def changed_provenance(settings: RefineSettings) -> str:
    """``changed=(<group>.<field>=<value>, ...)``: the settings changed from their defaults that
    the old form has no name for, in the groups' field order ("" for none)."""
    changed = []
    for group in ("hard", "growth", "soft", "reading"):
        value = getattr(settings, group)
        if value is None:
            continue
        default = type(value)()
        changed += [f"{group}.{f.name}={getattr(value, f.name)!r}" for f in fields(value)
                    if f"{group}.{f.name}" not in _OLD_FORM
                    and getattr(value, f.name) != getattr(default, f.name)]
    return f"changed=({', '.join(changed)})" if changed else ""


def soft_provenance(settings: RefineSettings) -> str:
    """``soft=SoftSettings(...)`` naming, by their old names, the settings of the old
    ``SoftSettings`` changed from their defaults ("" for none)."""
    changed = []
    for old, new in SOFT_FIELDS.items():
        group, name = new.split(".")
        value = getattr(settings, group)
        if value is not None and getattr(value, name) != getattr(type(value)(), name):
            changed.append(f"{old}={getattr(value, name)!r}")
    return f"soft=SoftSettings({', '.join(changed)})" if changed else ""


def em_provenance(settings: RefineSettings, evidence: str, guard) -> str:
    """``EMRefinement(...)``'s text (module docstring)."""
    hard, growth = settings.hard, settings.growth
    hard0, growth0 = HardRounds(), Growth()
    rounds = ", ".join(f"{k}={getattr(hard, k)!r}" for k in EM_ROUND)
    changed = "" if growth.budget == growth0.budget else f"budget={growth.budget!r}, "
    changed += f"settle={hard.settle!r}, " if hard.settle else ""
    changed += "" if hard.accelerate == hard0.accelerate else f"accelerate={hard.accelerate!r}, "
    changed += "" if growth.start == growth0.start else f"start={growth.start!r}, "
    for k in _FIRST:
        value = getattr(growth, k)
        changed += "" if value == getattr(growth0, k) else f"{k}={value!r}, "
    changed += "" if evidence == "auto" else f"evidence={evidence!r}, "
    for part in (soft_provenance(settings), changed_provenance(settings)):
        changed += f"{part}, " if part else ""
    return (f"EMRefinement(clone_factor={growth.clone_factor}, prefix={growth.prefix}, "
            f"prefix_visits={growth.prefix_visits}, max_rounds={hard.max_rounds}, "
            f"guard={bool(guard)}, {changed}settings=EMSettings({rounds}))")


def cscg_provenance(settings: RefineSettings, evidence: str) -> str:
    """``CSCGRefinement(...)``'s text: its four knobs, then ``evidence`` and ``soft`` only where
    changed."""
    hard = settings.hard
    soft = ", ".join(p for p in (soft_provenance(settings), changed_provenance(settings)) if p)
    return (f"CSCGRefinement(clones_per_symbol={int(hard.clones_per_symbol)}, "
            f"pseudocount={float(hard.pseudocount)}, max_iter={int(hard.max_iter)}, "
            f"tol={float(hard.tol)}"
            f"{'' if evidence == 'auto' else f', evidence={evidence!r}'}"
            f"{', ' + soft if soft else ''})")
