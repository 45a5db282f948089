"""Typed configs, derived from the components themselves.

A component's config is its factory's signature: every parameter becomes a field with the
parameter's annotation and default (a parameter without a default is required, ``???``), plus
``component``, the registered name that selects it.  So ``topomap clusters.ns=abc`` or a misspelt
key fails at once, and a config can never drift from the constructor it feeds.  Two conventions:
a parameter named ``seed`` defaults to the run's ``${seed}``, and the arguments the app supplies
itself (:data:`RUNTIME_ARGS`) are not config fields.

:func:`store_configs` puts every component's config into Hydra's ConfigStore as ``<kind>/<name>``
(with the values of a plugin's own YAML file for it, if it ships one) and the top-level schema as
``topomap_schema``; ``conf/config.yaml`` composes them.

Closed configs: Hydra checks the types; :func:`check_config` checks the composed config once,
before anything is built (a key no schema of the selected components declares, added with ``+``
or by a YAML file; a required value left out), naming the nearest valid key.  The command line is
screened before Hydra composes it (:func:`check_overrides`), in the same words: Hydra itself
refuses a key it does not know or a preset setting a field the chosen component lacks, before
there is a config to check, with a message that does not name the key meant; and a sweep with a
misspelt key stops before its first job.
"""

from __future__ import annotations

import dataclasses
import inspect
import re
import typing
from dataclasses import MISSING as _NO_DEFAULT
from dataclasses import dataclass, field, make_dataclass
from enum import Enum
from importlib import resources
from pathlib import Path
from typing import Any, Optional

from omegaconf import II, MISSING, OmegaConf

from ..core.learner import MapLearner
from .kinds import KINDS

__all__ = ["Config", "RunConf", "Objective", "LearnerConf", "OutputConf", "RUNTIME_ARGS", "schema_of",
           "learner_schema", "learner_key", "store_configs", "read_yaml_options", "check_overrides",
           "check_config", "group_options", "default_choices"]

#: factory arguments the app passes itself; never config fields
RUNTIME_ARGS = frozenset({"extra_actions"})
#: MapLearner arguments that are not ``learner.*`` fields: the components, the run's seed and
#: callbacks, and the settings the components stand for (``n_clusters``: ``clusters.ns``, ...)
_LEARNER_COMPONENT_ARGS = frozenset({kind.learner_arg for kind in KINDS.values() if kind.learner_arg}
                                    | {"n_clusters", "n_states", "random_state", "callbacks"})
_PRIMITIVES = (int, float, bool, str)


def _config_type(annotation, default):
    """The OmegaConf field type for a parameter: its annotation where OmegaConf can check it, else
    the type of its default (``str | OfficeLayout`` with default ``"paper"`` gives ``str``)."""
    args = [a for a in typing.get_args(annotation) if a is not type(None)]
    optional = type(None) in typing.get_args(annotation)
    if annotation in _PRIMITIVES:
        return annotation
    if optional and len(args) == 1 and args[0] in _PRIMITIVES:
        return Optional[args[0]]
    if optional and len(args) == 1 and typing.get_origin(args[0]) is list:
        return Optional[_config_type(args[0], None)]
    origin = typing.get_origin(annotation)
    if origin in (list, tuple) and all(a in _PRIMITIVES for a in typing.get_args(annotation)[:1]):
        return list[typing.get_args(annotation)[0]] if typing.get_args(annotation) else list[Any]
    if isinstance(default, _PRIMITIVES):
        return Optional[type(default)] if optional else type(default)
    return Any


def _field(name: str, typ, default):
    if default is inspect.Parameter.empty:
        return (name, typ, field(default=MISSING))
    if name == "seed":
        return (name, typ, field(default=II("seed")))
    if isinstance(default, (list, tuple, dict)):
        return (name, typ, field(default_factory=lambda d=default: type(d)(d)))
    return (name, typ, field(default=default))


def _parameters(factory):
    """``(name, annotation, default)`` of the factory's configurable parameters."""
    target = factory.__init__ if inspect.isclass(factory) else factory
    try:
        hints = typing.get_type_hints(target)
    except Exception:  # unresolvable annotations: fall back to the defaults' types
        hints = {}
    out = []
    for p in inspect.signature(factory).parameters.values():
        if p.name in RUNTIME_ARGS or p.kind in (p.VAR_POSITIONAL, p.VAR_KEYWORD):
            continue
        out.append((p.name, hints.get(p.name, Any), p.default))
    return out


