"""The ``topomap`` command: Hydra composes ``conf/`` and :func:`topomap.app.run.experiment.run` does the work.

    topomap                                   # the paper's experiment, outputs in outputs/runs/...
    topomap clusters.ns=15 stop.n_states=40
    topomap data=file data.path=my_log.npz
    topomap -m clusters.ns=10,20,30 stop.n_states=25,30,40
    topomap --list-plugins                    # every component by kind, with its plugin
    topomap --version                         # topomap's version (with Hydra's and Python's)

The line from the command to the work, each step once: :func:`main` reads the plugins named on the
command line (with Hydra's own parsers), loads the :class:`~topomap.app.compose.registry.Registry`,
screens the command line and stores every component's typed config
(:func:`~topomap.app.compose.command_line.prepare`); Hydra composes the config of each job and
:func:`~topomap.app.run.experiment.run` takes it from there: the config is checked, the
components are built, the map is learned, evaluated and written.
"""

from __future__ import annotations

import logging
import sys
from pathlib import Path

from .compose.command_line import CONFIG_MODULE, overrides_of, prepare
from .compose.registry import Registry
from .run.experiment import run
from .run.interrupts import interrupt_on_sigterm
from .run.job import run_job, write_status
from .run.outputs import OutputDirInUse

log = logging.getLogger("topomap")

__all__ = ["main", "list_plugins", "version_line"]


def list_plugins(registry: Registry, file=None) -> None:
    """Print every registered component by kind, and every action a plugin adds to a world, with
    the plugin that provides it."""
    from .compose.schemas import fields_of, schema_of

    file = sys.stdout if file is None else file
    last = None
    for kind, name, comp, provider in registry.items():
        if kind != last:
            print(f"{kind}:", file=file)
            last = kind
        print(f"  {name:<16} {provider:<24} {comp.description}", file=file)
    actions = []
    for name in registry.names("env"):
        params = fields_of(schema_of(registry.get("env", name)))
        for provider, added in registry.world_action_providers(params):
            actions += [(a.name, provider, f"an action of the {name} world") for a in added]
    if actions:  # (not "actions:", the header of the action rules, a kind of component)
        print("actions added to worlds:", file=file)
        for action, provider, what in actions:
            print(f"  {action:<16} {provider:<24} {what}", file=file)
    for err in registry.errors:
        print(f"error: {err}", file=file)


def _summary(results: dict, out) -> str:
    """The one-line result of a run, as printed."""
    if "loglik" in results:  # task=localize
        line = (f"localised {results['n_steps']} steps on a map of {results['n_states']} states, "
                f"log-likelihood {results['loglik']:.3f} per step (a log-density)")
        gt = results.get("ground_truth")
        if gt:
            line += (f" | ARI {gt['filter']['ari']:.3f} (filtered), "
                     f"{gt['viterbi']['ari']:.3f} (Viterbi)")
        return line
    gt = results.get("ground_truth", {})
    line = f"{results['n_states']['final']} states"
    choice = results.get("size_choice")
    refined = (choice or {}).get("refined")
    if choice:
        line += (f" (split to {choice['chosen']}, " + (f"refined to {refined['chosen']}, the sizes"
                 if refined else "the size") + f" {choice['criterion']} chose)")
    resized = results.get("resized")
    if resized:
        told = "the held-out choice" if refined else "stop.n_states"
        line += (f" (the refinement found {resized['from']}, brought to the {resized['to']} of "
                 f"{told}; learner.refined_size=free keeps its own)")
    if gt:
        stages = [gt[k] for k in ("phase1", "split", "final") if k in gt]
        label = " (phase 1 -> split -> refined)" if "split" in gt else ""

        def trace(key, fmt):
            return " -> ".join(format(s[key], fmt) for s in stages)

        line += (f" | ARI {trace('ari', '.3f')}, purity {trace('purity', '.3f')}, compound "
                 f"states {trace('compound_states', 'd')}{label}")
    if results.get("position"):
        line += " | " + _metres(results["position"])
    nav = results.get("navigation")
    if nav:
        ratio = "-" if nav["path_ratio"] is None else f"{nav['path_ratio']:.2f}"
        line += (f" | navigation: {nav['success_rate']:.0%} of {nav['episodes']} episodes, "
                 f"path {ratio} x the shortest")
    return line


def _metres(position: dict) -> str:
    """The held-out localisation error (median / 90th percentile, wrong-region share) of the map,
    the ceiling and K-means on the views, as the summary line says it."""
    def said(s):
        if s is None or s["median_error"] is None:
            return "-"
        wrong = "" if s["wrong_region"] is None else f", {s['wrong_region']:.0%} wrong region"
        return f"{s['median_error']:.2f} / {s['p90_error']:.2f} m{wrong}"

    return (f"localisation error (median / p90) {said(position['map'])} (ceiling "
            f"{said(position.get('ceiling'))}; K-means on views {said(position['kmeans_views'])})")


