"""How far the held-out walk itself moves the verdict "places against views" of one triple.

    python benchmarks/bench_walk_noise.py --log walk_noise.jsonl pillars:9:1 grid6:8:2

Each argument is ``case:setting:seed`` (``setting`` an index of ``bench_continuous.SETTINGS``).
The default learner (``MapLearner(n_clusters, n_states, refine="em", random_state=0)``) and
K-means on the views (as many clusters, ``n_init=4``, ``random_state=0``) are learned on the
triple's cached training walk, as ``bench_continuous.py`` does; each held-out step is placed at
its state's (cluster's) mean training position. Row: the ratio of the two median errors, and
its 5th and 95th percentiles over 2,000 block-bootstrap draws of 30-second stretches of the
held-out walk (seeded 0), and the ratio on each half of the walk.
"""

from __future__ import annotations

import argparse
import json
import os
from pathlib import Path

import numpy as np
from sklearn.cluster import KMeans

import bench_continuous as bc
from topomap.core.stats import label_means


def walk_noise(case: str, setting: int, seed: int, cache: Path, draws: int = 2000) -> dict:
    s = dict(bc.BASE, **bc.SETTINGS[setting])
    _, train, held, ns, S = bc.walks(case, seed, s, cache, 18_000)
    learner, _ = bc._fit(train, n_clusters=ns, n_states=S, random_state=0, refine="em")
    states = learner.map_.predict(held.observations, held.actions)
    placed = label_means(learner.labels_, train.positions, learner.map_.n_states)[states]
    km = KMeans(S, n_init=4, random_state=0).fit(train.observations)
    viewed = label_means(km.labels_, train.positions, S)[km.predict(held.observations)]
    ep = np.linalg.norm(placed - held.positions, axis=1)
    ev = np.linalg.norm(viewed - held.positions, axis=1)
    block = int(round(30 / s["dt"]))
    nb = len(ep) // block
    rng = np.random.default_rng(0)
    ratios = []
    for _ in range(draws):
        idx = (rng.integers(0, nb, nb)[:, None] * block + np.arange(block)).ravel()
        ratios.append(np.median(ep[idx]) / np.median(ev[idx]))
    half = len(ep) // 2
    return {"case": case, "setting": bc.setting_name(s), "seed": seed,
            "chosen": learner.motion_info_["chosen"],
            "ratio": round(float(np.median(ep) / np.median(ev)), 3),
            "q05_q95": [round(float(q), 3) for q in np.percentile(ratios, [5, 95])],
            "halves": [round(float(np.median(ep[:half]) / np.median(ev[:half])), 3),
                       round(float(np.median(ep[half:]) / np.median(ev[half:])), 3)],
            "block_steps": block, "blocks": nb}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("triples", nargs="+", help="case:setting:seed")
    p.add_argument("--log", default="walk_noise.jsonl")
    p.add_argument("--cache", default=os.path.expanduser("~/.cache/topomap-bench"))
    a = p.parse_args()
    for spec in a.triples:
        case, setting, seed = spec.split(":")
        row = walk_noise(case, int(setting), int(seed), Path(a.cache))
        print(row, flush=True)
        with open(a.log, "a") as fh:
            fh.write(json.dumps(row) + "\n")


if __name__ == "__main__":
    main()
