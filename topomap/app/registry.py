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

import importlib
import importlib.util
import os
import sys
from dataclasses import dataclass
from importlib.metadata import entry_points
from pathlib import Path
from typing import Any

import pluggy

from . import builtins, hookspecs
from .hookspecs import KINDS, Component

__all__ = ["Registry", "Parts", "PluginError", "ENTRY_POINT_GROUP", "AUTOLOAD_ENV"]

ENTRY_POINT_GROUP = "topomap"
BUILTINS = "topomap.builtins"
#: set (to anything but "" or "0") to skip plugins installed under :data:`ENTRY_POINT_GROUP`
AUTOLOAD_ENV = "TOPOMAP_DISABLE_PLUGIN_AUTOLOAD"


def autoload_disabled() -> bool:
    return os.environ.get(AUTOLOAD_ENV, "") not in ("", "0")


@dataclass
class Parts:
    """The components of one run, each built once from its config.

    ``world`` is None when the data component does not simulate (``data=file``).
    """

    world: Any
    noise: Any
    explorer: Any
    metric: Any
    clusters: Any
    split: Any
    stop: Any
    refine: Any
    data: Any
    evaluate: Any


@dataclass(frozen=True)
class PluginError:
    """A plugin that could not be loaded."""

    name: str
    module: str
    error: str

    def __str__(self) -> str:
        return f"plugin {self.name!r} (module {self.module}) failed to load: {self.error}"


def _import(ref: str):
    """Import ``"pkg.mod"``, ``"pkg.mod:attr"`` or ``"path/to/file.py[:attr]"``."""
    mod_ref, _, attr = ref.partition(":")
    if mod_ref.endswith(".py"):
        path = Path(mod_ref).resolve()
        if not path.is_file():
            raise ImportError(f"no such file {path}")
        name = f"topomap_plugin_{path.stem}"
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
        for impl in pm.hook.topomap_register_components.get_hookimpls():  # registration order
            provider = pm.get_name(impl.plugin) or repr(impl.plugin)
            try:
                returned = impl.function() or []
            except Exception as exc:  # a plugin's hook failing must not hide the others
                self.errors.append(PluginError(provider, _module_of(impl.plugin), repr(exc)))
                continue
            for comp in returned:
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
        try:
            return comp.factory(**params)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"{kind}={name}: {exc}") from None

    def config_paths(self) -> list[tuple[str, str]]:
        """``(folder, provider)`` of every plugin that ships config-group YAML files."""
        paths = []
        for impl in self.pm.hook.topomap_config_path.get_hookimpls():
            try:
                path = impl.function()
            except Exception as exc:
                provider = self.pm.get_name(impl.plugin)
                self.errors.append(PluginError(provider, _module_of(impl.plugin), repr(exc)))
                continue
            if path and str(path) not in [p for p, _ in paths]:
                paths.append((str(path), self.pm.get_name(impl.plugin)))
        return paths

    def plugin_names(self) -> list[str]:
        """Names of every loaded plugin but the built-ins (they can change what a world does)."""
        return sorted(name for name, _ in self.pm.list_name_plugin() if name != BUILTINS)

    # ------------------------------------------------------------------ building a run
    def world_actions(self, env: dict) -> list:
        """The actions plugins add to the world ``env["component"]``, in plugin order."""
        return [a for _, actions in self.world_action_providers(env) for a in actions]

    def world_action_providers(self, env: dict) -> list[tuple[str, list]]:
        """``(provider, actions)`` of every plugin adding actions to the world ``env["component"]``
        (the order in which they are appended to the world's own)."""
        out = []
        for impl in reversed(self.pm.hook.topomap_world_actions.get_hookimpls()):  # call order
            actions = impl.function(world=env["component"], params=dict(env))
            if actions:
                out.append((self.pm.get_name(impl.plugin), list(actions)))
        return out

    def build(self, cfg) -> Parts:
        """Every component of the run ``cfg`` (a mapping), each built once.

        The world, its noise and explorer are built only when the data component simulates.
        """
        data = self.make("data", cfg["data"])
        world = noise = explorer = None
        if getattr(data, "simulates", False):
            extra = self.world_actions(cfg["env"])
            world = self.make("env", cfg["env"], **({"extra_actions": extra} if extra else {}))
            noise = self.make("noise", cfg["noise"])
            explorer = self.make("explorer", cfg["explorer"])
        return Parts(world=world, noise=noise, explorer=explorer,
                     **{k: self.make(k, cfg[k])
                        for k in ("metric", "clusters", "split", "stop", "refine", "evaluate")},
                     data=data)

    def learner_events(self, metrics: dict):
        """A learner callback that passes every event to the plugins' ``topomap_learner_event``;
        plugins may add entries to ``metrics``."""
        def on_event(event, info):
            self.pm.hook.topomap_learner_event(event=event, info=dict(info, metrics=metrics))
        return on_event


def _module_of(plugin) -> str:
    return getattr(plugin, "__name__", None) or type(plugin).__module__
