"""The held-out check's verdict decided again from the folds a run recorded: would a stricter
rule on the same held-out parts have kept the places where they lose on the new walk?

    python benchmarks/bench_continuous_verdicts.py run1.jsonl run2.jsonl --rules each2 maj3

Reads the rows of ``bench_continuous.py`` logs with the routes ``views``, ``weight1`` (positions
at weight 1) and ``weight05`` (weight 0.5) -- or ``shipped`` where ``weight05`` is missing, as a
run of ``--routes views weight1 shipped`` leaves it -- and puts the default together from them:
where the odometry is loose (``motion.places.loose_return``) the places weighed half when the check
keeps them, else those at weight 1 when it keeps them (the second try), else the view clusters;
elsewhere those at weight 1 or the view clusters. Each rule re-decides a recorded check
(``motion.check``: its folds' misplaced shares, the pooled shares, the vote); a check that gives
way is scored at the view clusters' figure (the fallback places a walk where the views do, to
the third digit). Rules (``gain``: a fold's views' misplaced share less the places'):

* ``default`` -- the check as it is (the pooled share, or the vote);
* ``each2`` -- and each of the two pooled folds' gain at least ``motion.check.min_gain``;
* ``each2_pos`` -- and each of the two pooled folds' gain above zero;
* ``maj3`` -- and at least two of the three folds' gain at least ``motion.check.min_gain``;
* ``all3`` -- and all three folds' gain at least ``motion.check.min_gain``;
* ``no_vote`` -- the pooled share alone.

Printed per rule and per (setting, seeds 0-4 or 0-2 / 5-6): the walks more than 1 % above the
views and the wins (5 % or more below them), and every walk whose figure the rule changes.
"""

from __future__ import annotations

import argparse
import collections
import json

from topomap.core.motion import MotionSettings

ST = MotionSettings()


def _gains(c) -> list:
    return [f["misplaced"]["views"] - f["misplaced"]["places"] for f in c["folds"]]


def _pooled(c) -> bool:
    p, v = c["mean_misplaced"]["places"], c["mean_misplaced"]["views"]
    return p < v and p <= ST.check.margin * v and v - p >= ST.check.min_gain


RULES = {
    "default": lambda c: _pooled(c) or c["outvoted"],
    "each2": lambda c: len(_gains(c)) >= 2 and min(_gains(c)[:2]) >= ST.check.min_gain,
    "each2_pos": lambda c: len(_gains(c)) >= 2 and min(_gains(c)[:2]) > 0,
    "maj3": lambda c: len(_gains(c)) >= 3 and sum(g >= ST.check.min_gain for g in _gains(c)) >= 2,
    "all3": lambda c: len(_gains(c)) >= 3 and min(_gains(c)) >= ST.check.min_gain,
    "no_vote": _pooled,
}


def keeps(row, rule: str) -> bool:
    """Whether ``rule`` keeps the places of ``row`` (a check that never ran: as recorded)."""
    m = (row or {}).get("motion") or {}
    c = m.get("check")
    if not isinstance(c, dict):
        return m.get("chosen") == "places"
    return RULES["default"](c) and RULES[rule](c)


def _loose(m) -> bool:
    rr, V = m.get("return_ratios", [0, 0]), m.get("action_vectors") or []
    plane = any(abs(x[1]) > 0 for x in V)
    return bool(m.get("odometry")) and (max(rr) if plane else rr[0]) > ST.places.loose_return


def default_error(d: dict, rule: str) -> float:
    """The default's median error on one walk (``d``: route -> row) under ``rule``."""
    w1 = d["weight1"]
    if _loose(w1.get("motion") or {}):
        half = d.get("weight05") or d["shipped"]
        first_try = "weight05" in d or "loose" not in (half.get("motion") or {})
        if first_try and keeps(half, rule):
            return half["median_error"]
    if keeps(w1, rule):
        return w1["median_error"]
    fallback = [r["median_error"] for r in d.values()
                if r["route"] != "views" and (r.get("motion") or {}).get("chosen") == "views"]
    return fallback[0] if fallback else d["views"]["median_error"]


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("logs", nargs="+")
    p.add_argument("--rules", nargs="+", default=list(RULES), choices=list(RULES))
    a = p.parse_args()
    walks = collections.defaultdict(dict)
    for log in a.logs:
        for line in open(log):
            if line.strip():
                r = json.loads(line)
                walks[(r["case"], r["setting"], r["seed"])].setdefault(r["route"], r)
    walks = {k: d for k, d in sorted(walks.items()) if "views" in d and "weight1" in d and (
        "weight05" in d or "shipped" in d or not _loose(d["weight1"].get("motion") or {}))}
    for rule in a.rules:
        counts, changed = collections.defaultdict(collections.Counter), []
        for k, d in walks.items():
            v, e, e0 = d["views"]["median_error"], default_error(d, rule), default_error(
                d, "default")
            g = (k[1], "5-6" if k[2] >= 5 else "0-4")
            counts[g]["walks"] += 1
            counts[g]["above"] += e > 1.01 * v
            counts[g]["wins"] += e <= 0.95 * v
            if abs(e - e0) > 5e-4:
                changed.append(f"  {k[0]} {k[1]} seed {k[2]}: {e0:.3f} -> {e:.3f} m "
                               f"(views {v:.3f})")
        print(f"{rule}: " + "; ".join(f"{g[0]} {g[1]}: {c['walks']} walks, {c['above']} above,"
                                     f" {c['wins']} wins" for g, c in sorted(counts.items())))
        print("\n".join(changed))


if __name__ == "__main__":
    main()
