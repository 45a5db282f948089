"""Sensor noise models applied to noise-free observations.

Each model has ``apply(observations, rng) -> array``, which returns a new array of the same shape
and never modifies its input.  Observations are object sizes, hence non-negative; the models keep
them non-negative.
"""

from __future__ import annotations

import math

import numpy as np

from ..core.checks import ParameterError

__all__ = ["NoNoise", "GaussianNoise", "DropoutNoise", "MultiplicativeNoise"]


def _as_float(observations) -> np.ndarray:
    return np.array(observations, dtype=np.float64, copy=True)


def _check(name: str, value, low: float, high: float | None = None) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ParameterError(name, f"must be a number, got {value!r}")
    value = float(value)
    if not math.isfinite(value) or value < low or (high is not None and value >= high):
        bound = f">= {low}" if high is None else f"in [{low}, {high})"
        raise ParameterError(name, f"must be {bound}, got {value!r}")
    return value


class NoNoise:
    """Identity: returns a copy of the observations."""

    def apply(self, observations, rng: np.random.Generator) -> np.ndarray:
        """Return a float copy of ``observations``."""
        return _as_float(observations)

    def __repr__(self) -> str:
        return "NoNoise()"


class GaussianNoise:
    """Additive Gaussian noise ``N(0, sigma^2)`` on every entry, then clipped at 0.

    The clipping keeps sizes non-negative; it biases entries that are (close to) 0 upwards by about
    ``0.4 * sigma``, while entries much larger than ``sigma`` keep their mean.

    Parameters
    ----------
    sigma : float, default 0.01
        Standard deviation (radians of apparent size); must be >= 0.
    """

    def __init__(self, sigma: float = 0.01):
        self.sigma = _check("sigma", sigma, 0.0)

    def apply(self, observations, rng: np.random.Generator) -> np.ndarray:
        """Return ``max(observations + noise, 0)``."""
        X = _as_float(observations)
        if self.sigma == 0:
            return X
        return np.maximum(X + rng.normal(0.0, self.sigma, X.shape), 0.0)

    def __repr__(self) -> str:
        return f"GaussianNoise(sigma={self.sigma})"


class DropoutNoise:
    """Missed detections: each entry is set to 0 independently with probability ``p``.

    Parameters
    ----------
    p : float, default 0.1
        Drop probability, ``0 <= p < 1``.
    """

    def __init__(self, p: float = 0.1):
        self.p = _check("p", p, 0.0, 1.0)

    def apply(self, observations, rng: np.random.Generator) -> np.ndarray:
        """Return the observations with a random ``p`` fraction of entries zeroed."""
        X = _as_float(observations)
        if self.p > 0:
            X[rng.random(X.shape) < self.p] = 0.0
        return X

    def __repr__(self) -> str:
        return f"DropoutNoise(p={self.p})"


class MultiplicativeNoise:
    """Multiplicative lognormal gain: each entry is multiplied by ``exp(N(0, sigma^2))``.

    Zeros stay zero and signs are kept; the median gain is 1.

    Parameters
    ----------
    sigma : float, default 0.1
        Standard deviation of the log-gain; must be >= 0.
    """

    def __init__(self, sigma: float = 0.1):
        self.sigma = _check("sigma", sigma, 0.0)

    def apply(self, observations, rng: np.random.Generator) -> np.ndarray:
        """Return ``observations * exp(noise)``."""
        X = _as_float(observations)
        if self.sigma == 0:
            return X
        return X * np.exp(rng.normal(0.0, self.sigma, X.shape))

    def __repr__(self) -> str:
        return f"MultiplicativeNoise(sigma={self.sigma})"
