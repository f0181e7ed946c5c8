"""Errors of the ROS bridge (all :class:`~mapkit.errors.MapkitError` subclasses)."""

from __future__ import annotations

from mapkit.errors import MapkitError

__all__ = ["ROS_APT_PACKAGES", "RosError", "RosUnavailableError"]

#: The Debian packages that bring ROS 1 (what ``scripts/setup`` installs).
ROS_APT_PACKAGES = (
    "ros-core python3-rospy python3-std-msgs python3-nav-msgs python3-geometry-msgs "
    "python3-std-srvs python3-rostopic python3-rosservice"
)


class RosError(MapkitError):
    """Something on the ROS side failed: no master, a service that does not answer, a timeout."""


class RosUnavailableError(RosError, ImportError):
    """ROS 1 (rospy and the message packages) is not installed here."""