def schema_of(component) -> type:
    """The typed config dataclass of a registered component (derived unless it brings one)."""
    if component.config is not None:
        if not (dataclasses.is_dataclass(component.config)
                and "component" in {f.name for f in dataclasses.fields(component.config)}):
            raise ValueError(f"{component.kind} component {component.name!r}: config must be a "
                             "dataclass with a 'component' field (or left out, to be derived)")
        return component.config
    fields = [("component", str, field(default=component.name))]
    fields += [_field(n, _config_type(a, d), d) for n, a, d in _parameters(component.factory)]
    cls_name = "".join(w.title() for w in f"{component.kind}_{component.name}".split("_"))
    return make_dataclass(f"{cls_name}Conf", fields)


def learner_schema() -> type:
    """``learner.*``: the :class:`MapLearner` arguments that are not components."""
    fields = [_field(n, _config_type(a, d), d) for n, a, d in _parameters(MapLearner)
              if n not in _LEARNER_COMPONENT_ARGS]
    return make_dataclass("LearnerConf", fields)


#: ``learner.*``, derived from :class:`MapLearner`
LearnerConf = learner_schema()


@dataclass
class OutputConf:
    #: arcs drawn and exported to GraphML when P(x'|x,u) exceeds this (the paper: 0.8)
    min_prob: float = 0.8
    #: write PNG figures
    figures: bool = True
    #: the phase-1 state shown before/after its split (None: the first state that was split)
    compound_state: Optional[int] = None
    #: show progress bars on the terminal
    progress: bool = True
    #: a run into a folder that holds another run's outputs replaces them (false: refuses)
    overwrite: bool = False


class Task(Enum):
    """What a run does: learn a map (the default), or localise on a saved one."""

    learn = "learn"
    localize = "localize"


class Objective(Enum):
    """The value a run returns to a sweeper that optimises it (``hydra/sweeper=optuna``); both
    are better when larger (:data:`topomap.app.evaluate.OBJECTIVES`)."""

    heldout_loglik = "heldout_loglik"
    ari = "ari"


@dataclass
class RunConf:
    """The run settings at the top level of a config (:class:`Config` adds the groups)."""

    seed: int = 0
    plugins: list[str] = field(default_factory=list)
    #: learn: learn a map from the data; localize: apply the saved ``map`` to the data
    task: Task = Task.learn
    #: the map.json a ``task=localize`` run applies
    map: Optional[str] = None
    #: what the run returns to an optimising sweeper: heldout_loglik (needs held-out data, no
    #: ground truth) or ari (needs ground truth)
    objective: Objective = Objective.heldout_loglik


#: The top level of a run's config: the run settings, one group per kind of component
#: (:data:`~topomap.app.kinds.KINDS`; each holds a ``<kind>/<name>`` config), ``learner`` and
#: ``output``.
Config = make_dataclass("Config", [
    *((kind, Any, field(default=MISSING)) for kind in KINDS),
    ("learner", LearnerConf, field(default_factory=LearnerConf)),
    ("output", OutputConf, field(default_factory=OutputConf)),
], bases=(RunConf,))


# ------------------------------------------------------------------------------ plugin YAML files
_PACKAGE_HEADER = re.compile(r"^#\s*@package\s+(\S+)", re.MULTILINE)


def _yaml_folder(path: str):
    """A Traversable for ``pkg://package.sub`` or ``file:///abs/dir`` (or a plain path)."""
    if path.startswith("pkg://"):
        try:
            return resources.files(path[len("pkg://"):].replace("/", "."))
        except ImportError as exc:
            raise ValueError(f"config folder {path} cannot be imported ({exc})") from None
    folder = Path(path[len("file://"):] if path.startswith("file://") else path)
    if not folder.is_dir():
        raise ValueError(f"config folder {path} does not exist")
    return folder


def read_yaml_options(path: str) -> list[tuple[str, str, str, str | None]]:
    """``(group, option, text, package)`` of every ``<group>/<option>.yaml`` below ``path``."""
    out = []

    def walk(folder, group):
        for item in sorted(folder.iterdir(), key=lambda i: i.name):
            if item.is_dir() and not item.name.startswith(("_", ".")):
                walk(item, f"{group}/{item.name}" if group else item.name)
            elif item.name.endswith(".yaml") and group:
                text = item.read_text()
                header = _PACKAGE_HEADER.search(text)
                out.append((group, item.name[:-5], text, header.group(1) if header else None))

    walk(_yaml_folder(path), "")
    return out


