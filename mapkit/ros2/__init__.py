"""ROS 2 without ROS 2: mapkit's maps on a Humble/Jazzy robot's topics, over DDS.

A process with no ROS 2 install joins the ROS 2 graph as a DDS participant (Cyclone DDS from
PyPI, ``pip install 'mapkit[ros2]'``) and publishes what nav2's map_server publishes.

* :mod:`mapkit.ros2.messages`: the messages as CDR bytes (rosbags), type hashes (sans-I/O).
* :mod:`mapkit.ros2.graph`: topic naming, QoS, discovery user data (sans-I/O).
* :mod:`mapkit.ros2.dds`: the thin DDS driver (a node, its writers, ``ros_discovery_info``).
* :mod:`mapkit.ros2.map_server`: ``mapkit ros2 map-server`` and ``mapkit ros2 aria-bridge``.
"""
