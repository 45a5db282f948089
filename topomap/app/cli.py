"""The ``topomap`` command: Hydra composes ``conf/`` and :func:`topomap.app.run.experiment.run` does the work.

    topomap                                   # the paper's experiment, outputs in outputs/runs/...
    topomap clusters.ns=15 stop.n_states=40
    topomap data=file data.path=my_log.npz
    topomap -m clusters.ns=10,20,30 stop.n_states=25,30,40
    topomap --list-plugins                    # every component by kind, with its plugin
    topomap --version                         # topomap's version (with Hydra's and Python's)

The line from the command to the work, each step once: :func:`main` takes Ctrl-C and SIGTERM
(:mod:`~topomap.app.run.interrupts`), reads the plugins named on the command line (with Hydra's
own parsers), loads the :class:`~topomap.app.compose.registry.Registry`, screens the command line
and stores every component's typed config
(:func:`~topomap.app.compose.command_line.screen_command_line`).  A single run's config is then
checked and its components built (:func:`~topomap.app.run.experiment.check_and_build`), a
sweep's plan checked (:func:`check_sweep`), before Hydra makes a folder; Hydra composes the
config of each job and :func:`~topomap.app.run.experiment.run` takes it from there: the map is
learned, evaluated and written.  A sweep that ends before Hydra ends it (Ctrl-C, a search whose
every trial failed) gets its report here
(:func:`~topomap.app.report.callback.report_early_end`).
"""

from __future__ import annotations

import logging
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from .compose.registry import Registry

log = logging.getLogger("topomap")

__all__ = ["main", "list_plugins", "version_line", "check_sweep"]


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
    motion = results.get("motion") or {}
    if motion.get("reason"):
        line += f" | the map is the view clusters, not places: {motion['reason']}"
    nav = results.get("navigation")
    if nav:
        ratio = "-" if nav["path_ratio"] is None else f"{nav['path_ratio']:.2f}"
        line += (f" | navigation: {nav['success_rate']:.0%} of {nav['episodes']} episodes, "
                 f"path {ratio} x the shortest")
    return line


def _metres(position: dict) -> str:
    """The held-out localisation error (median / 90th percentile, wrong-region share) of the map,
    the ceiling, K-means on the views and K-means on the true positions, as the summary line
    says it."""
    def said(s):
        if s is None or s["median_error"] is None:
            return "-"
        wrong = "" if s["wrong_region"] is None else f", {s['wrong_region']:.0%} wrong region"
        return f"{s['median_error']:.2f} / {s['p90_error']:.2f} m{wrong}"

    return (f"localisation error (median / p90) {said(position['map'])} (ceiling "
            f"{said(position.get('ceiling'))}; K-means on views {said(position['kmeans_views'])}"
            f"; K-means on true positions {said(position.get('kmeans_positions'))})")


def optimising(sweeper) -> bool:
    """Whether a sweeper optimises what the jobs return (Optuna's has a ``direction``), rather
    than running a grid."""
    return sweeper is not None and "direction" in sweeper


def _task(cfg, registry: Registry, plan: Plan):
    """One run (or one job of a sweep) of the composed config ``cfg``; returns the run's
    ``objective`` (:data:`~topomap.app.results.OBJECTIVES`) for a sweeper to optimise, None for
    a failed job.  ``plan``: what the command checked before Hydra made the folder."""
    from hydra.core.hydra_config import HydraConfig

    from .run.job import run_job

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
        results = _single_run(cfg, out, registry, plan)
    print(f"topomap: {_summary(results, out)}\ntopomap: outputs in {out}")
    return (results.get("objective") or {}).get("value")


def _single_run(cfg, out, registry: Registry, plan: Plan) -> dict:
    """``topomap <overrides>`` without ``-m``: the run's results; an interrupted run, or one
    failed by something else than its settings or data, leaves ``status.json`` in its folder
    saying so; a run failed by its settings or data removes the folder it made
    (``plan.new_folder``) and ends the command with one line on stderr."""
    from .run.experiment import run
    from .run.interrupts import ending
    from .run.job import write_status
    from .run.outputs import OutputDirInUse, remove_new_folder

    try:
        return run(cfg, out, registry=registry, checked=plan.checked, on_replaced=_restart_log)
    except OutputDirInUse as exc:  # another run's folder: leave it as it is
        sys.exit(f"topomap: error: {exc}")
    except KeyboardInterrupt:
        ending()
        write_status(out, "interrupted")
        log.warning("interrupted")
        print(f"topomap: interrupted; {out}/status.json says so", file=sys.stderr)
        sys.exit(INTERRUPTED)
    except ValueError as exc:
        if not (plan.new_folder and remove_new_folder(out)):
            write_status(out, "failed", exc)
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


def _interrupted(plan: Plan) -> None:
    """After Ctrl-C or SIGTERM outside a single run's own handling: a sweep writes its report
    (with the interrupted job and the jobs that did not start); then one line, exit 130.  A
    second Ctrl-C meanwhile is recorded, not raised."""
    from .run.interrupts import ending

    ending()
    where = _report_early_end(plan)
    print("topomap: interrupted" + (f"; sweep report in {where}" if where else ""),
          file=sys.stderr)
    sys.exit(INTERRUPTED)


