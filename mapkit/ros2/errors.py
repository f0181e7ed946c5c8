"""The ROS 2 bridge's error."""

from __future__ import annotations

from mapkit.errors import MapkitError

__all__ = ["Ros2Error"]


class Ros2Error(MapkitError):
    """ROS 2 over DDS failed: the DDS binding is missing, a topic cannot be created, ..."""
