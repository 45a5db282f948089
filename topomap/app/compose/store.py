"""Every config into Hydra's ConfigStore, with the values of the YAML files plugins ship.

:func:`store_configs` puts the top-level schema (``topomap_schema``) and every component's
config (``<kind>/<name>``, :func:`~topomap.app.compose.schemas.schema_of`) into Hydra's
ConfigStore; a plugin's ``<kind>/<name>.yaml`` sets values on top of its component's typed
config, and any other ``<group>/<option>.yaml`` it ships (a preset, say) is an option of its
group as written (:func:`read_yaml_options`).  ``conf/config.yaml`` composes them.
"""

from __future__ import annotations

import re
from importlib import resources
from pathlib import Path

from omegaconf import OmegaConf

from .optuna import store_optuna_sweeper
from .schema_cache import renamed_of
from .schemas import config_schema, schema_of

__all__ = ["store_configs", "read_yaml_options"]

#: the header line of a YAML file that places its values (``# @package _global_``)
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


def _share_config_store(store_class) -> None:
    """Let Hydra's ConfigStore be shared rather than copied.  Hydra deep-copies the whole store
    every time it reads a config group's options (about 120 times for ``topomap --help``, several
    times per job of a sweep: seconds once every component's typed config is in it), though the
    store is one per process and hands out configs only through ``ConfigStore.load``, which
    copies the config it returns: a copy of the store itself protects nothing."""
    if "__deepcopy__" not in vars(store_class):
        store_class.__deepcopy__ = lambda self, memo: self


def _open_renamed(node, renamed: dict):
    """A component's config ``node`` open to the keys of before a rename (``renamed``, e.g.
    ``max_iter`` and ``soft.observed``): the config nodes that held them take keys they do not
    declare, which the factory then moves to their new places with a warning.  Other unknown
    keys are still refused, before Hydra composes
    (:func:`~topomap.app.compose.config_checks.check_overrides`) and after
    (:func:`~topomap.app.compose.config_checks.check_config`)."""
    node = OmegaConf.structured(node)
    for old in renamed:
        parent = old.rpartition(".")[0]
        OmegaConf.set_struct(OmegaConf.select(node, parent) if parent else node, False)
    return node


def store_configs(registry) -> None:
    """Put the top-level schema and every component's config into Hydra's ConfigStore."""
    from hydra.core.config_store import ConfigStore

    _share_config_store(ConfigStore)
    cs = ConfigStore.instance()
    cs.store(name="topomap_schema", node=config_schema())
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
        if renamed_of(schema_of(comp)):
            node = _open_renamed(node, renamed_of(schema_of(comp)))
        cs.store(group=kind, name=name, node=node, provider=provider)
    for (group, option), (text, package, provider) in files.items():
        cs.store(group=group, name=option, node=OmegaConf.create(text), package=package,
                 provider=provider)
    store_optuna_sweeper(cs)
