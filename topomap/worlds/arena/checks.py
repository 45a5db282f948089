"""Argument checks the arena's components share: errors that name the parameter, and the optional
ratinabox package asked for in one line."""

from __future__ import annotations

import math

from ...core.checks import ParameterError

__all__ = ["positive", "non_negative", "require_ratinabox"]


def require_ratinabox() -> None:
    """A :class:`~topomap.worlds.minigrid.MissingDependencyError` saying, in one line, how to
    install ratinabox, when it is missing (the arena's modules import it only when they use it,
    so the arena's components and their configs are known without it)."""
    from ..minigrid import MissingDependencyError

    try:
        import ratinabox  # noqa: F401
    except ImportError as exc:
        raise MissingDependencyError(
            f"the arena world needs the optional ratinabox package ({exc}); "
            'install it with: pip install "topomap[arena]"') from None


def _finite_number(value) -> bool:
    return (isinstance(value, (int, float)) and not isinstance(value, bool)
            and math.isfinite(value))


def positive(name: str, value) -> float:
    """``value`` as a float if it is a finite number > 0, else a ParameterError naming ``name``."""
    if not _finite_number(value) or value <= 0:
        raise ParameterError(name, f"must be a positive number, got {value!r}")
    return float(value)


def non_negative(name: str, value) -> float:
    """``value`` as a float if it is a finite number >= 0, else a ParameterError naming ``name``."""
    if not _finite_number(value) or value < 0:
        raise ParameterError(name, f"must be a non-negative number, got {value!r}")
    return float(value)
