"""Find plugins, collect their components, and build a run's components from its config.

``Registry.load()`` makes a pluggy plugin manager, registers topomap's built-in components, every
plugin installed under the entry-point group ``topomap`` (unless the environment variable
``TOPOMAP_DISABLE_PLUGIN_AUTOLOAD`` is set, as pytest's ``PYTEST_DISABLE_PLUGIN_AUTOLOAD``) and
every module named in ``modules`` (a dotted module path, optionally ``module:attribute``, or a
``.py`` file path), then collects the components their ``topomap_register_components`` hooks
return.  A plugin that fails to import is reported with its name and module (``Registry.errors``)
and the others still load.  ``Registry.build(cfg)`` builds every component of a run once.
"""

from __future__ import annotations

import hashlib
import importlib
import importlib.util
import inspect
import os
import sys
from dataclasses import dataclass
from importlib.metadata import entry_points
from pathlib import Path

import pluggy

from . import builtins, hookspecs
from ...core.checks import ParameterError
from .hookspecs import Component
from .kinds import KINDS, parts_of

__all__ = ["Registry", "Parts", "PluginError", "ENTRY_POINT_GROUP", "AUTOLOAD_ENV"]

ENTRY_POINT_GROUP = "topomap"
BUILTINS = "topomap.builtins"
#: set (to anything but "" or "0") to skip plugins installed under :data:`ENTRY_POINT_GROUP`
AUTOLOAD_ENV = "TOPOMAP_DISABLE_PLUGIN_AUTOLOAD"


def autoload_disabled() -> bool:
    return os.environ.get(AUTOLOAD_ENV, "") not in ("", "0")


class Parts:
    """The components of one run, each built once from its config: one attribute per kind of
    component (:data:`~topomap.app.compose.kinds.KINDS`), named as its config group.

    The parts of the world (``env``, ``noise``, ``explorer``) are None when the data component
    does not simulate (``data=file``).
    """

    def __init__(self, **built):
        unknown = set(built) - set(KINDS)
        if unknown:
            raise TypeError(f"Parts has no kind {', '.join(sorted(unknown))}")
        for kind in KINDS:
            setattr(self, kind, built.get(kind))

    def __repr__(self) -> str:
        return f"Parts({', '.join(f'{k}={getattr(self, k)!r}' for k in KINDS)})"


@dataclass(frozen=True)
class PluginError:
    """A plugin that could not be loaded."""

    name: str
    module: str
    error: str

    def __str__(self) -> str:
        return f"plugin {self.name!r} (module {self.module}) failed to load: {self.error}"


def plugin_module_name(path: Path) -> str:
    """The module name a plugin file is loaded under: ``topomap_plugin_<stem>_<hash of its
    folder>``, one per file, so that two files of one name in two folders are two modules."""
    digest = hashlib.sha1(str(path.resolve().parent).encode()).hexdigest()[:8]
    return f"topomap_plugin_{path.stem}_{digest}"


def _import(ref: str):
    """Import ``"pkg.mod"``, ``"pkg.mod:attr"`` or ``"path/to/file.py[:attr]"``."""
    mod_ref, _, attr = ref.partition(":")
    if mod_ref.endswith(".py"):
        path = Path(mod_ref).resolve()
        if not path.is_file():
            raise ImportError(f"no such file {path}")
        name = plugin_module_name(path)
        spec = importlib.util.spec_from_file_location(name, path)
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        spec.loader.exec_module(module)
    else:
        module = importlib.import_module(mod_ref)
    obj = getattr(module, attr) if attr else module
    return obj() if isinstance(obj, type) else obj


