"""The ROS 1 bridge: map transfer over ROS topics and an ARIA-aware map server.

Nothing here imports ``rospy`` (or any ROS message package) at import time: the ROS modules are
imported inside the functions that need them (:mod:`mapkit.ros.node`), so mapkit works without
ROS and says which Debian packages to install when a ROS command is used.

* :mod:`mapkit.ros.map_server`: ``/map``, ``/map_metadata``, ``static_map``, ``change_map``,
  the keepout mask and the goals/homes/docks as pose arrays, for ARIA ``.map`` files.
* :mod:`mapkit.ros.grids`: what the map server serves and the ROS messages for it.
* :mod:`mapkit.ros.transport`: MKT/1 frames (:mod:`mapkit.transfer.protocol`) on a pair of
  ``std_msgs/UInt8MultiArray`` topics per channel.
"""
