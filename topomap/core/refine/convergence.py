"""When an iterative fit stops: :class:`ConvergenceMonitor` (the role of hmmlearn's)."""

from __future__ import annotations

__all__ = ["ConvergenceMonitor"]


class ConvergenceMonitor:
    """Collects the value an iterative fit reports after every iteration (a log-likelihood, a
    path's log-probability) and tells when to stop.

    The fit has converged after ``n_iter`` reports, or once the last value has *stalled*: it
    gained less than ``tol`` over the value before (``last - previous < tol``; ``tol=0``: it did
    not rise), or, with ``rtol``, it is not above ``previous + rtol * |previous|`` (a gain relative
    to the value's size; ``tol`` is then not used).  The gain is judged only once more than
    ``min_iter`` values are reported (from a random start the first iterations barely move).

    Attributes
    ----------
    history : list -- every reported value, in order
    iter : int -- the number of reports
    stalled : bool -- whether the last value stalled
    converged : bool -- whether to stop
    """

    def __init__(self, tol: float = 0.0, n_iter: int = 100, *, min_iter: int = 0,
                 rtol: float | None = None):
        self.tol = tol
        self.n_iter = n_iter
        self.min_iter = min_iter
        self.rtol = rtol
        self.history = []

    def __repr__(self) -> str:
        return (f"ConvergenceMonitor(tol={self.tol!r}, n_iter={self.n_iter!r}, "
                f"min_iter={self.min_iter!r}, rtol={self.rtol!r}, iter={self.iter})")

    def report(self, value) -> None:
        """Record the value of one more iteration."""
        self.history.append(value)

    @property
    def iter(self) -> int:
        """The number of values reported."""
        return len(self.history)

    @property
    def stalled(self) -> bool:
        """Whether the last value gained too little over the one before to go on."""
        if len(self.history) <= max(self.min_iter, 1):
            return False
        previous, last = self.history[-2], self.history[-1]
        if self.rtol is not None:
            return last <= previous + self.rtol * abs(previous)
        return last - previous < self.tol

    @property
    def converged(self) -> bool:
        """Whether the fit should stop: ``n_iter`` values reported, or the last one stalled."""
        return self.iter >= self.n_iter or self.stalled
