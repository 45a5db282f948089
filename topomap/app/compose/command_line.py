"""The command line before Hydra composes it, and the config it composes.

What must happen before Hydra composes the config of ``topomap <overrides>``, each once
(:func:`screen_command_line`): the plugins the overrides name (:func:`plugins_named`) are loaded
into the :class:`~topomap.app.compose.registry.Registry`, the command line is screened in
topomap's words (:func:`~topomap.app.compose.config_checks.check_overrides`) and every
component's typed config is stored (:func:`~topomap.app.compose.store.store_configs`).  :func:`compose` gives the config
Hydra composes from it (Hydra's compose API; for notebooks and tests).

This module holds the one private Hydra API topomap uses: :func:`hydra_arguments` reads the
command line with Hydra's own argument parser (``hydra._internal.utils.get_args_parser``), for
Hydra has no public one, and a parser of our own would have to follow every flag Hydra adds
(which of them take a value).  ``tests/test_hydra_private.py`` fails if Hydra changes it.
"""

from __future__ import annotations

from .config_checks import check_overrides
from .registry import Registry
from .store import store_configs

__all__ = ["CONFIG_MODULE", "NOT_A_RUN", "hydra_arguments", "overrides_of", "plugins_named",
           "renamed_overrides", "screen_command_line", "compose"]

#: the package of topomap's Hydra configs (``conf/``)
CONFIG_MODULE = "topomap.conf"

#: Hydra's flags that print or inspect rather than run (attributes of :func:`hydra_arguments`)
NOT_A_RUN = ("cfg", "help", "hydra_help", "info", "shell_completion", "experimental_rerun")


def hydra_arguments(argv):
    """The command line ``argv`` as Hydra's own parser reads it (an ``argparse.Namespace``:
    ``overrides``, ``multirun``, the flags of :data:`NOT_A_RUN`, ...); the words it does not
    know are left out."""
    from hydra._internal.utils import get_args_parser

    args, _ = get_args_parser().parse_known_args(list(argv))
    return args


def overrides_of(argv) -> list[str]:
    """The overrides (``key=value`` words) of a command line, as Hydra's own parser reads it;
    none with ``--shell-completion`` (``-sc``), whose words are commands to Hydra's shell
    completion (``install=bash``, ``query=bash``), not keys of the config."""
    args = hydra_arguments(argv)
    return [] if args.shell_completion else list(args.overrides or [])


def renamed_overrides(words) -> list[str]:
    """The words of a command line with the keys the learner's settings had before a rename
    (``learner.motion.holdout``, ``learner.motion.check=crossfit``) under their keys now
    (``learner.motion.check.holdout``, ``learner.motion.check.rule``), a ``FutureWarning``
    naming the new key for each (:func:`topomap.core.motion.renamed.moved_override`); Hydra
    then composes the new keys.  A ``ValueError`` where the new key is given too."""
    words = list(words)
    if not any("learner.motion." in w for w in words):
        return words  # the learner's core is not imported for a command that names none
    from ...core.motion.renamed import moved_override

    moved = [moved_override(w) for w in words]
    given = {_key(w) for w, m in zip(words, moved) if w == m}
    for word, new in zip(words, moved):
        if word != new and _key(new) in given:
            raise ValueError(f"{_key(word)} is the old key of {_key(new)}: give {_key(new)} "
                             "only")
    return moved


def _key(word: str) -> str:
    return word.lstrip("+~").partition("=")[0]


def plugins_named(overrides) -> list[str]:
    """The plugin modules the overrides name (``plugins=[a,b]``), read with Hydra's override
    parser: their components' configs must be stored before Hydra composes."""
    from hydra.core.override_parser.overrides_parser import OverridesParser

    try:
        overrides = OverridesParser.create().parse_overrides(list(overrides))
    except Exception:  # a syntax error: Hydra reports it when it parses the same line
        return []
    for override in overrides:
        if override.key_or_group.lstrip("+~") != "plugins":
            continue
        if override.is_sweep_override():
            raise ValueError("plugins cannot be swept; list every plugin in one plugins=[...]")
        value = override.value()
        return [str(v) for v in (value if isinstance(value, list) else [value]) if v]
    return []


def screen_command_line(overrides, registry: Registry | None = None, *,
                        user_configs: bool = False) -> Registry:
    """What must happen before Hydra composes the config of ``topomap <overrides>``: the registry
    (of the plugins the overrides name, unless given), the command line screened
    (:func:`~topomap.app.compose.config_checks.check_overrides`: Hydra would refuse an unknown key or a preset
    that does not fit with its own message) and every component's config stored.
    ``user_configs``: the command line brings config folders of its own (``-cd``, ``-cp``,
    ``-cn``), whose options topomap does not know."""
    registry = registry or Registry.load(plugins_named(overrides))
    check_overrides(overrides, registry, user_configs=user_configs)
    store_configs(registry)
    return registry


def compose(overrides=(), registry: Registry | None = None, *, screened: bool = False,
            return_hydra_config=False):
    """The composed config of ``topomap <overrides>`` (Hydra's compose API; for notebooks and
    tests).  The command line is screened and the registry's component configs are stored
    first (:func:`screen_command_line`), unless ``screened``: that was done with ``registry``."""
    from hydra import compose as hydra_compose
    from hydra import initialize_config_module

    overrides = renamed_overrides(overrides)
    if not (screened and registry is not None):
        screen_command_line(overrides, registry)
    with initialize_config_module(version_base="1.3", config_module=CONFIG_MODULE):
        return hydra_compose(config_name="config", overrides=list(overrides),
                             return_hydra_config=return_hydra_config)