def _merge_yaml(schema, text: str, name: str):
    """A component's typed config with the values of its YAML file (which may name the legacy
    ``<name>_schema`` in its defaults list; that entry is implied)."""
    values = OmegaConf.create(text) or OmegaConf.create({})
    defaults = [d for d in values.pop("defaults", []) if d not in (f"{name}_schema", "_self_")]
    if defaults:
        raise ValueError(f"config option {name}.yaml: a component's YAML file may only set values "
                         f"(its defaults list names {list(defaults)})")
    return OmegaConf.merge(OmegaConf.structured(schema), values)


def store_configs(registry) -> None:
    """Put the top-level schema and every component's config into Hydra's ConfigStore."""
    from hydra.core.config_store import ConfigStore

    cs = ConfigStore.instance()
    cs.store(name="topomap_schema", node=Config)
    files = {}
    for path, provider in registry.config_paths():
        try:
            options = read_yaml_options(path)
        except ValueError as exc:
            raise ValueError(f"plugin {provider!r}: {exc}") from None
        for group, option, text, package in options:
            files[(group, option)] = (text, package, provider)
    for kind, name, comp, provider in registry.items():
        text = files.pop((kind, name), (None,))[0]
        node = schema_of(comp) if text is None else _merge_yaml(schema_of(comp), text, name)
        cs.store(group=kind, name=name, node=node, provider=provider)
    for (group, option), (text, package, provider) in files.items():
        cs.store(group=group, name=option, node=OmegaConf.create(text), package=package,
                 provider=provider)
    store_optuna_sweeper(cs)


def store_optuna_sweeper(cs) -> None:
    """``hydra/sweeper=optuna`` set for topomap, when the Optuna sweeper plugin is installed
    (``pip install "topomap[optuna]"``): the plugin's own config (``OptunaSweeperConf``), but
    maximising (both of topomap's objectives are better when larger; the plugin minimises by
    default), one trial at a time, and going on past jobs that cannot run (``max_failure_rate``:
    such a job is a failed trial and a row of ``summary.csv``, as in a grid); and its default
    sampler, ``hydra/sweeper/sampler=tpe``, seeded by the run's ``seed`` (the same command
    proposes the same trials).  Every field can still be set: ``hydra.sweeper.n_trials=30``."""
    try:
        from hydra_plugins.hydra_optuna_sweeper.config import OptunaSweeperConf, TPESamplerConfig
    except ImportError:
        return
    from hydra.core.plugins import Plugins

    Plugins.instance()  # Hydra's first plugin scan stores the plugin's options: let it come first

    @dataclass
    class TopomapOptunaSweeperConf(OptunaSweeperConf):
        direction: Any = "maximize"
        n_jobs: int = 1
        max_failure_rate: float = 1.0

    @dataclass
    class SeededTPESamplerConf(TPESamplerConfig):
        seed: Optional[int] = II("seed")

    cs.store(group="hydra/sweeper", name="optuna", node=TopomapOptunaSweeperConf, provider="topomap")
    cs.store(group="hydra/sweeper/sampler", name="tpe", node=SeededTPESamplerConf,
             provider="topomap")


def fields_of(schema) -> dict:
    """``{field: default}`` of a config dataclass (``MISSING`` for required ones)."""
    out = {}
    for f in dataclasses.fields(schema):
        if f.default is not _NO_DEFAULT:
            out[f.name] = f.default
        elif f.default_factory is not _NO_DEFAULT:
            out[f.name] = f.default_factory()
        else:
            out[f.name] = MISSING
    return out


def learner_key(param: str) -> str:
    """The config key of a :class:`MapLearner` parameter an error names: a component's parameter
    under its group (``stopping.n_states`` -> ``stop.n_states``), the learner's own settings under
    ``learner`` (``reg_covar`` -> ``learner.reg_covar``); any other name is kept."""
    head, dot, rest = param.partition(".")
    groups = {kind.learner_arg: name for name, kind in KINDS.items() if kind.learner_arg}
    if head in groups:
        return groups[head] + dot + rest
    return f"learner.{param}" if param in fields_of(LearnerConf) else param


# ------------------------------------------------------------------------------ closed configs
def _keys_of(schema, prefix: str) -> set[str]:
    return {f"{prefix}.{k}" for k in fields_of(schema)}


def valid_keys(registry) -> set[str]:
    """Every key a config may hold: the top level, every field of every registered component
    (of any component of its group), ``learner.*`` and ``output.*``."""
    keys = set(fields_of(Config)) | _keys_of(LearnerConf, "learner") | _keys_of(OutputConf, "output")
    for kind, _, comp, _ in registry.items():
        keys |= _keys_of(schema_of(comp), kind)
    return keys


