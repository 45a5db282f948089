"""``explorer=active``: go where the map is least known, by the history or the plan policy."""

from __future__ import annotations

from ...core.checks import ParameterError
from .history import HistoryExplorer
from .plan import PlanExplorer

__all__ = ["active_explorer", "ROUTES"]

#: what a state can be: the routes, one explorer each
ROUTES = ("history", "plan")


def active_explorer(update_every: int = 250, route: str = "history", context: int = 3,
                    gamma: float = 0.9, horizon: int = 30, epsilon: float = 0.0):
    """Go where the map is least known: count-based novelty on (state, action) pairs.

    ``route`` says what a state is, and so which explorer is made:

    * ``"history"`` (default): the robot's recent past read through the map's symbols
      (:class:`~topomap.worlds.explorers.history.HistoryExplorer` with ``context``);
    * ``"plan"``: the map's own state, tracked as a belief, with planned novelty
      (:class:`~topomap.worlds.explorers.plan.PlanExplorer` with ``gamma`` and ``horizon``).

    Every setting is checked, whichever the route.  Both walk at random until a map exists; the
    run maps while exploring every ``update_every`` steps
    (:meth:`topomap.MapLearner.partial_fit`).  Measured (``benchmarks/bench_online.py``):
    ``"history"`` reaches a given ARI in about as many steps as a random walk, ``"plan"`` in more
    on gridrooms.

    Parameters
    ----------
    update_every : int
        Steps between two updates of the map.
    route : {"history", "plan"}
        What a state is (see above).
    context : int
        ``"history"``: the past views that make a state, besides the current one.
    gamma : float
        ``"plan"``: discount of the value iteration, in (0, 1).
    horizon : int
        ``"plan"``: rounds of value iteration.
    epsilon : float
        Share of random actions, in [0, 1].
    """
    if route not in ROUTES:
        raise ParameterError("route", f"must be one of {', '.join(ROUTES)}, got {route!r}")
    made = {"history": HistoryExplorer(update_every, context, epsilon),   # both made: every
            "plan": PlanExplorer(update_every, gamma, horizon, epsilon)}  # setting is checked
    return made[route]
