"""Typed configs, derived from the components themselves.

A component's config is its factory's signature: every parameter becomes a field with the
parameter's annotation and default (a parameter without a default is required, ``???``), plus
``component``, the registered name that selects it.  So ``topomap clusters.ns=abc`` or a misspelt
key fails at once, and a config can never drift from the constructor it feeds.  Two conventions:
a parameter named ``seed`` defaults to the run's ``${seed}``, and the arguments the app supplies
itself (:data:`RUNTIME_ARGS`) are not config fields.

:func:`~topomap.app.compose.store.store_configs` puts them into Hydra's ConfigStore, where
``conf/config.yaml`` composes them.

Closed configs: Hydra checks the types; :mod:`topomap.app.compose.config_checks` checks the command line
and the composed config against these schemas, naming the nearest valid key.
"""

from __future__ import annotations

import copy
import dataclasses
import inspect
import typing
import warnings
from contextlib import contextmanager
from dataclasses import MISSING as _NO_DEFAULT
from dataclasses import dataclass, field, make_dataclass
from enum import Enum
from typing import Any, Optional

from omegaconf import II, MISSING, OmegaConf
from omegaconf.errors import ValidationError

from ...core.checks import ParameterError
from ..results import OBJECTIVES
from .kinds import KINDS, parts_of
from .schema_cache import cached_schema, renamed_of

__all__ = ["Config", "RunConf", "Objective", "LearnerConf", "OutputConf", "RUNTIME_ARGS", "schema_of",
           "settings_schema", "learner_schema", "config_schema", "learner_key", "config_keys",
           "fields_of", "moved_keys"]

#: factory arguments the app passes itself; never config fields
RUNTIME_ARGS = frozenset({"extra_actions"})
#: the import path of the learner, whose arguments but the components are ``learner.*``
LEARNER = "topomap.core.learner:MapLearner"
_PRIMITIVES = (int, float, bool, str)


def _config_type(annotation, default):
    """The OmegaConf field type for a parameter: its annotation where OmegaConf can check it, else
    the type of its default (``str | OfficeLayout`` with default ``"paper"`` gives ``str``); a
    parameter whose default is a dataclass instance (``EMRefinement``'s ``soft``) gets a nested
    config of that dataclass's fields (``refine.soft.<key>``, :func:`settings_schema`)."""
    if dataclasses.is_dataclass(default) and not isinstance(default, type):
        return settings_schema(type(default))
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


def settings_schema(settings) -> type:
    """The typed config of a settings dataclass: its fields, their types and defaults, in a
    dataclass of its own that Hydra may change (the settings class may be frozen)."""
    hints = typing.get_type_hints(settings)
    return make_dataclass(f"{settings.__name__}Conf", [
        _field(f.name, _config_type(hints.get(f.name, Any), f.default), f.default)
        for f in dataclasses.fields(settings)])


def _field(name: str, typ, default):
    if default is inspect.Parameter.empty:
        return (name, typ, field(default=MISSING))
    if dataclasses.is_dataclass(default) and not isinstance(default, type):
        return (name, typ, field(default_factory=typ))
    if name == "seed":
        return (name, typ, field(default=II("seed")))
    if isinstance(default, (list, tuple, dict)):
        return (name, typ, field(default_factory=lambda d=default: type(d)(d)))
    return (name, typ, field(default=default))


def _parameters(factory, exclude=()):
    """``(name, annotation, default)`` of the factory's configurable parameters (but those named
    in ``exclude``)."""
    target = factory.__init__ if inspect.isclass(factory) else factory
    try:
        hints = typing.get_type_hints(target)
    except Exception:  # unresolvable annotations: fall back to the defaults' types
        hints = {}
    out = []
    for p in inspect.signature(factory).parameters.values():
        if (p.name in RUNTIME_ARGS or p.name in exclude
                or p.kind in (p.VAR_POSITIONAL, p.VAR_KEYWORD)):
            continue
        annotation = hints.get(p.name, p.annotation)  # a signature made by hand: its own
        out.append((p.name, Any if annotation is p.empty else annotation, p.default))
    return out


def schema_of(component) -> type:
    """The typed config dataclass of a registered component (derived unless it brings one).
    A factory named by its import path (topomap's own) is not imported: its config is kept
    between commands (:func:`~topomap.app.compose.schema_cache.cached_schema`).  A factory's
    ``renamed_params`` (``{"max_iter": "hard.max_iter"}``, the keys of before a rename) come
    with it (:func:`~topomap.app.compose.schema_cache.renamed_of`)."""
    if component.config is not None:
        if not (dataclasses.is_dataclass(component.config)
                and "component" in {f.name for f in dataclasses.fields(component.config)}):
            raise ValueError(f"{component.kind} component {component.name!r}: config must be a "
                             "dataclass with a 'component' field (or left out, to be derived)")
        return component.config

    def derive():
        factory = component.load_factory()
        fields = [("component", str, field(default=component.name))]
        fields += [_field(n, _config_type(a, d), d)
                   for n, a, d in _parameters(factory, parts_of(component.kind))]
        cls_name = "".join(w.title() for w in f"{component.kind}_{component.name}".split("_"))
        schema = make_dataclass(f"{cls_name}Conf", fields)
        schema.__renamed__ = dict(getattr(factory, "renamed_params", None) or {})
        return schema

    if isinstance(component.factory, str):
        return cached_schema(f"{component.kind}/{component.name}={component.factory}", derive)
    return derive()