def _unknown(key: str, valid, where: str = "") -> ValueError:
    import difflib

    close = difflib.get_close_matches(key, sorted(valid), n=1, cutoff=0.6)
    hint = f"; did you mean {close[0]}?" if close else ""
    return ValueError(f"unknown config key {key!r}{where}{hint} (topomap --help lists the config)")


def check_overrides(overrides, registry, *, user_configs: bool = False) -> None:
    """Screen a command line before Hydra composes it, in topomap's words.

    * a key no config declares, ``+`` or not: refused, naming the nearest valid key;
    * a group's option that does not exist (``env=gridrom``): refused, naming the nearest option;
    * a key of a component that is not selected (``data.path`` while ``data=simulate``):
      refused, naming the components that have that key (Hydra would offer to append it);
    * a preset that sets a field the chosen component lacks (:func:`_check_preset`).

    ``hydra.*`` and deletions are left to Hydra; so are the options of a group when the command
    line brings config folders of its own (``user_configs``, or ``hydra.searchpath``), which may
    add options."""
    from hydra.core.override_parser.overrides_parser import OverridesParser

    try:
        parsed = OverridesParser.create().parse_overrides(list(overrides))
    except Exception:  # a syntax error: Hydra reports it with its own message
        return
    valid = valid_keys(registry)
    groups = set(KINDS) | {"experiment"}
    for override in parsed:
        key = override.key_or_group
        if (override.is_delete() or "/" in key or key.split(".")[0] == "hydra"
                or key in groups or key in valid):
            continue
        raise _unknown(key, valid)
    user_configs = user_configs or any(o.key_or_group.startswith("hydra.searchpath")
                                       for o in parsed)
    chosen = {}  # group -> the options the command line chooses (several in a sweep)
    for o in parsed:
        if o.key_or_group in groups and not o.is_delete():
            options = _options_of(o)
            if options is not None:
                chosen[o.key_or_group] = options
    if not user_configs:
        for group, options in chosen.items():
            for option in options:
                _check_option(group, option, registry)
    _check_component_keys(parsed, chosen, registry)
    choices = {g: v[0] for g, v in chosen.items() if len(v) == 1}
    if "experiment" in choices:
        _check_preset(choices.pop("experiment"), choices, registry)


def _options_of(override) -> list[str] | None:
    """The options a group override chooses: one, the values of a plain sweep
    (``env=office,gridroom``), or None when they are not spelt out (e.g. ``glob(...)``)."""
    value = override.value()
    if isinstance(value, str):
        return [value]
    if override.is_sweep_override() and override.is_discrete_sweep():
        return [str(v) for v in override.sweep_string_iterator()]
    return None


def group_options(group: str, registry) -> list[str]:
    """The options of a config group: the registered components (and the options of plugins'
    YAML files) of a kind; the packaged and plugins' presets for ``experiment``."""
    names = set(registry.names(group)) if group in KINDS else set()
    if group == "experiment":
        names |= {p.name[:-5] for p in (resources.files("topomap.conf") / "experiment").iterdir()
                  if p.name.endswith(".yaml")}
    for path, _ in registry.config_paths():
        try:
            names |= {option for g, option, _, _ in read_yaml_options(path) if g == group}
        except ValueError:
            continue  # store_configs names the broken folder
    return sorted(names)


def _check_option(group: str, option: str, registry) -> None:
    """Refuse ``<group>=<option>`` when the group has no such option, naming the nearest one."""
    import difflib

    options = group_options(group, registry)
    if option in options or not options:
        return
    close = difflib.get_close_matches(option, options, n=1, cutoff=0.6)
    hint = f"; did you mean {group}={close[0]}?" if close else ""
    raise ValueError(f"unknown {group}={option}{hint} (the options: {', '.join(options)})")


def default_choices() -> dict[str, str]:
    """The component each group selects when the command line does not choose (the defaults
    list of ``conf/config.yaml``)."""
    text = (resources.files("topomap.conf") / "config.yaml").read_text()
    defaults = OmegaConf.to_container(OmegaConf.create(text)).get("defaults") or []
    return {k: v for d in defaults if isinstance(d, dict) for k, v in d.items() if k in KINDS}


