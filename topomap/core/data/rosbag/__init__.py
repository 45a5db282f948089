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
    position topic (a pose or odometry), a step's position is that of the latest position message
    at or before it, and steps before the first one are dropped too.  Each bag of a list is one
    episode (``lengths``).

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

Every problem with a bag is a one-line :class:`ValueError` naming the file.

Modules: ``read`` (:func:`read_rosbag`) with ``options`` (its arguments, checked) and
``decode`` (messages into values, :func:`twist_action`), ``write`` (:func:`write_rosbag`),
``common`` (the rosbags import, message types, error messages).
"""

from .common import ACTION_TYPES, GDS_TYPES, POSITION_TYPES
from .decode import twist_action
from .read import read_rosbag
from .write import write_rosbag

__all__ = ["read_rosbag", "write_rosbag", "twist_action", "ACTION_TYPES", "GDS_TYPES",
           "POSITION_TYPES"]
