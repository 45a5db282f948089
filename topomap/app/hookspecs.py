"""The old place of the plugin hooks, kept for one release: plugins import
``from topomap import Component, hookimpl`` (the hooks are in
:mod:`topomap.app.compose.hookspecs`).  A name taken from here warns once."""

import warnings

from .compose import hookspecs as _hookspecs


def __getattr__(name):
    if name in _hookspecs.__all__:
        warnings.warn(f"topomap.app.hookspecs.{name} is deprecated and goes in the next release: "
                      f"from topomap import Component, hookimpl", FutureWarning, stacklevel=2)
        return getattr(_hookspecs, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
