"""Exploration policies: how the simulated robot picks its next action.

An explorer has one method, ``choose(executable, rng) -> int``, which receives the boolean mask of
the actions that can be started at the current place and returns the index of one of them (it
only reads the mask).  Two optional methods let an explorer use what a real robot has, and
nothing more:

* ``see(view)`` -- called by the world before every ``choose`` with a :class:`View`: the step's
  observation, the executable actions and the GDS recognised there.  A view has no place: the
  true place never reaches an explorer.
* ``update(learner)`` -- called while mapping as the robot explores (``data.update_every``, or
  an explorer with this method) after every ``partial_fit`` of the run's
  :class:`~topomap.MapLearner`: the map learned so far is ``learner.map_``.

=============  ====================================================================================
module         its one job
=============  ====================================================================================
``base``       the view, the mask check, :class:`RandomExplorer` (the paper's), :class:`MapExplorer`
``history``    :class:`HistoryExplorer`: the action least taken from the recent past's symbols
``plan``       :class:`PlanExplorer`: the action of highest planned novelty under a belief
``active``     :func:`active_explorer` (``explorer=active``): one of the two, by ``route``
=============  ====================================================================================
"""

from .active import active_explorer
from .base import MapExplorer, RandomExplorer, View, show
from .history import HistoryExplorer
from .plan import PlanExplorer

__all__ = ["View", "show", "RandomExplorer", "MapExplorer", "HistoryExplorer", "PlanExplorer",
           "active_explorer"]
