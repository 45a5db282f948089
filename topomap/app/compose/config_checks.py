"""Closed configs: the command line and the composed config checked against the schemas of
:mod:`topomap.app.compose.schemas`, in topomap's words.

:func:`check_config` checks the composed config once, before anything is built (a key no schema
of the selected components declares, added with ``+`` or by a YAML file; a required value left
out), naming the nearest valid key.  The command line is screened before Hydra composes it
(:func:`check_overrides`), in the same words: Hydra itself refuses a key it does not know or a
preset setting a field the chosen component lacks, before there is a config to check, with a
message that does not name the key meant; and a sweep with a misspelt key stops before its first
job.
"""

from __future__ import annotations

import dataclasses
from importlib import resources

from omegaconf import OmegaConf

from ..results import OBJECTIVES, objective_direction
from .kinds import KINDS
from .schema_cache import renamed_of
from .schemas import OutputConf, config_schema, fields_of, learner_schema, schema_of
from .store import read_yaml_options

__all__ = ["check_overrides", "check_config", "check_search_direction", "group_options",
           "default_choices", "preset_overrides", "valid_keys", "renamed_keys"]


def _keys_of(schema, prefix: str) -> set[str]:
    """``<prefix>.<field>`` of every field, and of the fields of a nested settings config
    (``refine.soft.<key>``)."""
    keys = set()
    for name, default in fields_of(schema).items():
        keys.add(f"{prefix}.{name}")
        if dataclasses.is_dataclass(default):
            keys |= _keys_of(type(default), f"{prefix}.{name}")
    return keys


def valid_keys(registry) -> set[str]:
    """Every key a config may hold: the top level, every field of every registered component
    (of any component of its group), ``learner.*`` and ``output.*``."""
    keys = set(fields_of(config_schema())) | _keys_of(learner_schema(), "learner") | _keys_of(OutputConf, "output")
    for kind, _, comp, _ in registry.items():
        keys |= _keys_of(schema_of(comp), kind)
    return keys


def renamed_keys(registry) -> set[str]:
    """Every key of before a rename that some component's config still accepts
    (``refine.max_iter``, ``refine.soft.observed``; :func:`~topomap.app.compose.schema_cache.
    renamed_of`): the component's factory takes it with a warning naming the new key."""
    return {f"{kind}.{old}" for kind, _, comp, _ in registry.items()
            for old in renamed_of(schema_of(comp))}


def _has_key(schema, key: str) -> bool:
    """Whether a component's config ``schema`` has ``key``, or accepts it as a key of before a
    rename."""
    return key in fields_of(schema) or key in renamed_of(schema)


def _unknown(key: str, valid, where: str = "", groups=(), added: bool = False) -> ValueError:
    """The error of an unknown ``key``, naming the nearest valid key or, for a key without a
    dot, group (``groups``: chosen as ``group=<option>``); ``added``: given with ``+``."""
    import difflib

    candidates = set(valid) | set(groups) if "." not in key else set(valid) - set(groups)
    close = difflib.get_close_matches(key, sorted(candidates), n=1, cutoff=0.6)
    hint = ""
    if close:
        hint = (f"; did you mean the group {close[0]} ({close[0]}=<option>)?"
                if close[0] in groups else f"; did you mean {close[0]}?")
    plus = ("; the config is typed, so + adds no key" if added else "")
    return ValueError(f"unknown config key {key!r}{where}{hint}{plus} (topomap --help lists the "
                      "config)")


def _check_added(override, groups) -> None:
    """Refuse ``+key=value`` for a key or group topomap's config already has, as Hydra does
    for a structured config, in one line: drop the ``+`` (``++`` sets it either way)."""
    if not override.is_add():
        return
    key = override.key_or_group
    what = "a group" if key in groups else "a key"
    value = override.input_line.partition("=")[2]
    raise ValueError(f"{override.input_line}: {key} is {what} of the config already, and + adds "
                     f"only new ones; drop the +: {key}={value}")


