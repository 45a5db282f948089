"""Actions from motion: discrete commands read off a continuous path.

An action rule is a component with plain typed parameters, ``action_names`` and
``actions(motion) -> (T,) int`` (ids into ``action_names``), given the path's
:class:`~topomap.worlds.arena.kinematics.Motion`.  The action of step ``t`` describes the move from
sample ``t`` to sample ``t + 1``, the command a robot executes after its observation at ``t``.

:class:`CompassActions`
    the octant of the velocity (``east``, ``northeast``, ... ``southeast``), or ``stop`` below
    ``linear_threshold`` m/s.
:class:`TurnActions`
    what a differential-drive robot is commanded, by the same rule as a ROS ``Twist``
    (:func:`topomap.core.data.rosbag.decode.twist_action`): turning wins over driving,
    ``turn_left`` / ``turn_right`` at a rotational velocity of at least ``angular_threshold``
    rad/s either way, else ``forward`` at ``linear_threshold`` m/s or more, else ``stop``.
"""

from __future__ import annotations

import numpy as np

from ...core.checks import ParameterError
from .checks import positive

__all__ = ["CompassActions", "TurnActions", "ACTION_RULES", "make_action_rule"]

COMPASS = ["east", "northeast", "north", "northwest", "west", "southwest", "south", "southeast"]


class CompassActions:
    """The octant of the velocity, or ``stop``.

    Parameters
    ----------
    linear_threshold : float
        Below this speed (m/s) the action is ``stop``.
    """

    action_names = [*COMPASS, "stop"]

    def __init__(self, linear_threshold: float = 0.02):
        self.linear_threshold = positive("linear_threshold", linear_threshold)

    def actions(self, motion) -> np.ndarray:
        """(T,) ids: octant ``k`` is centred on ``45 k`` degrees anticlockwise from east."""
        v = np.asarray(motion.velocity, dtype=np.float64)
        octant = np.round(np.arctan2(v[:, 1], v[:, 0]) / (np.pi / 4)).astype(np.int64) % 8
        slow = np.hypot(v[:, 0], v[:, 1]) < self.linear_threshold
        return np.where(slow, len(COMPASS), octant)

    def __repr__(self) -> str:
        return f"CompassActions(linear_threshold={self.linear_threshold:g})"


class TurnActions:
    """``forward``, ``turn_left``, ``turn_right`` or ``stop``, from speed and turning rate.

    Parameters
    ----------
    linear_threshold : float
        m/s: slower (and not turning) is ``stop``.
    angular_threshold : float
        rad/s: turning at least this fast (anticlockwise positive) is a turn.
    """

    action_names = ["forward", "turn_left", "turn_right", "stop"]

    def __init__(self, linear_threshold: float = 0.02, angular_threshold: float = 0.5):
        self.linear_threshold = positive("linear_threshold", linear_threshold)
        self.angular_threshold = positive("angular_threshold", angular_threshold)

    def actions(self, motion) -> np.ndarray:
        """(T,) ids, by the ``Twist`` rule (see the module docstring)."""
        w = np.asarray(motion.rotational_velocity, dtype=np.float64)
        speed = np.hypot(*np.asarray(motion.velocity, dtype=np.float64).T)
        return np.select([w >= self.angular_threshold, w <= -self.angular_threshold,
                          speed >= self.linear_threshold], [1, 2, 0], default=3)

    def __repr__(self) -> str:
        return (f"TurnActions(linear_threshold={self.linear_threshold:g}, "
                f"angular_threshold={self.angular_threshold:g})")


#: the action rules by name (a world given a name builds the rule with its defaults)
ACTION_RULES = {"compass": CompassActions, "turns": TurnActions}


def make_action_rule(rule):
    """``rule`` if it is an action rule, else the rule named ``rule`` with its defaults."""
    if isinstance(rule, str):
        if rule not in ACTION_RULES:
            raise ParameterError("actions", f"must be one of {', '.join(ACTION_RULES)} or an "
                                            f"action rule, got {rule!r}")
        return ACTION_RULES[rule]()
    if not callable(getattr(rule, "actions", None)) or not getattr(rule, "action_names", None):
        raise ParameterError("actions", "must have action_names and an actions(motion) method, "
                                        f"got {rule!r}")
    return rule
