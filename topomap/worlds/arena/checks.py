"""Argument checks the arena's components share: errors that name the parameter."""

from __future__ import annotations

import math

from ...core.checks import ParameterError

__all__ = ["positive", "non_negative"]


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