def _report_early_end(plan: Plan) -> Path | None:
    """The report of a sweep that ended before Hydra ended it (interrupted, or a search whose
    every trial failed), unless it was written; its summary's path (None: no sweep, or no
    report)."""
    if plan.mode != "sweep":
        return None
    from .report.callback import report_early_end, written_report

    return written_report(plan.folder) or report_early_end(plan.folder, plan.config)


def version_line() -> str:
    """What ``topomap --version`` prints: topomap's version, with Hydra's and Python's (read from
    the installed packages' metadata: nothing is imported)."""
    import platform
    from importlib.metadata import PackageNotFoundError, version

    from .. import __version__

    try:
        hydra_version = version("hydra-core")
    except PackageNotFoundError:
        hydra_version = "not installed"
    return f"topomap {__version__} (Hydra {hydra_version}, Python {platform.python_version()})"


def _user_configs(argv) -> bool:
    """Whether the command line names config folders or a primary config of its own."""
    flags = ("-cd", "--config-dir", "-cp", "--config-path", "-cn", "--config-name")
    return any(a in flags or a.startswith(tuple(f + "=" for f in flags)) for a in argv)


def _pin(argv, key: str, value: str) -> None:
    """Give Hydra ``key=value`` (quoted) in place of any ``key=`` of the command line."""
    quoted = "'" + value.replace("\\", "\\\\").replace("'", "\\'") + "'"
    sys.argv[1:] = [a for a in argv if not a.startswith(f"{key}=")] + [f"{key}={quoted}"]


class Plan:
    """What the command line asks for, checked before Hydra makes a folder (:func:`_plan`).

    ``mode`` is ``"run"`` or ``"sweep"``, None for a command that does not run (``--cfg``, ...)
    or brings config folders of its own; ``folder`` the run's or the sweep's folder; ``config``
    the config composed (Hydra's part included: for a sweep, the values its jobs share);
    ``checked`` a single run's checked config and components
    (:class:`~topomap.app.run.experiment.CheckedRun`), handed to the run; ``new_folder``
    whether the command made the run's folder.  (A plain class: ``dataclasses`` would cost
    ``topomap --version`` the import of ``inspect``.)"""

    def __init__(self, mode: str | None = None, folder: Path | None = None, config: Any = None,
                 checked: Any = None, new_folder: bool = False):
        self.mode, self.folder, self.config = mode, folder, config
        self.checked, self.new_folder = checked, new_folder


def _plan(argv, registry: Registry) -> Plan:
    """For ``topomap <overrides>`` (one run): everything checked and every component built
    before Hydra makes the run's folder (:func:`~topomap.app.run.experiment.check_and_build`,
    once: the run takes it over), and that folder chosen now and given to Hydra
    (``hydra.run.dir``), so that it can be held (:func:`~topomap.app.run.outputs.
    locked_output_dir`) before Hydra writes ``.hydra/`` into it.  For a sweep, its plan is
    checked (:func:`check_sweep`) and its folder chosen now too (``hydra.sweep.dir``)."""
    from hydra.core.override_parser.overrides_parser import OverridesParser
    from hydra.errors import HydraException
    from omegaconf import OmegaConf, open_dict

    from .compose.command_line import NOT_A_RUN, compose, hydra_arguments

    args = hydra_arguments(argv)
    if any(getattr(args, flag, None) for flag in NOT_A_RUN) or _user_configs(argv):
        return Plan()
    overrides = list(args.overrides or [])
    shared = overrides
    if args.multirun:  # the values every job shares: the sweep's folder and logger
        parsed = OverridesParser.create().parse_overrides(overrides)
        shared = [o.input_line for o in parsed if not o.is_sweep_override()]
        task = [o.input_line for o in parsed if not o.is_hydra_override()]
    try:
        cfg = compose(shared, registry, screened=True, return_hydra_config=True)
    except HydraException:  # Hydra says what is wrong, in its own words, when it composes
        return Plan()
    if args.multirun:
        folder = Path(str(cfg.hydra.sweep.dir))
        with open_dict(cfg):  # its folder chosen once; its overrides, as Hydra keeps them
            cfg.hydra.sweep.dir = str(folder)
            cfg.hydra.overrides.task = task
        check_sweep(cfg)
        _pin(argv, "hydra.sweep.dir", str(folder))
        return Plan("sweep", folder, cfg)
    from .run.experiment import check_and_build

    folder = str(cfg.hydra.run.dir)
    plain = OmegaConf.to_container(cfg, resolve=False)
    plain.pop("hydra")
    checked = check_and_build(OmegaConf.create(plain), registry)
    _pin(argv, "hydra.run.dir", folder)
    return Plan("run", Path(folder), cfg, checked)