class Registry:
    """Components by kind and name, with the plugin that provides each."""

    def __init__(self, pm: pluggy.PluginManager, errors=()):
        self.pm = pm
        self.errors: list[PluginError] = list(errors)
        self._components: dict[str, dict[str, tuple[Component, str]]] = {k: {} for k in KINDS}
        for provider, plugin, returned in self._call_each("topomap_register_components"):
            if isinstance(returned, Exception):  # a plugin's hook failing must not hide the others
                self.errors.append(PluginError(provider, _module_of(plugin), repr(returned)))
                continue
            for comp in returned or []:
                self._add(comp, provider)

    def _add(self, comp: Component, provider: str) -> None:
        if not isinstance(comp, Component):
            raise ValueError(
                f"plugin {provider!r} returned {comp!r} from topomap_register_components; "
                "expected topomap.hookspecs.Component objects"
            )
        known = self._components[comp.kind]
        if comp.name in known:
            other = known[comp.name][1]
            raise ValueError(
                f"{comp.kind} component {comp.name!r} is registered by two plugins: "
                f"{other!r} and {provider!r}; uninstall or rename one of them"
            )
        known[comp.name] = (comp, provider)

    def _call_each(self, hook: str, **kwargs):
        """Call the hook ``hook`` of one plugin at a time (through pluggy, which passes each the
        arguments it takes) and yield ``(provider, plugin, result)`` in registration order;
        ``result`` is the exception the plugin raised, if it raised.  (``pm.hook.<hook>(...)``
        calls them all at once: its results do not say which plugin gave them, and the first
        plugin that raises stops it.)"""
        plugins = [impl.plugin for impl in getattr(self.pm.hook, hook).get_hookimpls()]
        for plugin in plugins:
            alone = self.pm.subset_hook_caller(hook, [p for p in plugins if p is not plugin])
            try:
                results = alone(**kwargs)
            except Exception as exc:
                results = [exc]
            yield (self.pm.get_name(plugin) or repr(plugin), plugin,
                   results[0] if results else None)

    # ------------------------------------------------------------------ loading
    @classmethod
    def load(cls, modules=(), *, entry_points_group: str | None = ENTRY_POINT_GROUP) -> "Registry":
        """Build the registry from built-ins, installed entry points and ``modules``.

        ``entry_points_group=None`` (or the environment variable :data:`AUTOLOAD_ENV`) skips the
        installed plugins.
        """
        if autoload_disabled():
            entry_points_group = None
        pm = pluggy.PluginManager("topomap")
        pm.add_hookspecs(hookspecs.TopomapSpecs)
        pm.register(builtins, name=BUILTINS)
        errors: list[PluginError] = []
        if entry_points_group:
            for ep in sorted(entry_points(group=entry_points_group), key=lambda e: e.name):
                if pm.has_plugin(ep.name) or pm.get_plugin(ep.name) is not None:
                    continue
                try:
                    obj = ep.load()
                    pm.register(obj() if isinstance(obj, type) else obj, name=ep.name)
                except Exception as exc:
                    errors.append(PluginError(ep.name, ep.value, f"{type(exc).__name__}: {exc}"))
        for ref in modules:
            ref = str(ref)
            if pm.get_plugin(ref) is not None:
                continue
            try:
                pm.register(_import(ref), name=ref)
            except Exception as exc:
                errors.append(PluginError(ref, ref.partition(":")[0], f"{type(exc).__name__}: {exc}"))
        try:
            pm.check_pending()
        except pluggy.PluginValidationError as exc:
            raise ValueError(f"plugin {exc.plugin!r}: {exc}") from None
        return cls(pm, errors)

    # ------------------------------------------------------------------ lookup
    def names(self, kind: str) -> list[str]:
        return sorted(self._components[kind])

    def items(self):
        """Yield ``(kind, name, component, provider)`` for every component."""
        for kind in KINDS:
            for name in self.names(kind):
                comp, provider = self._components[kind][name]
                yield kind, name, comp, provider

    def get(self, kind: str, name: str) -> Component:
        if kind not in self._components:
            raise ValueError(f"unknown component kind {kind!r}; kinds are {', '.join(KINDS)}")
        try:
            return self._components[kind][name][0]
        except KeyError:
            msg = (f"{kind}={name!r} is not a registered {kind} component; "
                   f"available: {', '.join(self.names(kind)) or 'none'}")
            if self.errors:
                msg += "; note that " + "; ".join(str(e) for e in self.errors)
            raise ValueError(msg) from None

    def provider(self, kind: str, name: str) -> str:
        self.get(kind, name)
        return self._components[kind][name][1]

    def make(self, kind: str, params, **extra):
        """Build a component from its config (a mapping with ``component`` and the parameters)."""
        params = dict(params)
        name = params.pop("component", None)
        if name is None:
            raise ValueError(f"{kind} config has no 'component' field naming the component")
        comp = self.get(kind, name)
        params.update(extra)
        from .schemas import moved_keys, schema_of  # keys of before a rename: their keys now

        params = moved_keys(kind, schema_of(comp), params)
        try:
            return comp.load_factory()(**params)
        except ParameterError as err:  # named by the factory's parameter: say the config key
            raise ValueError(f"{kind}={name}: {err.renamed(f'{kind}.{err.param}')}") from None
        except (TypeError, ValueError) as exc:
            raise ValueError(f"{kind}={name}: {exc}") from None

    def config_paths(self) -> list[tuple[str, str]]:
        """``(folder, provider)`` of every plugin that ships config-group YAML files."""
        paths = []
        for provider, plugin, path in self._call_each("topomap_config_path"):
            if isinstance(path, Exception):
                self.errors.append(PluginError(provider, _module_of(plugin), repr(path)))
            elif path and str(path) not in [p for p, _ in paths]:
                paths.append((str(path), provider))
        return paths

    def plugin_names(self) -> list[str]:
        """Names of every loaded plugin but the built-ins (they can change what a world does)."""
        return sorted(name for name, _ in self.pm.list_name_plugin() if name != BUILTINS)

    # ------------------------------------------------------------------ building a run
    def world_actions(self, env: dict) -> list:
        """The actions plugins add to the world ``env["component"]``, in the order pluggy calls
        them (they are appended to the world's own)."""
        added = self.pm.hook.topomap_world_actions(world=env["component"], params=dict(env))
        return [action for actions in added for action in actions or ()]

    def world_action_providers(self, env: dict) -> list[tuple[str, list]]:
        """``(provider, actions)`` of every plugin adding actions to the world ``env["component"]``,
        in the order of :meth:`world_actions`."""
        out = []
        called = self._call_each("topomap_world_actions", world=env["component"], params=dict(env))
        for provider, _, actions in reversed(list(called)):  # pluggy calls the last registered first
            if isinstance(actions, Exception):
                raise actions
            if actions:
                out.append((provider, list(actions)))
        return out

    def build(self, cfg) -> Parts:
        """Every component of the run ``cfg`` (a mapping), each built once, in the order of
        :data:`~topomap.app.compose.kinds.KINDS` -- the data component first: the parts of the world are
        built only when it simulates."""
        data = self.make("data", cfg["data"])
        simulates = bool(getattr(data, "simulates", False))
        built = {"data": data}
        for kind in KINDS.values():
            if kind.name in built or (kind.simulated and not simulates):
                continue
            if kind.part_of is not None:  # None: not chosen, the whole's own default applies
                chosen = cfg.get(kind.name)
                built[kind.name] = None if chosen is None else self.make(kind.name, chosen)
                continue
            extra = self.world_actions(cfg["env"]) if kind.name == "env" else None
            extra = {"extra_actions": extra} if extra else {}
            built[kind.name] = self.make(kind.name, cfg[kind.name],
                                         **extra, **self._parts(kind.name, cfg, built))
        return Parts(**built)

    def takes(self, kind: str, name: str, argument: str) -> bool:
        """Whether the factory of the component ``<kind>=<name>`` takes ``argument``."""
        return argument in inspect.signature(self.get(kind, name).load_factory()).parameters

    def _parts(self, kind: str, cfg, built: dict) -> dict:
        """The chosen parts of the run's ``kind`` component (a world's sensor and actions), by the
        arguments its factory takes; a part it does not take is refused, naming those that do."""
        name = cfg[kind]["component"]
        out = {}
        for part in parts_of(kind):
            if built.get(part) is None:
                continue
            if not self.takes(kind, name, part):
                others = [f"{kind}={n}" for n in self.names(kind) if self.takes(kind, n, part)]
                hint = f"; {', '.join(others)} does" if others else ""
                raise ValueError(f"{part}={cfg[part]['component']}: {kind}={name} takes no "
                                 f"{part}{hint}")
            out[part] = built[part]
        return out

    def learner_events(self, metrics: dict):
        """A learner callback that passes every event to the plugins' ``topomap_learner_event``;
        plugins may add entries to ``metrics``."""
        def on_event(event, info):
            self.pm.hook.topomap_learner_event(event=event, info=dict(info, metrics=metrics))
        return on_event


def _module_of(plugin) -> str:
    return getattr(plugin, "__name__", None) or type(plugin).__module__