def optimising(sweeper) -> bool:
    """Whether a sweeper optimises what the jobs return (Optuna's has a ``direction``), rather
    than running a grid."""
    return sweeper is not None and "direction" in sweeper


def _task(cfg, registry: Registry):
    """One run (or one job of a sweep) of the composed config ``cfg``; returns the run's
    ``objective`` (:data:`~topomap.app.results.OBJECTIVES`) for a sweeper to optimise, None for
    a failed job."""
    from hydra.core.hydra_config import HydraConfig

    hc = HydraConfig.get()
    out = hc.runtime.output_dir
    if hc.mode.name == "MULTIRUN":
        # trajectories are shared through the sweep folder, and a failure is written to the job's
        # status.json (the sweep report lists it) instead of ending the sweep
        sweep_dir = Path(hc.runtime.cwd, hc.sweep.dir)  # absolute, even with hydra.job.chdir
        results = run_job(cfg, out, sweep_dir=sweep_dir, registry=registry,
                          needs_objective=optimising(hc.sweeper))
        if results is None:
            return None
    else:
        results = _single_run(cfg, out, registry)
    print(f"topomap: {_summary(results, out)}\ntopomap: outputs in {out}")
    return (results.get("objective") or {}).get("value")


def _single_run(cfg, out, registry: Registry) -> dict:
    """``topomap <overrides>`` without ``-m``: the run's results; a failed or interrupted run
    leaves ``status.json`` in its folder saying so, and ends the command with one line."""
    try:
        return run(cfg, out, registry=registry, on_replaced=_restart_log)
    except OutputDirInUse as exc:  # another run's folder: leave it as it is
        sys.exit(f"topomap: error: {exc}")
    except KeyboardInterrupt:
        write_status(out, "interrupted")
        log.warning("interrupted")
        print(f"topomap: interrupted; {out}/status.json says so", file=sys.stderr)
        sys.exit(INTERRUPTED)
    except ValueError as exc:
        write_status(out, "failed", exc)
        log.error("%s", exc)
        sys.exit(f"topomap: error: {exc}")
    except Exception as exc:
        write_status(out, "failed", exc)
        raise


def _restart_log(out) -> None:
    """Start the run's log file in ``out`` afresh: with ``output.overwrite=true`` the previous
    run's log lines go with its outputs (Hydra opened the file to append)."""
    import logging

    folder = Path(out).resolve()
    for handler in logging.getLogger().handlers:
        if isinstance(handler, logging.FileHandler) and Path(handler.baseFilename).parent == folder:
            handler.acquire()
            try:
                handler.flush()
                handler.stream.seek(0)
                handler.stream.truncate()
            finally:
                handler.release()


#: the exit status of a run or sweep ended by Ctrl-C or SIGTERM (128 + SIGINT, as shells report)
INTERRUPTED = 130


def _interrupted(exc: KeyboardInterrupt) -> None:
    """After Ctrl-C or SIGTERM outside a single run's own handling: a sweep writes its report
    (with the interrupted job and the jobs that did not start); then one line, exit 130."""
    from .report.callback import SweepInterrupted

    where = exc.write_report() if isinstance(exc, SweepInterrupted) else None
    print("topomap: interrupted" + (f"; sweep report in {where}" if where else ""),
          file=sys.stderr)
    sys.exit(INTERRUPTED)


def version_line() -> str:
    """What ``topomap --version`` prints: topomap's version, with Hydra's and Python's."""
    import platform

    from hydra import __version__ as hydra_version

    from .. import __version__

    return f"topomap {__version__} (Hydra {hydra_version}, Python {platform.python_version()})"


def _user_configs(argv) -> bool:
    """Whether the command line names config folders or a primary config of its own."""
    flags = ("-cd", "--config-dir", "-cp", "--config-path", "-cn", "--config-name")
    return any(a in flags or a.startswith(tuple(f + "=" for f in flags)) for a in argv)


def main() -> None:
    """Console entry point."""
    import hydra

    interrupt_on_sigterm()
    argv = sys.argv[1:]
    if "--version" in argv:
        print(version_line())
        return
    if argv and argv[0] in ("--list-plugins", "plugins"):
        list_plugins(Registry.load(argv[1:]))
        return
    try:
        registry = prepare(overrides_of(argv), user_configs=_user_configs(argv))
    except ValueError as exc:
        sys.exit(f"topomap: error: {exc}")
    except KeyboardInterrupt as exc:
        _interrupted(exc)

    @hydra.main(version_base="1.3", config_path=f"pkg://{CONFIG_MODULE}", config_name="config")
    def topomap(cfg):
        return _task(cfg, registry)

    try:
        topomap()
    except KeyboardInterrupt as exc:
        _interrupted(exc)


if __name__ == "__main__":
    main()
