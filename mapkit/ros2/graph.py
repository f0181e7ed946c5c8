"""How a ROS 2 node looks on DDS (sans-I/O): topic names, QoS, discovery user data.

* ROS topic ``/map`` is the DDS topic ``rt/map`` (``rt/`` topics, ``rq/``/``rr/`` services).
* Participants carry USER_DATA ``enclave=/;``; on Jazzy every reader and writer carries
  ``typehash=RIHS01_...;`` (a missing hash counts as zero there, so Humble peers interoperate).
* The node itself exists only as a ``ParticipantEntitiesInfo`` sample on ``ros_discovery_info``
  (reliable, transient-local, keep-last 1), listing its writers' GUIDs.
"""

from __future__ import annotations

from dataclasses import dataclass

from mapkit.ros2.errors import Ros2Error

__all__ = [
    "DISCOVERY_TOPIC",
    "LATCHED",
    "QosSpec",
    "dds_topic",
    "endpoint_user_data",
    "participant_user_data",
    "resolve_topic",
]

#: The DDS topic where every ROS 2 participant announces its nodes (no ``rt/`` prefix).
DISCOVERY_TOPIC = "ros_discovery_info"


@dataclass(frozen=True)
class QosSpec:
    """The QoS of a ROS 2 publisher, as far as DDS matching sees it."""

    reliable: bool = True
    transient_local: bool = True
    depth: int = 1


#: nav2 map_server's ``/map``, costmap_filter_info_server's topics, ``ros_discovery_info``.
LATCHED = QosSpec(reliable=True, transient_local=True, depth=1)


def resolve_topic(name: str, namespace: str = "/") -> str:
    """A ROS 2 topic name made absolute (``map`` in ``/`` -> ``/map``).

    Raises:
        Ros2Error: For a name ROS 2 would refuse (empty, ``~``, characters other than
            letters, digits, ``_`` and ``/``, a part starting with a digit, ``//``).

    Examples:
        >>> resolve_topic("map"), resolve_topic("/robot1/map"), resolve_topic("map", "/r1")
        ('/map', '/robot1/map', '/r1/map')
    """
    if not name or name.startswith("~"):
        raise Ros2Error(f"invalid ROS 2 topic name {name!r}")
    full = name if name.startswith("/") else namespace.rstrip("/") + "/" + name
    parts = full.split("/")[1:]
    for part in parts:
        if (
            not part
            or part[0].isdigit()
            or not all(c.isalnum() or c == "_" for c in part)
            or not part.isascii()
        ):
            raise Ros2Error(f"invalid ROS 2 topic name {name!r}: bad part {part!r}")
    return full


def dds_topic(name: str, namespace: str = "/") -> str:
    """The DDS topic of a ROS 2 topic: ``rt`` + its absolute name.

    Examples:
        >>> dds_topic("map"), dds_topic("/keepout_filter_mask")
        ('rt/map', 'rt/keepout_filter_mask')
    """
    return "rt" + resolve_topic(name, namespace)


def participant_user_data(enclave: str = "/") -> bytes:
    """The participant USER_DATA ROS 2 writes (``enclave=/;``)."""
    return f"enclave={enclave};".encode()


def endpoint_user_data(type_hash: str | None) -> bytes:
    """An endpoint's USER_DATA: ``typehash=RIHS01_...;`` on Jazzy, nothing on Humble."""
    return f"typehash={type_hash};".encode() if type_hash else b""
