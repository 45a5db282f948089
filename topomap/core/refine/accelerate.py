"""Accelerated Baum-Welch: SQUAREM (Varadhan & Roland, 2008, "Simple and globally convergent
methods for accelerating the convergence of any EM algorithm") on the expected counts.

Baum-Welch is a fixed-point map ``F``: counts -> M-step -> E-step -> counts, and an E-step on
the model of ``c`` gives ``F(c)`` and that model's log-likelihood ``L(c)`` together.  Its slow
tail (mass moving between the duplicate clones of one place) converges linearly.  A cycle starts
from ``c`` with ``c1 = F(c)`` and ``L(c)`` in hand; one E-step gives ``c2 = F(c1)`` and ``L(c1)``,
and with ``r = c1 - c`` and ``v = c2 - 2 c1 + c`` the cycle jumps along the path they trace::

    a = -|r| / |v|   (clamped to -step_max .. -1; -1 gives c2, plain EM, and no jump)
    c' = max(c - 2 a r + a^2 v, 0)

An E-step on ``c'`` gives ``F(c')`` and ``L(c')``.  The jump is kept if ``L(c') >= L(c1)``, the
last point of the plain path: the next cycle starts from ``c'`` with ``F(c')`` in hand (that
E-step is SQUAREM's stabilising EM step and the next cycle's first at once, so a cycle costs two
E-steps, not three).  Otherwise the cycle falls back to plain EM -- the next starts from ``c1``
with ``c2`` in hand -- and ``step_max`` shrinks.  Counts are the M-step's input, so clipping at
0 keeps every row a distribution (the pseudocount keeps it positive).

Cost is counted in E-steps, as for :func:`~topomap.core.refine.clones.baum_welch`, and the
convergence test keeps its meaning: it is judged on every cycle's plain EM step ``c -> c1``,
which must gain ``tol`` (nats over the sequence).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ..checks import ParameterError
from ..progress import report

__all__ = ["ACCELERATIONS", "check_accelerate", "Squarem", "squarem"]

#: the accelerations of Baum-Welch: ``none`` (plain EM) and ``squarem``
ACCELERATIONS = ("none", "squarem")

#: SQUAREM's first ``step_max``, and the factor it grows by when a step reaches it (shrinks by
#: when a step is refused); the defaults of the authors' SQUAREM package, whose first cycle's
#: step_max of 1 grows to 4 at once
STEP_MAX0 = 4.0
MSTEP = 4.0


def check_accelerate(value) -> str:
    """``value`` if it names an acceleration, else a ``ParameterError`` naming ``accelerate``."""
    if value not in ACCELERATIONS:
        raise ParameterError("accelerate", f"must be one of {', '.join(ACCELERATIONS)}, "
                             f"got {value!r}")
    return value


class Squarem:
    """The state of SQUAREM's cycles: the largest step length, and what they did.

    Attributes
    ----------
    step_max : float -- the longest jump a cycle may take
    jumps, refused : int -- cycles whose jump was kept / refused (fell back to plain EM)
    """

    def __init__(self, step_max: float = STEP_MAX0, mstep: float = MSTEP):
        self.step_max, self.mstep = step_max, mstep
        self.jumps = self.refused = 0

    def step_length(self, rr: float, vv: float) -> float:
        """SQUAREM's ``a = -|r|/|v|`` from ``rr = |r|^2`` and ``vv = |v|^2``, clamped to
        ``-step_max .. -1``."""
        a = -np.sqrt(rr / vv) if vv > 0 else -1.0
        return min(-1.0, max(-self.step_max, float(a)))

    def jump(self, c0, c1, c2):
        """The extrapolated counts of one cycle from ``c0``, ``c1 = F(c0)``, ``c2 = F(c1)``,
        and the step length (None: -1, the plain EM step ``c2``)."""
        a = self.step_length(*_norms(c0, c1, c2))
        if a == -1.0:
            return c2, None
        return _extrapolate(c0, c1, c2, a), a

    def judge(self, a: float, kept: bool) -> None:
        """Adapt ``step_max`` after a jump of length ``a``: grow it when a kept jump reached it,
        shrink it (not below ``STEP_MAX0``) when the jump was refused."""
        if kept:
            self.jumps += 1
            if a <= -self.step_max:
                self.step_max *= self.mstep
        else:
            self.refused += 1
            self.step_max = max(STEP_MAX0, self.step_max / self.mstep)


@njit(cache=True)
def _norms(c0, c1, c2):
    """``|r|^2`` and ``|v|^2`` of a cycle, in one pass and without BLAS (whose idle threads
    would spin beside the next E-step)."""
    rr = vv = 0.0
    for i in range(c0.size):
        r = c1[i] - c0[i]
        v = c2[i] - 2.0 * c1[i] + c0[i]
        rr += r * r
        vv += v * v
    return rr, vv


@njit(cache=True)
def _extrapolate(c0, c1, c2, a):
    """``max(c0 - 2 a r + a^2 v, 0)``, in one pass."""
    out = np.empty_like(c0)
    for i in range(c0.size):
        r = c1[i] - c0[i]
        v = c2[i] - 2.0 * c1[i] + c0[i]
        x = c0[i] - 2.0 * a * r + a * a * v
        out[i] = x if x > 0.0 else 0.0
    return out


def squarem(em_step, counts, *, max_iter: int, tol: float, min_iter: int = 10, stop=None,
            rtol: float = 0.0):
    """SQUAREM cycles from ``counts`` (the module's text) until a cycle's plain EM step gains
    less than ``tol`` (with ``rtol`` > 0 instead: at most ``rtol`` x |the log-likelihood it
    started from|; checked once more than ``min_iter`` E-steps ran), ``max_iter`` E-steps, or
    ``stop()`` (judged as there) holds.

    ``em_step(c)`` is one E-step on the model of ``c``: it returns ``(F(c), occupancy, ll)``,
    ``ll`` the log-likelihood of that model.  Returns ``(counts, occupancy, history, state)``:
    ``F`` of the point the cycles ended on (whose M-step is the fitted model), its occupancy,
    the log-likelihood of every E-step and the :class:`Squarem` state.
    """
    history, state = [], Squarem()

    def step(c):
        new, occ, ll = em_step(c)
        history.append(ll)
        report("EM", len(history), max_iter)
        return new, occ, ll

    def done(gain=np.inf, base=0.0):
        n = len(history)
        stalled = gain <= rtol * abs(base) if rtol else gain < tol
        return n >= max_iter or n > min_iter and (stalled or stop is not None and stop())

    x0 = counts
    x1, occ1, l0 = step(x0)
    while not done():
        x2, occ2, l1 = step(x1)
        if done(l1 - l0, l0):
            return x2, occ2, history, state
        c, a = state.jump(x0, x1, x2)
        if a is None:  # the plain EM step
            x0, x1, l0, occ1 = x1, x2, l1, occ2
            continue
        x3, occ3, lc = step(c)
        kept = lc >= l1
        state.judge(a, kept)
        x0, x1, l0, occ1 = (c, x3, lc, occ3) if kept else (x1, x2, l1, occ2)
    return x1, occ1, history, state