def moved_keys(kind: str, schema, params: dict) -> dict:
    """A component's config ``params`` (a plain mapping; ``schema`` its typed config) with the
    keys of before a rename (:func:`~topomap.app.compose.schema_cache.renamed_of`) moved to
    their keys now, each value typed as its new key is (``refine.tol=0`` gives
    ``hard.tol`` 0.0, as ``refine.hard.tol=0`` does), a ``FutureWarning`` naming the new key
    for each; a ``ValueError`` when the new key is given another value too."""
    renamed = renamed_of(schema)
    given = [(old, new) for old, new in renamed.items() if _get(params, old) is not _ABSENT]
    if not given:
        return params
    out, typed = copy.deepcopy(dict(params)), OmegaConf.structured(schema)
    for old, new in given:
        parent, _, key = old.rpartition(".")
        value = (out[parent] if parent else out).pop(key)
        if not new:
            warnings.warn(f"{kind}.{old} has no effect (it never had) and goes in 0.4; leave it "
                          "out", FutureWarning, stacklevel=3)
            continue
        warnings.warn(f"{kind}.{old} was renamed {kind}.{new} in 0.3; the old key goes in 0.4",
                      FutureWarning, stacklevel=3)
        default = OmegaConf.select(typed, new)
        try:
            OmegaConf.update(typed, new, value)
            value = OmegaConf.select(typed, new)
        except ValidationError:  # the component names the field and the problem
            pass
        group, _, name = new.rpartition(".")
        target = out.setdefault(group, {}) if group else out
        if target.get(name, default) not in (default, value):
            raise ValueError(f"{kind}.{old} is the old key of {kind}.{new}: give {kind}.{new} "
                             "only")
        target[name] = value
    return out


_ABSENT = object()


def _get(params, path: str):
    """The value at the dotted ``path`` of nested mappings, or ``_ABSENT``."""
    for key in path.split("."):
        if not isinstance(params, dict) or key not in params:
            return _ABSENT
        params = params[key]
    return params


def learner_schema() -> type:
    """``learner.*``: the :class:`~topomap.MapLearner` arguments that are not components (nor
    the run's seed and callbacks, the settings the components stand for -- ``n_clusters`` is
    ``clusters.ns`` -- or the deprecated names of components)."""

    def derive():
        from ...core.components import RENAMED
        from ...core.learner import MapLearner

        left_out = ({kind.learner_arg for kind in KINDS.values() if kind.learner_arg}
                    | {"n_clusters", "n_states", "random_state", "callbacks"} | set(RENAMED))
        return make_dataclass("LearnerConf", [_field(n, _config_type(a, d), d)
                                              for n, a, d in _parameters(MapLearner)
                                              if n not in left_out])

    return cached_schema(f"learner={LEARNER}", derive)


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
    #: a sweep into a ``hydra.sweep.dir`` that holds jobs runs only those it has not completed
    #: with the same config (false: refuses the folder); an Optuna search goes on with its study
    resume: bool = False


class Task(Enum):
    """What a run does: learn a map (the default), or localise on a saved one."""

    learn = "learn"
    localize = "localize"


#: The value a run returns to a sweeper that optimises it (``hydra/sweeper=optuna``): one of
#: :data:`~topomap.app.results.OBJECTIVES`
Objective = Enum("Objective", {name: name for name in OBJECTIVES}, module=__name__)


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


_made: dict[str, type] = {}


def config_schema() -> type:
    """The top level of a run's config: the run settings, one group per kind of component
    (:data:`~topomap.app.compose.kinds.KINDS`; each holds a ``<kind>/<name>`` config, or None
    for a part of another component left to that component's default),
    ``learner`` (:func:`learner_schema`) and ``output``."""
    if "Config" not in _made:
        learner = learner_schema()
        _made["Config"] = make_dataclass("Config", [
            *((name, Any, field(default=None if kind.part_of else MISSING))
              for name, kind in KINDS.items()),
            ("learner", learner, field(default_factory=learner)),
            ("output", OutputConf, field(default_factory=OutputConf)),
        ], bases=(RunConf,))
    return _made["Config"]


def __getattr__(name):
    """``Config`` and ``LearnerConf``, made on first use (:func:`config_schema`,
    :func:`learner_schema`)."""
    if name == "Config":
        return config_schema()
    if name == "LearnerConf":
        return learner_schema()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


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
    under its group (``refine.prefix``, ``stop.n_states``), the learner's own settings under
    ``learner`` (``reg_covar`` -> ``learner.reg_covar``); any other name is kept."""
    head, dot, rest = param.partition(".")
    groups = {kind.learner_arg: name for name, kind in KINDS.items() if kind.learner_arg}
    if head in groups:
        return groups[head] + dot + rest
    return f"learner.{param}" if param in fields_of(learner_schema()) else param


@contextmanager
def config_keys(group: str | None = None):
    """Name the parameter of a :class:`~topomap.core.checks.ParameterError` raised inside by its
    config key: ``<group>.<param>`` for a component of ``group``, else the key of a
    :class:`MapLearner` parameter (:func:`~topomap.app.compose.schemas.learner_key`); a parameter
    already named as a part's key (``sensor.max_range``, raised by a world while it walks) is
    kept."""
    try:
        yield
    except ParameterError as err:
        if err.param.partition(".")[0] in KINDS:
            raise
        key = f"{group}.{err.param}" if group else learner_key(err.param)
        raise err.renamed(key) from err.__cause__
