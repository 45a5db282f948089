"""ROS 1 and ROS 2 bags as a topomap data source: :func:`read_rosbag` and :func:`write_rosbag`.

Bags are read and written with the pure-Python ``rosbags`` package (the optional ``ros`` extra);
no ROS installation is needed.  A ROS 1 bag is one ``.bag`` file; a ROS 2 bag is a folder with a
``metadata.yaml`` and its sqlite3 (``.db3``) or MCAP (``.mcap``) storage file, which may also be
passed on its own.

How messages become steps (:func:`read_rosbag`)
    One step per message on the action topic, at that message's bag (record) timestamp.  The
    step's observation is the latest observation message recorded at or before it; steps before
    the first observation are dropped (their count per bag is kept in ``meta["dropped_steps"]``).
    With a GDS topic, a step gets the GDS of the GDS message nearest in time to it if that message
    is at most ``gds_window`` seconds away (the earlier one on a tie), else none (-1).  With a
    position topic (the ground truth: a pose) or an odometry topic (the robot's dead reckoning), a
    step's position or odometry is that of the latest such message at or before it, and steps
    before the first one are dropped too.  Each bag of a list is one episode (``lengths``).

Positions and odometry
    Positions are the ground truth, used only to score a map: a motion capture's or a
    simulator's pose (``POSITION_TYPES``), or a ``tf2_msgs/TFMessage`` topic's transform from
    ``position_frame`` to ``position_child_frame``.  Poses in the frame ``odom`` -- the robot's
    own, which drifts (REP 105) -- are refused as positions unless ``position_frame="odom"``
    says so.  Odometry (``ODOMETRY_TYPES``: ``nav_msgs/Odometry``, ``PoseStamped``, ...) gives
    x, y and the yaw of the orientation (``Trajectory.odometry``); a move of more than
    ``MAX_ODOMETRY_STEP`` metres between two steps is an error naming the step.

Observations
    ``sensor_msgs/LaserScan``: the ``ranges`` with every ``inf``/``nan`` replaced by the scan's
    ``range_max``, then optionally clipped at ``max_range``, then optionally reduced to
    ``scan_bins`` sectors, sector ``k`` holding the minimum range of beams
    ``[k*N//B, (k+1)*N//B)``.  Any message type: the numeric fields named in
    ``observation_fields`` (dotted paths such as ``pose.position.x``; an array field gives one
    column per element), in the order given.

Actions
    ``std_msgs/String`` (names, kept in ``action_names``), ``std_msgs/Int32`` (ids >= 0) and
    ``geometry_msgs/Twist`` or ``TwistStamped`` discretised by :func:`twist_action`.  Names get ids
    in order of first appearance over the steps of all bags, unless ``action_names`` fixes them.
    The same holds for GDS names (``std_msgs/String``) and ids (``std_msgs/Int32``).

What :func:`write_rosbag` writes, one message of each topic per step at the step's time
    observations (``sensor_msgs/LaserScan`` or ``std_msgs/Float64MultiArray``), actions
    (``std_msgs/String`` names, or ``Int32`` ids, the names also on ``<action topic>/names`` in
    id order), GDS (likewise, at steps with one), the ground truth (``geometry_msgs/PoseStamped``
    in ``map``), the odometry (``nav_msgs/Odometry`` from ``odom`` to ``base_link``, its twist
    the velocity over the step before) and its transform (``/tf``: ``tf2_msgs/TFMessage``
    ``odom`` -> ``base_link``), and on request the actions as velocity commands
    (``geometry_msgs/Twist`` on ``cmd_vel_topic``, by ``messages.TWIST_OF_ACTION``).

Every problem with a bag is a one-line :class:`ValueError` naming the file.

Modules: ``read`` (:func:`read_rosbag`) with ``options`` (its arguments, checked) and
``decode`` (messages into values, :func:`twist_action`), ``write`` (:func:`write_rosbag`) with
``messages`` (the messages of a step), ``common`` (the rosbags import, message types, errors).
"""

from .common import ACTION_TYPES, GDS_TYPES, ODOMETRY_TYPES, POSITION_TYPES
from .decode import twist_action
from .messages import TWIST_OF_ACTION
from .read import read_rosbag
from .write import write_rosbag

__all__ = ["read_rosbag", "write_rosbag", "twist_action", "ACTION_TYPES", "GDS_TYPES",
           "POSITION_TYPES", "ODOMETRY_TYPES", "TWIST_OF_ACTION"]
