"""Maps from continuous motion (logs recorded at 10-50 Hz).

``settings`` -- :class:`MotionSettings` (the learner's ``motion``; its groups
:class:`PlaceSettings` and :class:`CheckSettings`) and how a continuous log is recognised
(``renamed``: the settings' flat names of before 0.3); ``odometry`` -- the actions' displacements learned from the data, and positions
corrected by copies of the views; ``places`` -- places cut from views and positions; ``check``
-- the held-out check that keeps them or falls back to the view clusters; ``learn`` -- the
branch of :meth:`topomap.MapLearner.fit` that uses them.  ``motion="robot"``: ``scans`` --
headings from egocentric scans closed by loops; ``reckoning`` -- poses and keyframes;
``robot`` -- cells and places on the reckoned positions, a walk placed by its own odometry;
``robot_decode`` -- that decoder; ``symmetry`` -- whether the map is its own point reflection;
``robot_fit`` -- the branch of :meth:`topomap.MapLearner.fit` and ``predict`` that uses them.
"""

from .settings import (MODES, CheckSettings, MotionSettings, PlaceSettings, is_continuous,
                       mean_run, motion_settings)

__all__ = ["MODES", "MotionSettings", "PlaceSettings", "CheckSettings", "motion_settings",
           "is_continuous", "mean_run"]