def _check_component_keys(parsed, chosen: dict, registry) -> None:
    """Refuse ``<group>.<key>=...`` when no selected component of ``group`` has ``key``, naming
    the components that have it (``data.path`` belongs to ``data=file``)."""
    preset = {}
    if len(chosen.get("experiment", [])) == 1:
        preset = {k.split("/")[-1]: v for d in (_load_preset(chosen["experiment"][0]) or {})
                  .get("defaults") or [] if isinstance(d, dict) for k, v in d.items()}
    defaults = default_choices()
    for o in parsed:
        group, dot, key = o.key_or_group.lstrip("+~").partition(".")
        if o.is_delete() or not dot or group not in KINDS or "." in key:
            continue
        told = group in chosen
        selected = chosen.get(group) or [preset.get(group) or defaults.get(group)]
        for option in selected:
            if option not in registry.names(group):
                continue
            if key in fields_of(schema_of(registry.get(group, option))):
                continue
            owners = [n for n in registry.names(group)
                      if key in fields_of(schema_of(registry.get(group, n)))]
            if not owners:
                continue  # no component has it: the unknown-key check speaks
            more = f" (and {', '.join(f'{group}={n}' for n in owners[1:])})" if owners[1:] else ""
            where = f"{group}={owners[0]}{more}"
            if told:
                raise ValueError(f"{group}.{key} is not a key of {group}={option}: it belongs "
                                 f"to {where}; leave it out, or choose {group}={owners[0]}")
            raise ValueError(f"{group}.{key} belongs to {where}, not to {group}={option} (the "
                             f"default); add {group}={owners[0]}")


def _load_preset(name: str) -> dict | None:
    path = resources.files("topomap.conf") / "experiment" / f"{name}.yaml"
    return OmegaConf.to_container(OmegaConf.create(path.read_text())) if path.is_file() else None


def preset_overrides(name: str, without=()) -> list[str] | None:
    """The command-line overrides that ``experiment=<name>`` stands for (its group choices, then
    its values), leaving out the groups in ``without``; None if there is no such preset."""
    preset = _load_preset(name)
    if preset is None:
        return None
    out = [f"{k.split('/')[-1]}={v}" for d in preset.get("defaults") or []
           if isinstance(d, dict) for k, v in d.items() if k.split("/")[-1] not in without]
    return out + [f"{section}.{k}={v}" for section, values in preset.items()
                  if section not in ("defaults", *without) and isinstance(values, dict)
                  for k, v in values.items()]


def _check_preset(name: str, choices: dict, registry) -> None:
    """Refuse ``experiment=<name> <group>=<option>`` when the preset sets a field of ``group``
    that the chosen component lacks (e.g. ``experiment=gridroom stop=auto``: the preset's
    ``stop.n_states``), spelling out the preset's other settings to give instead."""
    preset = _load_preset(name)
    if preset is None:
        return  # Hydra names the missing preset
    for group, option in choices.items():
        if not isinstance(preset.get(group), dict) or option not in registry.names(group):
            continue
        fields = set(fields_of(schema_of(registry.get(group, option))))
        lost = [k for k in preset[group] if k not in fields]
        if lost:
            rest = " ".join(preset_overrides(name, without=choices))
            raise ValueError(
                f"experiment={name} sets {group}.{lost[0]}, which {group}={option} does not "
                f"have; give the preset's other settings instead: topomap {rest} "
                f"{group}={option}")


def check_config(cfg, registry) -> None:
    """Refuse a composed config (a plain mapping) holding a key that its schemas do not declare,
    e.g. one added with ``+`` or by a YAML file (only the selected components' fields count), or
    lacking a required value (``???``)."""
    for section, values in cfg.items():
        for key, value in (values.items() if isinstance(values, dict) else ()):
            if value == "???":
                raise ValueError(f"{section}.{key} is required: give it on the command line, "
                                 f"e.g. topomap ... {section}.{key}=<value>")
    top = set(fields_of(Config))
    extra = [k for k in cfg if k not in top and k != "hydra"]
    sections = {"learner": LearnerConf, "output": OutputConf}
    for kind in KINDS:
        if isinstance(cfg.get(kind), dict) and "component" in cfg[kind]:
            sections[kind] = schema_of(registry.get(kind, cfg[kind]["component"]))
    for section, schema in sections.items():
        allowed = set(fields_of(schema))
        extra += [f"{section}.{k}" for k in cfg.get(section) or {} if k not in allowed]
    if extra:
        key = extra[0]
        section = key.split(".")[0]
        valid = top | set().union(*(_keys_of(s, n) for n, s in sections.items()))
        comp = (cfg.get(section) or {}).get("component") if "." in key else None
        raise _unknown(key, valid, f" for {section}={comp}" if comp else "")
