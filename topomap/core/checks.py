"""Checks of parameter values, and the error that names the parameter.

The core speaks of its own parameters (``ns``, ``n_states``, ``clone_factor``, ...): a
:class:`ParameterError` carries the parameter's name and the problem separately, so a caller that
knows the parameter under another name (the ``topomap`` command calls ``FixedClusters(ns=...)``'s
``ns`` ``clusters.ns``) can say the same problem in its own words with :meth:`ParameterError.renamed`.
"""

from __future__ import annotations

import numbers

__all__ = ["ParameterError", "check_count", "checked_group"]


class ParameterError(ValueError):
    """A bad value of the parameter ``param``: ``str(err)`` is ``"<param> <problem>"``.

    ``problem`` starting with ``=`` (``"=30 is below ..."``) is joined without a space.
    """

    def __init__(self, param: str, problem: str):
        self.param = param
        self.problem = problem
        super().__init__(self._join(param, problem))

    @staticmethod
    def _join(name: str, problem: str) -> str:
        return f"{name}{'' if problem.startswith('=') else ' '}{problem}"

    def renamed(self, name: str) -> "ParameterError":
        """The same problem, the parameter called ``name`` (e.g. a config key)."""
        err = ParameterError(name, self.problem)
        err.__cause__ = self.__cause__
        return err


def _is_int(value) -> bool:
    return isinstance(value, numbers.Integral) and not isinstance(value, bool)


def check_count(value, param: str, *, minimum: int = 1, allow_none: bool = False):
    """``value`` as an ``int`` if it is an integer ``>= minimum`` (or None when ``allow_none``),
    else a :class:`ParameterError` naming ``param``."""
    if value is None and allow_none:
        return None
    if not _is_int(value) or value < minimum:
        what = {1: "a positive integer", 0: "a non-negative integer"}.get(
            minimum, f"an integer >= {minimum}")
        raise ParameterError(param, f"must be {what}{' or None' if allow_none else ''}, "
                                    f"got {value!r}")
    return int(value)


def checked_group(cls, value, key: str, checks: dict, convert=dict):
    """``value`` -- a ``cls`` (a frozen settings dataclass) or a mapping of some of its fields,
    made a ``cls`` through ``convert`` -- with each field passed to its check of ``checks``
    (``check(value, "<key>.<field>")``); a :class:`ParameterError` names ``<key>.<field>``, or
    ``key`` for a value of another kind."""
    from collections.abc import Mapping
    from dataclasses import fields

    names = [f.name for f in fields(cls)]
    if isinstance(value, Mapping):
        unknown = sorted(set(value) - set(names))
        if unknown:
            raise ParameterError(f"{key}.{unknown[0]}", f"is not a {key} setting; the "
                                                        f"settings are {', '.join(names)}")
        value = cls(**convert(value))
    if not isinstance(value, cls):
        raise ParameterError(key, f"must be {cls.__name__} or a mapping of its fields, got "
                                  f"{value!r}")
    for name, check in checks.items():
        check(getattr(value, name), f"{key}.{name}")
    return value
