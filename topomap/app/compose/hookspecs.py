"""Hook specifications: what a topomap plugin can implement.

A plugin is any module or object with functions decorated by :data:`hookimpl` whose names match
the specifications below.  It is found through the setuptools entry-point group ``topomap``
(``[project.entry-points.topomap] my_plugin = "my_package.plugin"``; set
``TOPOMAP_DISABLE_PLUGIN_AUTOLOAD=1`` to skip them) or listed in the Hydra config
(``plugins: [my_module]``).  topomap's own components are registered by the very same hooks
(:mod:`topomap.app.compose.builtins`).  See ``docs/plugins.md`` for a walk-through.

Component kinds
---------------
A component has one of the kinds declared in :mod:`topomap.app.compose.kinds`
(:data:`~topomap.app.compose.kinds.KINDS`, with what the factory of each kind returns); the kind is also
the config group that selects the component (``topomap split=<name>``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable

import pluggy

from .kinds import KINDS

__all__ = ["hookspec", "hookimpl", "Component", "KINDS", "TopomapSpecs"]

hookspec = pluggy.HookspecMarker("topomap")
hookimpl = pluggy.HookimplMarker("topomap")


@dataclass(frozen=True)
class Component:
    """One selectable component.

    Attributes
    ----------
    kind : str
        One of :data:`KINDS`; also the Hydra config group that selects it.
    name : str
        The name users write: ``topomap split=<name>``.
    factory : callable or str
        Called with the config's fields (all but ``component``) as keyword arguments; returns the
        object.  Its signature *is* the typed config: every parameter becomes a field of
        ``<kind>.<param>`` with the parameter's annotation and default (no default: required);
        a parameter named ``seed`` follows the run's ``seed`` unless set.  Or its import path,
        ``"package.module:attribute"``: imported when a run builds the component
        (:meth:`load_factory`), so that listing or checking configs does not import it.
    config : dataclass type, optional
        Typed parameters written by hand instead: a dataclass with a ``component: str = "<name>"``
        field and one field per factory argument.  Usually left out (derived from the factory).
    description : str
        One line shown by ``topomap --list-plugins``.
    """

    kind: str
    name: str
    factory: Callable[..., Any]
    config: type | None = None
    description: str = ""

    def __post_init__(self):
        if self.kind not in KINDS:
            raise ValueError(f"component {self.name!r}: kind {self.kind!r} is not one of {', '.join(KINDS)}")
        if not isinstance(self.name, str) or not self.name.isidentifier():
            raise ValueError(f"component name {self.name!r} must be a Python-identifier-like string")
        if isinstance(self.factory, str) and not _import_path(self.factory):
            raise ValueError(f"component {self.name!r}: factory {self.factory!r} is not an "
                             "import path 'package.module:attribute'")

    def load_factory(self) -> Callable[..., Any]:
        """The factory, imported first when it is given by its import path."""
        if not isinstance(self.factory, str):
            return self.factory
        import importlib

        module, _, attr = self.factory.partition(":")
        return getattr(importlib.import_module(module), attr)


def _import_path(text: str) -> bool:
    """Whether ``text`` reads ``package.module:attribute``."""
    module, colon, attr = text.partition(":")
    return bool(colon) and attr.isidentifier() and all(p.isidentifier() for p in module.split("."))


class TopomapSpecs:
    """The hooks topomap calls."""

    @hookspec
    def topomap_register_components(self) -> list[Component]:
        """Return the components this plugin provides (a list of :class:`Component`).

        Called once, when the registry is built at start-up.  Results of all plugins are
        collected; two plugins providing the same ``(kind, name)`` is an error naming both.
        """

    @hookspec
    def topomap_config_path(self) -> str:
        """Return the folder of this plugin's config-group YAML files.

        ``"pkg://my_plugin.conf"`` (a package) or ``"file:///abs/path/conf"``.  Called once at
        start-up.  Every ``<group>/<option>.yaml`` in it becomes a selectable option: a file named
        after one of the plugin's components sets values on top of the component's typed config
        (so types are still checked); any other file, such as an ``experiment/<name>.yaml`` preset
        with a ``# @package _global_`` header, is an option of its group as written.
        """

    @hookspec
    def topomap_world_actions(self, world: str, params: dict) -> list:
        """Return extra actions for the world named ``world`` (``[]`` or ``None`` for none).

        :param world: the environment component's name, e.g. ``"office"``.
        :param params: the world's configured parameters (read-only).

        Called before the world is built; the actions of all plugins are appended after the world's
        own, in plugin order, and passed to the environment factory as ``extra_actions``.  For the
        office world an action is an object with ``name``, ``is_executable(world, pose)`` and
        ``execute(world, pose, rng) -> pose`` (see :class:`topomap.worlds.office.Action`).
        """

    @hookspec
    def topomap_learner_event(self, event: str, info: dict) -> None:
        """Observe the learner's progress.

        :param event: ``"phase1"`` after clustering, ``"split"`` after each split, ``"refine"``
            after a refinement, ``"done"`` at the end.
        :param info: ``learner`` (the :class:`topomap.MapLearner`), ``labels`` (state of every
            step; for ``"split"`` the learner's working array, changed in place by later splits,
            so copy it to keep it), ``entropies`` (dict with ``H_o``, ``H_u``, ``H_x``, ``n_states``), ``record``
            (for ``"split"``: iteration, state, new_state, gain, sizes) and ``metrics`` (a dict a
            plugin may add JSON-serialisable entries to; they are written to ``metrics.json`` under
            ``plugin_metrics``).
        """
