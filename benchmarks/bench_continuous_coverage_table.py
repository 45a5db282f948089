"""The rules of the check decided again from ``bench_continuous_quarters.py``'s log.

    python benchmarks/bench_continuous_coverage_table.py quarters.jsonl

Every rule chooses between the whole log's places and its view clusters, so its error on the
new walk is one of the two recorded beside the quarters; a rule is decided from the recorded
folds (the last quarter, ``q3``, is the default's fold).  Printed: one row per walk, and per rule
the walks more than 1 % above K-means on the views (misses) and those 5 % or more below them
(wins).
"""

from __future__ import annotations

import argparse
import json

MARGIN_SE = 2.0


def z(f):
    return f["gap"] / f["se"] if f["se"] > 0 else float("inf")


def novel(row, share, key="novelty_0.1"):
    """The most novel quarter but the last, where its novelty reaches ``share``."""
    qs = [(f[key], i) for i, f in enumerate(row["quarters"][:-1]) if f is not None]
    best = max(qs, key=lambda t: (t[0], -t[1]))
    return row["quarters"][best[1]] if best[0] >= share else None


def rules(row):
    last = row["quarters"][-1]
    boot = z(last) < -MARGIN_SE  # True: views
    out = {"bootstrap": boot}
    for share in (0.2, 0.3, 0.4):  # that quarter held out instead of the last (the shipped)
        f = novel(row, share)
        out[f"instead{share}"] = boot if f is None else f["gap"] < 0
    f = novel(row, 0.3)  # the same quarter held out beside the last: a second fold's cost
    out["both0.3"] = boot or (f is not None and f["gap"] < 0)
    out["both0.3_z-1"] = boot or (f is not None and z(f) < -1)
    out["margin1"] = z(last) < -1.0
    # a second held-out quarter (the one before the last, learned on the rest) when close
    q2 = row["quarters"][2]
    out["second_close"] = boot or (abs(z(last)) < MARGIN_SE and z(q2) < -MARGIN_SE)
    out["any_quarter"] = any(z(f) < -MARGIN_SE for f in row["quarters"] if f is not None)
    return out


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("log")
    a = p.parse_args()
    rows = sorted((json.loads(line) for line in open(a.log)),
                  key=lambda r: (r["case"], r["seed"]))
    names = list(rules(rows[0]))
    tally = {n: [0, 0] for n in names}
    print("| walk | views | places | fallback | default | last quarter z | most novel other "
          "quarter: novelty, z | " + " | ".join(names) + " |")
    print("|---" * (6 + len(names)) + "|")
    for r in rows:
        views, places, fall = r["views_yardstick"], r["whole_places"], r["whole_views"]
        dec = rules(r)
        qs = [(f["novelty_0.1"], i) for i, f in enumerate(r["quarters"][:-1])]
        nv, i = max(qs, key=lambda t: (t[0], -t[1]))
        cells = []
        for n in names:
            err = fall if dec[n] else places
            ratio = err / views
            tally[n][0] += ratio > 1.01
            tally[n][1] += ratio <= 0.95
            cells.append(f"{err:.3f}{' **' if ratio > 1.01 else ''}")
        print(f"| `{r['case']}` s{r['seed']} | {views:.3f} | {places:.3f} | {fall:.3f} | "
              f"{r['shipped']:.3f} | {z(r['quarters'][-1]):+.2f} | q{i} {nv:.2f}, "
              f"{z(r['quarters'][i]):+.2f} | " + " | ".join(cells) + " |")
    print("| misses / wins |  |  |  |  |  |  | " + " | ".join(f"{m} / {w}" for m, w in
                                                            tally.values()) + " |")


if __name__ == "__main__":
    main()
