"""The ``topomap`` command: Hydra composes ``conf/`` and :func:`topomap.experiment.run` does the work.

    topomap                                   # the paper's experiment, outputs in outputs/runs/...
    topomap clusters.ns=15 stop.n_states=40
    topomap data=file data.path=my_log.npz
    topomap -m clusters.ns=10,20,30 stop.n_states=25,30,40
    topomap --list-plugins                    # every component by kind, with its plugin
"""

from __future__ import annotations

import logging
import re
import sys
from pathlib import Path

import hydra
from hydra.core.hydra_config import HydraConfig
from omegaconf import DictConfig

from . import schema  # noqa: F401  (stores the structured configs before Hydra composes)
from .experiment import run
from .registry import Registry

log = logging.getLogger("topomap")

_PLUGINS_ARG = re.compile(r"^\+?\+?plugins=\[?(?P<list>[^\]]*)\]?$")


def _plugins_from_argv(argv) -> list[str]:
    """Plugin modules named on the command line (``plugins=[a,b]``), needed before composition so
    that their components' typed configs can be selected in the same command."""
    for arg in argv:
        m = _PLUGINS_ARG.match(arg)
        if m:
            return [p.strip().strip("'\"") for p in m.group("list").split(",") if p.strip()]
    return []


def with_plugin_searchpath(argv, paths) -> list[str]:
    """Append plugins' config folders to ``hydra.searchpath`` (merging a user's own override)."""
    if not paths:
        return list(argv)
    argv = list(argv)
    for i, arg in enumerate(argv):
        m = re.match(r"^(\+?hydra\.searchpath)=\[(?P<list>.*)\]$", arg)
        if m:
            user = [p.strip() for p in m.group("list").split(",") if p.strip()]
            argv[i] = f"{m.group(1)}=[{','.join(user + [p for p in paths if p not in user])}]"
            return argv
    return argv + [f"hydra.searchpath=[{','.join(paths)}]"]


def list_plugins(registry: Registry, file=sys.stdout) -> None:
    """Print every registered component by kind, with the plugin that provides it."""
    last = None
    for kind, name, comp, provider in registry.items():
        if kind != last:
            print(f"{kind}:", file=file)
            last = kind
        print(f"  {name:<16} {provider:<24} {comp.description}", file=file)
    for err in registry.errors:
        print(f"error: {err}", file=file)


@hydra.main(version_base="1.3", config_path="conf", config_name="config")
def _hydra_main(cfg: DictConfig):
    hc = HydraConfig.get()
    out = hc.runtime.output_dir
    registry = _REGISTRY if not cfg.plugins else None
    if hc.mode.name == "MULTIRUN":
        # one job of a sweep: trajectories are shared through the sweep folder, and a failure is
        # written to the job's status.json (the sweep report lists it) instead of ending the sweep
        from .sweep import run_job

        sweep_dir = Path(hc.runtime.cwd, hc.sweep.dir)  # absolute, even with hydra.job.chdir
        results = run_job(cfg, out, sweep_dir=sweep_dir, registry=registry)
        if results is None:
            return None
    else:
        try:
            results = run(cfg, out, registry=registry)
        except ValueError as exc:
            log.error("%s", exc)
            sys.exit(f"topomap: error: {exc}")
    gt = results.get("ground_truth", {}).get("final", {})
    line = f"{results['n_states']['final']} states"
    if gt:
        g0 = results["ground_truth"]["phase1"]
        line += (f" | ARI {g0['ari']:.3f} -> {gt['ari']:.3f}, purity {g0['purity']:.3f} -> "
                 f"{gt['purity']:.3f}, compound states {g0['compound_states']} -> "
                 f"{gt['compound_states']}")
    print(f"topomap: {line}\ntopomap: outputs in {out}")
    return gt.get("ari")


_REGISTRY: Registry | None = None


def main(argv=None) -> None:
    """Console entry point."""
    global _REGISTRY
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv and argv[0] in ("--list-plugins", "plugins"):
        list_plugins(Registry.load(argv[1:]))
        return
    try:
        _REGISTRY = Registry.load(_plugins_from_argv(argv))
        _REGISTRY.store_configs()
    except ValueError as exc:
        sys.exit(f"topomap: error: {exc}")
    sys.argv = [sys.argv[0]] + with_plugin_searchpath(argv, _REGISTRY.config_paths())
    _hydra_main()


if __name__ == "__main__":
    main()
