"""Map quality, navigation and run time in every world, from the commands a user runs.

    python benchmarks/bench_worlds.py                         # every world, seeds 0-2
    python benchmarks/bench_worlds.py --worlds gridroom --seeds 0
    python benchmarks/bench_worlds.py --variants "" "stop=auto" "stop=auto stop.criterion=bic"
    python benchmarks/bench_worlds.py --no-navigation --worlds minigrid_fourrooms
    python benchmarks/bench_worlds.py --no-navigation --worlds open_rooms --seeds 0   # 10k-200k steps

Every row is a ``topomap`` command (``COMMANDS``), run in this process exactly as the command
line runs it (the same config composition, data, learner and evaluation; figures off), once per
seed with ``seed=<s> evaluate=navigation`` added, and once more per ``--variants`` entry (extra
overrides, e.g. ``stop=auto``).  So ``topomap <command> seed=0`` prints the figures of seed 0.
The table gives the medians over the seeds of: ARI after phase 1, after the split and at the end
(refined, with ``refine=em``), NMI at the end, the states at the end (every seed's count, and the
split's own count where ``stop=auto`` chose it), the navigation success rate of each seed and the
median path length over the true shortest path (``evaluate=navigation``, 100 episodes), and the
fit time (phase 1, the split, the refinement; simulation, scoring and navigation excluded).
Prints a Markdown table.
"""

from __future__ import annotations

import argparse
import shlex
import statistics
import tempfile

from topomap.app.compose.command_line import compose
from topomap.app.compose.config_checks import preset_overrides
from topomap.app.run.experiment import run
from topomap.app.compose.registry import Registry

TEN_K = "data.n_steps=10000"
GRID12 = "env=gridroom env.width=12 env.height=12 env.n_symbols=8 clusters.ns=8 stop.n_states=144"
RG60 = ("env=random_graph env.n_places=60 env.n_symbols=15 env.out_degree=3 clusters.ns=15 "
        "stop.n_states=60")
FOURROOMS = ("env=minigrid env.name=MiniGrid-FourRooms-v0 data.n_steps=50000 clusters.ns=450 "
             "stop.n_states=1036")
EMPTY16 = "env=minigrid env.name=MiniGrid-Empty-16x16-v0 clusters.ns=109 stop.n_states=780"

#: world -> the commands (overrides of ``topomap``) of its rows
COMMANDS = {
    "office": ["", "refine=em", f"{TEN_K}", f"{TEN_K} refine=em"],
    "gridroom": [f"env=gridroom clusters.ns=4 stop.n_states=48 {TEN_K}", "experiment=gridroom"],
    "gridroom_12x12": [f"{GRID12} {TEN_K}", f"{GRID12} {TEN_K} refine=em"],
    "random_graph": ["env=random_graph", f"env=random_graph {TEN_K}",
                     f"env=random_graph {TEN_K} refine=em"],
    "random_graph_60": [f"{RG60} {TEN_K}", f"{RG60} {TEN_K} refine=em"],
    "minigrid_empty": ["experiment=minigrid_empty refine=none", "experiment=minigrid_empty"],
    "minigrid_fourrooms": [FOURROOMS, f"{FOURROOMS} refine=em"],
    # the open rooms as the data grow (not in the default run: about an hour; --worlds open_rooms)
    "open_rooms": [f"{room} data.n_steps={n} refine=em" for n in (10000, 50000, 200000)
                   for room in (FOURROOMS.replace(" data.n_steps=50000", ""), EMPTY16)],
}
#: the worlds a plain run measures
DEFAULT_WORLDS = [w for w in COMMANDS if w != "open_rooms"]


def with_variant(command: str, variant: str) -> str:
    """``command`` with ``variant`` added; a group the variant chooses (``stop=auto``) replaces the
    command's settings of that group, and a preset (``experiment=X``) is spelled out without it."""
    extra = shlex.split(variant)
    groups = {t.split("=")[0] for t in extra if "=" in t and "." not in t.split("=")[0]}
    out = []
    for token in shlex.split(command):
        key = token.split("=")[0]
        if key == "experiment" and groups:
            out += preset_overrides(token.split("=", 1)[1], without=groups)
        elif key.split(".")[0] not in groups:
            out.append(token)
    last = {t.split("=")[0]: t for t in out + extra}  # a later setting of a key wins
    return " ".join(last.values())


def run_command(command: str, seed: int, navigation: bool, registry: Registry) -> dict:
    overrides = [*shlex.split(command), f"seed={seed}", "output.figures=false",
                 "output.progress=false"]
    if navigation:
        overrides.append("evaluate=navigation")
    with tempfile.TemporaryDirectory() as out:
        results = run(compose(overrides, registry), out, registry=registry)
    gt, nav = results["ground_truth"], results.get("navigation") or {}
    t = results["timings"]
    choice = results.get("size_choice") or {}
    return {
        "ari1": gt["phase1"]["ari"], "ari_split": gt.get("split", gt["final"])["ari"],
        "ari": gt["final"]["ari"], "nmi": gt["final"]["nmi"],
        "states": results["n_states"]["final"], "chosen": choice.get("chosen"),
        "nav": nav.get("success_rate"), "ratio": nav.get("path_ratio"),
        "fit": t["phase1"] + t["phase2"] + t.get("refine", 0.0),
    }


def _median(runs, key, fmt):
    values = [r[key] for r in runs if r[key] is not None]
    return format(statistics.median(values), fmt) if values else "-"


def row(command: str, runs: list) -> str:
    states = "/".join(str(r["states"]) for r in runs)
    if runs[0]["chosen"] is not None:
        states += " (split to " + "/".join(str(r["chosen"]) for r in runs) + ")"
    nav = "-" if runs[0]["nav"] is None else "/".join(f"{r['nav']:.0%}" for r in runs)
    cmd = f"topomap {command}".strip()
    return (f"| `{cmd}` | {_median(runs, 'ari1', '.3f')} | "
            f"{_median(runs, 'ari_split', '.3f')} | {_median(runs, 'ari', '.3f')} | "
            f"{_median(runs, 'nmi', '.3f')} | {states} | {nav} | "
            f"{_median(runs, 'ratio', '.2f')} | {_median(runs, 'fit', '.2f')} |")


HEADER = ("| command | ARI p1 | ARI split | ARI final | NMI final | states (each seed) "
          "| navigation (each seed) | path / shortest | fit s |")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--worlds", nargs="+", default=DEFAULT_WORLDS, choices=list(COMMANDS))
    ap.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2])
    ap.add_argument("--variants", nargs="+", default=[""],
                    help='extra overrides added to every command, one row each ("" = none)')
    ap.add_argument("--no-navigation", action="store_true", help="skip evaluate=navigation")
    args = ap.parse_args()
    registry = Registry.load()
    run_command("data.n_steps=500 data.heldout_steps=0 refine=em", 0, False, registry)  # compile
    print(f"medians over seeds {args.seeds}")
    print(HEADER)
    print("|" + "---|" * (HEADER.count("|") - 1))
    for world in args.worlds:
        for command in COMMANDS[world]:
            for variant in args.variants:
                full = with_variant(command, variant)
                runs = [run_command(full, s, not args.no_navigation, registry) for s in args.seeds]
                print(row(full, runs), flush=True)


if __name__ == "__main__":
    main()
