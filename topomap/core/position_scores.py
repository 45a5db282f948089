"""The scores in metres' old place, kept until 0.4: they are :mod:`topomap.evaluation.metres`.

Importing a name from here still works, with a :class:`FutureWarning` naming the new place.
"""

import importlib
import warnings

#: the module the scores in metres moved to
MOVED_TO = "topomap.evaluation.metres"


def __getattr__(name):
    if name.startswith("__"):
        raise AttributeError(name)
    warnings.warn(f"topomap.core.position_scores is now {MOVED_TO}; the old name goes in 0.4",
                  FutureWarning, stacklevel=2)
    return getattr(importlib.import_module(MOVED_TO), name)