def check_overrides(overrides, registry, *, user_configs: bool = False) -> None:
    """Screen a command line before Hydra composes it, in topomap's words.

    * a key no config declares, ``+`` or not: refused, naming the nearest valid key or group;
    * ``+key=value`` of a key or group the config has: refused (drop the ``+``), as Hydra does
      for a structured config; ``++key=value`` sets it;
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
    renamed = renamed_keys(registry)
    groups = set(KINDS) | {"experiment"}
    for override in parsed:
        _check_hydra_plugin(override)
    for override in parsed:
        key = override.key_or_group
        if override.is_delete() or "/" in key or key.split(".")[0] == "hydra":
            continue
        if key in groups or key in valid or key in renamed:
            continue
        raise _unknown(key, valid, groups=groups, added=override.is_add())
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
    _check_values(parsed, chosen, registry)
    choices = {g: v[0] for g, v in chosen.items() if len(v) == 1}
    if "experiment" in choices:
        _check_preset(choices.pop("experiment"), choices, registry)
    for override in parsed:  # a key of the chosen components, or a group, given with +
        if "/" not in override.key_or_group and override.key_or_group.split(".")[0] != "hydra":
            _check_added(override, groups)


#: Hydra's sweepers and launchers that come with an extra of topomap: (option, Hydra plugin
#: package, extra); the options are those of ``conf/hydra`` and of the plugins
HYDRA_PLUGIN_EXTRAS = {
    "hydra/sweeper": [(("optuna", "optuna_pricai2002"), "hydra_optuna_sweeper", "optuna")],
    "hydra/launcher": [(("joblib",), "hydra_joblib_launcher", "cluster"),
                       (("submitit_local", "submitit_slurm", "slurm"),
                        "hydra_submitit_launcher", "cluster"),
                       (("ray", "ray_aws", "ray_cluster"), "hydra_ray_launcher", "ray")],
}


def _check_hydra_plugin(override) -> None:
    """Refuse a sweeper or launcher whose Hydra plugin is not installed, naming the extra that
    brings it (Hydra would say only that it cannot find the option)."""
    import importlib.util

    group = override.key_or_group.lstrip("+~")
    if group not in HYDRA_PLUGIN_EXTRAS or override.is_delete():
        return
    options = _options_of(override) or []
    for options_of_plugin, package, extra in HYDRA_PLUGIN_EXTRAS[group]:
        for option in set(options) & set(options_of_plugin):
            if importlib.util.find_spec(f"hydra_plugins.{package}") is None:
                raise ValueError(f'{group}={option} needs the {package.replace("_", "-")} '
                                 f'plugin: pip install "topomap[{extra}]"')


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
    close = ([o for o in options if o.lower() == option.lower()]
             or difflib.get_close_matches(option, options, n=1, cutoff=0.6))
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
            if option is not None and (option not in registry.names(group) or _has_key(
                    schema_of(registry.get(group, option)), key)):
                continue
            owners = [n for n in registry.names(group)
                      if _has_key(schema_of(registry.get(group, n)), key)]
            if not owners:
                continue  # no component has it: the unknown-key check speaks
            more = f" (and {', '.join(f'{group}={n}' for n in owners[1:])})" if owners[1:] else ""
            where = f"{group}={owners[0]}{more}"
            if option is None:  # a part left to its whole's own (sensor: null)
                raise ValueError(f"{group}.{key} belongs to {where}, and no {group} is chosen; "
                                 f"add {group}={owners[0]}")
            if told:
                raise ValueError(f"{group}.{key} is not a key of {group}={option}: it belongs "
                                 f"to {where}; leave it out, or choose {group}={owners[0]}")
            raise ValueError(f"{group}.{key} belongs to {where}, not to {group}={option} (the "
                             f"default); add {group}={owners[0]}")


def _schema_of_key(key: str, chosen: dict, registry) -> list:
    """The config dataclasses that hold ``key`` for the components the command line selects
    (several in a sweep of a group), and the key's field name in them; for a key of a nested
    settings config (``refine.hard.max_iter``, ``learner.motion.check.holdout``), that config's
    dataclass."""
    from .schemas import OutputConf

    section, dot, name = key.partition(".")
    if not dot:
        return [(config_schema(), section)]
    group, dot, name = name.rpartition(".")
    if section == "learner":
        schemas = [learner_schema()]
    elif section == "output":
        schemas = [OutputConf]
    elif section in KINDS:
        options = chosen.get(section) or [default_choices().get(section)]
        schemas = [schema_of(registry.get(section, o)) for o in options
                   if o in registry.names(section)]
    else:
        return []
    for part in group.split(".") if group else ():  # into a nested settings config
        schemas = [f.type for schema in schemas for f in dataclasses.fields(schema)
                   if f.name == part and dataclasses.is_dataclass(f.type)]
    return [(schema, name) for schema in schemas]


def _describe(typ) -> str:
    """What a config field of type ``typ`` holds, in words."""
    import enum
    import typing

    args = [a for a in typing.get_args(typ) if a is not type(None)]
    optional = type(None) in typing.get_args(typ)
    base = args[0] if optional and len(args) == 1 else typ
    words = {int: "an integer", float: "a number", bool: "true or false", str: "text"}
    if isinstance(base, type) and issubclass(base, enum.Enum):
        what = "one of " + ", ".join(m.value for m in base)
    else:
        what = words.get(base, f"a {getattr(base, '__name__', base)}")
    return what + (" or null" if optional else "")


def _check_values(parsed, chosen: dict, registry) -> None:
    """Refuse ``key=value`` when the value does not fit the key's type, in one line naming the
    key (``clusters.ns=abc is not an integer``), with the nearest valid choice of a key that
    takes a few (``task=localise``: did you mean task=localize?)."""
    import difflib
    import enum
    import typing

    from omegaconf.errors import ValidationError

    for o in parsed:
        key = o.key_or_group.lstrip("+~")
        if o.is_delete() or key.split(".")[0] == "hydra" or key in KINDS or "/" in key:
            continue
        if o.is_sweep_override():
            if not o.is_discrete_sweep():
                continue
            values = list(o.sweep_iterator())
        else:
            values = [o.value()]
        for schema, name in _schema_of_key(key, chosen, registry):
            fields = typing.get_type_hints(schema)
            if name not in fields:
                continue
            node = OmegaConf.structured(schema)
            for value in values:
                try:
                    node[name] = value
                except ValidationError:
                    text = "null" if value is None else str(value)
                    msg = f"{key}={text} is not {_describe(fields[name])}"
                    typ = fields[name]
                    if isinstance(typ, type) and issubclass(typ, enum.Enum):
                        close = difflib.get_close_matches(text, [m.value for m in typ], n=1)
                        msg += f"; did you mean {key}={close[0]}?" if close else ""
                    raise ValueError(msg) from None


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
    top = set(fields_of(config_schema()))
    extra = [k for k in cfg if k not in top and k != "hydra"]
    sections = {"learner": learner_schema(), "output": OutputConf}
    for kind in KINDS:
        if isinstance(cfg.get(kind), dict) and "component" in cfg[kind]:
            sections[kind] = schema_of(registry.get(kind, cfg[kind]["component"]))
    for section, schema in sections.items():
        allowed = set(fields_of(schema)) | set(renamed_of(schema))
        extra += [f"{section}.{k}" for k in cfg.get(section) or {} if k not in allowed]
    if extra:
        key = extra[0]
        section = key.split(".")[0]
        valid = top | set().union(*(_keys_of(s, n) for n, s in sections.items()))
        comp = (cfg.get(section) or {}).get("component") if "." in key else None
        raise _unknown(key, valid, f" for {section}={comp}" if comp else "")


def check_search_direction(multirun_cfg) -> None:
    """Refuse (a ValueError naming ``hydra.sweeper.direction``) a search that would optimise its
    objective the wrong way: the sweeper's ``direction`` against the objective's
    (:data:`~topomap.app.results.OBJECTIVES`).  A grid has no direction: nothing to check."""
    direction = OmegaConf.select(multirun_cfg, "hydra.sweeper.direction", default=None)
    direction = getattr(direction, "name", direction)  # the plugin's Direction enum, or text
    objective = OmegaConf.select(multirun_cfg, "objective", default=None)
    objective = getattr(objective, "value", objective)
    wanted = objective_direction(objective) if objective in OBJECTIVES else None
    if isinstance(direction, str) and wanted and direction != wanted:
        raise ValueError(f"hydra.sweeper.direction={direction}, but objective={objective} is "
                         f"better when {'larger' if wanted == 'maximize' else 'smaller'}; give "
                         f"hydra.sweeper.direction={wanted}")
