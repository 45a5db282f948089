"""Derived configs kept between commands, so that ``topomap --help`` needs no heavy import.

The typed config of a component is its factory's signature (:mod:`~topomap.app.compose.schemas`),
and reading a signature imports the factory's module -- for topomap's own components that means
scikit-learn and numba, seconds before the first line of ``--help`` or of a config error.  A
built-in component names its factory by import path (``"topomap.worlds.office:OfficeWorld"``),
and :func:`cached_schema` keeps the config derived from it in a small JSON file
(:func:`cache_file`), valid while no source file of the ``topomap`` package changed (their sizes
and times, with topomap's and Python's versions, make the file's key).  A run imports the factory
when it builds the component, as before; a config that cannot be written as JSON is simply not
kept.  Set ``TOPOMAP_CACHE_DIR`` to keep the file elsewhere (``""``: keep none).
"""

from __future__ import annotations

import copy
import dataclasses
import hashlib
import json
import os
import sys
import typing
from dataclasses import MISSING as _NO_DEFAULT
from dataclasses import field, make_dataclass
from pathlib import Path
from typing import Any, Optional

from ...core.data.atomic import atomic_write

__all__ = ["cached_schema", "cache_file", "source_stamp", "renamed_of", "CACHE_ENV"]

#: the folder of the cache file; "" keeps none (default: ``$XDG_CACHE_HOME/topomap`` or
#: ``~/.cache/topomap``)
CACHE_ENV = "TOPOMAP_CACHE_DIR"
_PRIMITIVES = {"int": int, "float": float, "bool": bool, "str": str}
_memo: dict[str, type] = {}
_stored: dict | None = None


def renamed_of(schema) -> dict:
    """The keys of a component's config before a rename and their keys now (``{"max_iter":
    "hard.max_iter"}``; "" for a key that no longer does anything): the factory's
    ``renamed_params``, which the config accepts until they go (the factory warns)."""
    return dict(getattr(schema, "__renamed__", None) or {})


def source_stamp(root=None) -> str:
    """The key of the cache: topomap's and Python's versions and every source file of the
    package below ``root`` (default: topomap's folder; path, size, modification time)."""
    from ... import __version__

    root = Path(__file__).resolve().parents[2] if root is None else Path(root)
    h = hashlib.sha256(f"{__version__} {sys.version}".encode())
    for folder, dirs, files in os.walk(root):
        dirs[:] = sorted(d for d in dirs if not d.startswith((".", "__pycache__")))
        for name in sorted(f for f in files if f.endswith(".py")):
            st = os.stat(os.path.join(folder, name))
            h.update(f"{folder}/{name} {st.st_size} {st.st_mtime_ns}\n".encode())
    return h.hexdigest()[:20]


def cache_file() -> Path | None:
    """The cache file of this installation (None: ``TOPOMAP_CACHE_DIR=""``)."""
    folder = os.environ.get(CACHE_ENV)
    if folder == "":
        return None
    if folder is None:
        base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
        folder = Path(base) / "topomap"
    return Path(folder) / f"schemas-{source_stamp()}.json"


def _read() -> dict:
    global _stored
    if _stored is None:
        path = cache_file()
        try:
            _stored = json.loads(path.read_text()) if path is not None else {}
        except (OSError, ValueError):
            _stored = {}
    return _stored


def _write(key: str, encoded: dict) -> None:
    stored = _read()
    stored[key] = encoded
    path = cache_file()
    if path is None:
        return
    try:
        atomic_write(path, lambda tmp: tmp.write_text(json.dumps(stored, sort_keys=True)))
    except OSError:  # a read-only home: derive again next time
        pass


def _encode_type(typ):
    if typ is Any:
        return "Any"
    for name, prim in _PRIMITIVES.items():
        if typ is prim:
            return name
    if dataclasses.is_dataclass(typ):
        return {"settings": typ.__name__, "fields": _encode_fields(typ)}
    origin, args = typing.get_origin(typ), typing.get_args(typ)
    if origin is list and len(args) == 1:
        return {"list": _encode_type(args[0])}
    if origin is typing.Union and len(args) == 2 and type(None) in args:
        return {"optional": _encode_type(next(a for a in args if a is not type(None)))}
    raise TypeError(f"no JSON form for the type {typ!r}")


def _decode_type(spec):
    if spec == "Any":
        return Any
    if isinstance(spec, str):
        return _PRIMITIVES[spec]
    if "settings" in spec:
        return make_dataclass(spec["settings"], _decode_fields(spec["fields"]))
    if "list" in spec:
        return list[_decode_type(spec["list"])]
    return Optional[_decode_type(spec["optional"])]


def _encode_fields(schema) -> list[dict]:
    out = []
    for f in dataclasses.fields(schema):
        entry = {"name": f.name, "type": _encode_type(f.type)}
        if f.default is not _NO_DEFAULT:
            entry["default"] = f.default
        elif f.default_factory is f.type:  # a nested settings config
            entry["nested"] = True
        elif f.default_factory is not _NO_DEFAULT:
            entry["factory"] = value = f.default_factory()
            if isinstance(value, tuple):  # JSON reads it back as a list
                entry["tuple"] = True
        json.dumps(entry)  # a TypeError when a default has no JSON form
        out.append(entry)
    return out


def _decode_fields(entries) -> list[tuple]:
    out = []
    for e in entries:
        typ = _decode_type(e["type"])
        if "default" in e:
            out.append((e["name"], typ, field(default=e["default"])))
        elif e.get("nested"):
            out.append((e["name"], typ, field(default_factory=typ)))
        elif "factory" in e:
            kind = tuple if e.get("tuple") else copy.deepcopy
            out.append((e["name"], typ, field(default_factory=lambda v=e["factory"], k=kind: k(v))))
        else:
            out.append((e["name"], typ))
    return out


def cached_schema(key: str, derive) -> type:
    """The config dataclass ``derive()`` gives for ``key`` (a factory's import path), from the
    cache file when it holds it, else derived and kept."""
    if key in _memo:
        return _memo[key]
    encoded = _read().get(key)
    if encoded is not None:
        try:
            schema = make_dataclass(encoded["class"], _decode_fields(encoded["fields"]))
            schema.__renamed__ = dict(encoded.get("renamed", {}))
        except (KeyError, TypeError, AttributeError):
            encoded = None
    if encoded is None:
        schema = derive()
        try:
            _write(key, {"class": schema.__name__, "fields": _encode_fields(schema),
                         "renamed": renamed_of(schema)})
        except TypeError:  # a type or default JSON cannot hold: derived every time
            pass
    _memo[key] = schema
    return schema
