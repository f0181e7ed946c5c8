"""ROS 2 messages for the map server as CDR bytes (sans-I/O): build, serialise, hash.

Messages are built as :mod:`rosbags` message objects from the types of a ROS 2 distribution
(``humble`` or ``jazzy``) and serialised with ``rosbags.serde.serialize_cdr``: plain CDR (XCDR1),
little-endian, with the 4-byte encapsulation header ``00 01 00 00``, byte for byte what
rmw_fastrtps and rmw_cyclonedds put on the wire. Nav2's ``nav2_msgs/msg/CostmapFilterInfo``
is not in rosbags' stores and is registered from its ``.msg`` text.

Type hashes (REP 2011, ``RIHS01_...``) are what Jazzy's rmw announces in each endpoint's user
data; Humble announces none.
"""

from __future__ import annotations

import math
from functools import cache
from typing import Any

import numpy as np

from mapkit.raster.grid import OccupancyGrid
from mapkit.ros.grids import Pose
from mapkit.ros2.errors import Ros2Error

__all__ = [
    "COSTMAP_FILTER_INFO",
    "DISTROS",
    "KEEPOUT_FILTER",
    "OCCUPANCY_GRID",
    "PARTICIPANT_ENTITIES_INFO",
    "POSE_ARRAY",
    "costmap_filter_info_cdr",
    "grid_cdr",
    "participant_entities_info_cdr",
    "pose_array_cdr",
    "type_hash",
    "typestore",
]

DISTROS = ("humble", "jazzy")
OCCUPANCY_GRID = "nav_msgs/msg/OccupancyGrid"
POSE_ARRAY = "geometry_msgs/msg/PoseArray"
COSTMAP_FILTER_INFO = "nav2_msgs/msg/CostmapFilterInfo"
PARTICIPANT_ENTITIES_INFO = "rmw_dds_common/msg/ParticipantEntitiesInfo"
#: ``CostmapFilterInfo.type`` of Nav2's keepout (and preferred lanes) filter.
KEEPOUT_FILTER = 0

_COSTMAP_FILTER_INFO_MSG = """\
std_msgs/Header header
uint8 type
string filter_mask_topic
float32 base
float32 multiplier
"""


@cache
def typestore(distro: str = "jazzy") -> Any:
    """The rosbags type store of a ROS 2 distribution, with Nav2's CostmapFilterInfo added.

    Raises:
        Ros2Error: For a distribution other than ``humble`` or ``jazzy``.
    """
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    stores = {"humble": Stores.ROS2_HUMBLE, "jazzy": Stores.ROS2_JAZZY}
    if distro not in stores:
        raise Ros2Error(f"unknown ROS 2 distribution {distro!r}: use one of {', '.join(DISTROS)}")
    store = get_typestore(stores[distro])
    store.register(get_types_from_msg(_COSTMAP_FILTER_INFO_MSG, COSTMAP_FILTER_INFO))
    return store


def type_hash(typename: str, distro: str = "jazzy") -> str:
    """The REP 2011 type hash (``RIHS01_`` + 64 hex digits) of a message type.

    Examples:
        >>> type_hash("nav_msgs/msg/OccupancyGrid")[:15]
        'RIHS01_8d348150'
    """
    return str(typestore(distro).hash_rihs01(typename))


def _time(store: Any, seconds: float) -> Any:
    sec = math.floor(seconds)
    return store.types["builtin_interfaces/msg/Time"](
        sec=int(sec), nanosec=min(round((seconds - sec) * 1e9), 999_999_999)
    )


def _header(store: Any, frame_id: str, stamp: float) -> Any:
    return store.types["std_msgs/msg/Header"](stamp=_time(store, stamp), frame_id=frame_id)


def _pose(store: Any, x: float, y: float, yaw: float) -> Any:
    t = store.types
    return t["geometry_msgs/msg/Pose"](
        position=t["geometry_msgs/msg/Point"](x=float(x), y=float(y), z=0.0),
        orientation=t["geometry_msgs/msg/Quaternion"](
            x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2)
        ),
    )


def _serialize(store: Any, msg: Any, typename: str) -> bytes:
    return bytes(store.serialize_cdr(msg, typename))


