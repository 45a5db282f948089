"""Public names of a package imported on first use (PEP 562), so that importing the package
loads nothing heavy."""

from __future__ import annotations

import importlib

__all__ = ["lazy_getattr", "lazy_dir"]


def lazy_getattr(package: str, public: dict[str, str]):
    """The module ``__getattr__`` of ``package``: a name of ``public`` (name -> module, absolute
    or relative to ``package``) is imported from its module when first asked for, then kept in
    the package's namespace."""
    namespace = vars(importlib.import_module(package))

    def __getattr__(name):
        if name in public:
            value = getattr(importlib.import_module(public[name], package), name)
            namespace[name] = value
            return value
        raise AttributeError(f"module {package!r} has no attribute {name!r}")

    return __getattr__


def lazy_dir(package: str, public):
    """The module ``__dir__`` of ``package``: its own names and the names ``public`` (its
    ``__all__``), imported or not yet, so that ``dir()`` and an editor's completion list what the
    package offers."""
    namespace, public = vars(importlib.import_module(package)), frozenset(public)

    def __dir__():
        return sorted(set(namespace) | public)

    return __dir__
