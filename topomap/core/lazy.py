"""Public names of a package imported on first use (PEP 562), so that importing the package
loads nothing heavy."""

from __future__ import annotations

import importlib

__all__ = ["lazy_getattr"]


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