def grid_cdr(
    grid: OccupancyGrid,
    frame_id: str = "map",
    stamp: float = 0.0,
    load_time: float | None = None,
    distro: str = "jazzy",
) -> bytes:
    """A ``nav_msgs/msg/OccupancyGrid`` as CDR: row-major from the southern row, int8 cells.

    Args:
        grid: The grid.
        frame_id: ``header.frame_id``.
        stamp: ``header.stamp`` in seconds since the epoch.
        load_time: ``info.map_load_time`` (default: ``stamp``).
        distro: ``humble`` or ``jazzy`` (the layout is the same).
    """
    store = typestore(distro)
    t = store.types
    info = t["nav_msgs/msg/MapMetaData"](
        map_load_time=_time(store, stamp if load_time is None else load_time),
        resolution=float(grid.resolution),
        width=int(grid.width),
        height=int(grid.height),
        origin=_pose(store, grid.origin[0], grid.origin[1], 0.0),
    )
    data = np.ascontiguousarray(grid.data, dtype=np.int8).ravel()
    msg = t[OCCUPANCY_GRID](header=_header(store, frame_id, stamp), info=info, data=data)
    return _serialize(store, msg, OCCUPANCY_GRID)


def pose_array_cdr(
    poses: tuple[Pose, ...], frame_id: str = "map", stamp: float = 0.0, distro: str = "jazzy"
) -> bytes:
    """A ``geometry_msgs/msg/PoseArray`` as CDR (z 0, yaw as a quaternion about z)."""
    store = typestore(distro)
    msg = store.types[POSE_ARRAY](
        header=_header(store, frame_id, stamp), poses=[_pose(store, p.x, p.y, p.yaw) for p in poses]
    )
    return _serialize(store, msg, POSE_ARRAY)


def costmap_filter_info_cdr(
    mask_topic: str,
    frame_id: str = "map",
    stamp: float = 0.0,
    filter_type: int = KEEPOUT_FILTER,
    base: float = 0.0,
    multiplier: float = 1.0,
    distro: str = "jazzy",
) -> bytes:
    """A ``nav2_msgs/msg/CostmapFilterInfo`` as CDR, as Nav2's costmap_filter_info_server sends.

    The defaults describe a keepout mask (type 0, base 0, multiplier 1: mask value 100 keeps
    the robot out, -1 and 0 leave the costmap as it is).
    """
    store = typestore(distro)
    msg = store.types[COSTMAP_FILTER_INFO](
        header=_header(store, frame_id, stamp),
        type=int(filter_type),
        filter_mask_topic=mask_topic,
        base=float(base),
        multiplier=float(multiplier),
    )
    return _serialize(store, msg, COSTMAP_FILTER_INFO)


def gid_size(distro: str) -> int:
    """Bytes in an ``rmw_dds_common/msg/Gid``: 24 on Humble, 16 from Iron on."""
    return 24 if distro == "humble" else 16


def participant_entities_info_cdr(
    participant_gid: bytes,
    node_name: str,
    node_namespace: str,
    writer_gids: list[bytes],
    reader_gids: list[bytes] | None = None,
    distro: str = "jazzy",
) -> bytes:
    """The ``ros_discovery_info`` sample that puts one node into the ROS 2 graph.

    Args:
        participant_gid: The DDS participant's 16-byte GUID.
        node_name: The node's name (``ros2 node list`` shows ``namespace/name``).
        node_namespace: Its namespace (``/``).
        writer_gids: 16-byte GUIDs of the node's writers.
        reader_gids: 16-byte GUIDs of its readers.
        distro: ``humble`` (Gid of 24 bytes, GUID zero-padded) or ``jazzy`` (16 bytes).
    """
    store = typestore(distro)
    t = store.types
    size = gid_size(distro)

    def gid(raw: bytes) -> Any:
        if len(raw) != 16:
            raise Ros2Error(f"a DDS GUID has 16 bytes, got {len(raw)}")
        return t["rmw_dds_common/msg/Gid"](
            data=np.frombuffer(raw.ljust(size, b"\0"), dtype=np.uint8).copy()
        )

    node = t["rmw_dds_common/msg/NodeEntitiesInfo"](
        node_namespace=node_namespace,
        node_name=node_name,
        reader_gid_seq=[gid(g) for g in reader_gids or []],
        writer_gid_seq=[gid(g) for g in writer_gids],
    )
    msg = t[PARTICIPANT_ENTITIES_INFO](gid=gid(participant_gid), node_entities_info_seq=[node])
    return _serialize(store, msg, PARTICIPANT_ENTITIES_INFO)