def check_sweep(multirun_cfg) -> None:
    """Refuse (a ValueError naming the key) a sweep before its first job: a search the wrong
    way (:func:`~topomap.app.compose.config_checks.check_search_direction`), or going on from a
    folder without a study of its objective (:func:`~topomap.app.compose.study.check_resume`),
    SLURM's launcher on a machine without ``sbatch``, a folder that holds another sweep's jobs
    (:func:`~topomap.app.report.jobs.check_sweep_folder`; with ``output.resume=true``, those of
    the same sweep go on)."""
    import shutil

    from omegaconf import OmegaConf

    from .compose.config_checks import check_search_direction
    from .report.jobs import check_sweep_folder

    check_search_direction(multirun_cfg)
    resume_from = OmegaConf.select(multirun_cfg, "hydra.sweeper.storage.resume_from",
                                   default=None)
    if resume_from not in (None, ""):
        from .compose.study import check_resume

        objective = OmegaConf.select(multirun_cfg, "objective", default=None)
        check_resume(str(resume_from), str(getattr(objective, "value", objective)))
    launcher = str(OmegaConf.select(multirun_cfg, "hydra.launcher._target_", default="") or "")
    if launcher.endswith("SlurmLauncher") and shutil.which("sbatch") is None:
        raise ValueError("hydra/launcher=slurm submits the jobs with SLURM's sbatch, which is not "
                         "on this machine's PATH: start the sweep on a machine of the cluster, or "
                         "run it here with hydra/launcher=submitit_local")
    sweep_dir = OmegaConf.select(multirun_cfg, "hydra.sweep.dir", default=None)
    if sweep_dir is not None:
        check_sweep_folder(Path(str(sweep_dir)), multirun_cfg,
                           bool(OmegaConf.select(multirun_cfg, "output.resume", default=False)))


def _log_sweep(registry: Registry, sweep_dir: Path, logger_cfg) -> None:
    """After a sweep: its report's files to the sweep's record in the logger, when the logger
    keeps sweeps (``log_sweep``; MLflow: the parent run of the jobs' runs)."""
    if not sweep_dir.is_dir() or not isinstance(logger_cfg, dict):
        return
    logger = registry.make("logger", logger_cfg)
    if logger is not None and hasattr(logger, "log_sweep"):
        logger.log_sweep(sweep_dir, Path.cwd())


def main() -> None:
    """Console entry point."""
    argv = sys.argv[1:]
    if "--version" in argv:
        print(version_line())
        return
    from .compose.help_cache import keeping_help, kept_help

    kept = kept_help(argv)
    if kept is not None:
        sys.stdout.write(kept)
        return
    with keeping_help(argv):
        _main(argv)


def _main(argv: list[str]) -> None:
    """:func:`main` past ``--version`` and a kept ``--help``."""
    import hydra

    from .compose.command_line import (CONFIG_MODULE, overrides_of, renamed_overrides,
                                       screen_command_line)
    from .compose.registry import Registry
    from .run.interrupts import take_interrupts

    take_interrupts()
    if argv and argv[0] in ("--list-plugins", "plugins"):
        list_plugins(Registry.load(argv[1:]))
        return
    plan = Plan()
    try:
        argv = sys.argv[1:] = renamed_overrides(argv)  # old keys of settings: their keys now
        registry = screen_command_line(overrides_of(argv), user_configs=_user_configs(argv))
        plan = _plan(argv, registry)
    except ValueError as exc:
        sys.exit(f"topomap: error: {exc}")
    except KeyboardInterrupt:
        _interrupted(plan)

    @hydra.main(version_base="1.3", config_path=f"pkg://{CONFIG_MODULE}", config_name="config")
    def topomap(cfg):
        return _task(cfg, registry, plan)

    try:
        _launch(topomap, plan, registry)
    except ValueError as exc:  # the folder is another run's; the logger's store
        sys.exit(f"topomap: error: {exc}")
    except KeyboardInterrupt:
        _interrupted(plan)
    except SystemExit as exc:  # a search whose every trial failed, say: its report, then why
        if exc.code not in (None, 0):
            _report_early_end(plan)
        raise


def _launch(topomap, plan: Plan, registry: Registry) -> None:
    """Hydra's part of :func:`main`: the run, in the folder held for it, or the sweep, then its
    report's files to the logger; an interrupt whose exception was dropped where it landed
    ends the command here (:func:`~topomap.app.run.interrupts.stop_if_interrupted`)."""
    from .run.interrupts import stop_if_interrupted

    if plan.mode == "run":
        from .run.outputs import locked_output_dir

        with locked_output_dir(plan.folder, bool(plan.config.output.overwrite)) as new_folder:
            plan.new_folder = new_folder
            topomap()
        stop_if_interrupted()
        return
    topomap()
    stop_if_interrupted()
    if plan.mode == "sweep":
        from omegaconf import OmegaConf

        _log_sweep(registry, plan.folder, OmegaConf.to_container(plan.config.logger,
                                                                 resolve=True))


if __name__ == "__main__":
    main()
