# mypy: disable-error-code="type-arg,valid-type"
"""ROS 2 message types declared for the DDS binding, named as rosidl names them on the wire.

The DDS type of ``pkg/msg/Name`` is ``pkg::msg::dds_::Name_``. These declarations give Cyclone
DDS the type names (what matching checks) and the XTypes type information it announces; the
bytes themselves come from :mod:`mapkit.ros2.messages` (rosbags), which this module's types
must and do match field for field. Imported only when the DDS binding is used.
"""

# No ``from __future__ import annotations``: cyclonedds reads these annotations as objects
# (its IDL annotations such as sequence[int8] are not types to mypy, hence the line above).

from typing import Any

from cyclonedds.idl import IdlStruct, types as t

from mapkit.ros2.messages import (
    COSTMAP_FILTER_INFO,
    OCCUPANCY_GRID,
    PARTICIPANT_ENTITIES_INFO,
    POSE_ARRAY,
    gid_size,
)

__all__ = ["dds_type", "dds_type_name"]


def dds_type_name(typename: str) -> str:
    """``pkg/msg/Name`` -> ``pkg::msg::dds_::Name_`` (rosidl's DDS type name).

    Examples:
        >>> dds_type_name("nav_msgs/msg/OccupancyGrid")
        'nav_msgs::msg::dds_::OccupancyGrid_'
    """
    pkg, kind, name = typename.split("/")
    return f"{pkg}::{kind}::dds_::{name}_"


class Time_(IdlStruct, typename="builtin_interfaces::msg::dds_::Time_"):
    sec: t.int32
    nanosec: t.uint32


class Header_(IdlStruct, typename="std_msgs::msg::dds_::Header_"):
    stamp: Time_
    frame_id: str


class Point_(IdlStruct, typename="geometry_msgs::msg::dds_::Point_"):
    x: t.float64
    y: t.float64
    z: t.float64


class Quaternion_(IdlStruct, typename="geometry_msgs::msg::dds_::Quaternion_"):
    x: t.float64
    y: t.float64
    z: t.float64
    w: t.float64


class Pose_(IdlStruct, typename="geometry_msgs::msg::dds_::Pose_"):
    position: Point_
    orientation: Quaternion_


class MapMetaData_(IdlStruct, typename="nav_msgs::msg::dds_::MapMetaData_"):
    map_load_time: Time_
    resolution: t.float32
    width: t.uint32
    height: t.uint32
    origin: Pose_


class OccupancyGrid_(IdlStruct, typename="nav_msgs::msg::dds_::OccupancyGrid_"):
    header: Header_
    info: MapMetaData_
    data: t.sequence[t.int8]


class PoseArray_(IdlStruct, typename="geometry_msgs::msg::dds_::PoseArray_"):
    header: Header_
    poses: t.sequence[Pose_]


class CostmapFilterInfo_(IdlStruct, typename="nav2_msgs::msg::dds_::CostmapFilterInfo_"):
    header: Header_
    type: t.uint8
    filter_mask_topic: str
    base: t.float32
    multiplier: t.float32


class Gid16_(IdlStruct, typename="rmw_dds_common::msg::dds_::Gid_"):
    data: t.array[t.uint8, 16]


class Gid24_(IdlStruct, typename="rmw_dds_common::msg::dds_::Gid_"):
    data: t.array[t.uint8, 24]


class NodeEntitiesInfo16_(IdlStruct, typename="rmw_dds_common::msg::dds_::NodeEntitiesInfo_"):
    node_namespace: t.bounded_str[256]
    node_name: t.bounded_str[256]
    reader_gid_seq: t.sequence[Gid16_]
    writer_gid_seq: t.sequence[Gid16_]


class NodeEntitiesInfo24_(IdlStruct, typename="rmw_dds_common::msg::dds_::NodeEntitiesInfo_"):
    node_namespace: t.bounded_str[256]
    node_name: t.bounded_str[256]
    reader_gid_seq: t.sequence[Gid24_]
    writer_gid_seq: t.sequence[Gid24_]


class ParticipantEntitiesInfo16_(
    IdlStruct, typename="rmw_dds_common::msg::dds_::ParticipantEntitiesInfo_"
):
    gid: Gid16_
    node_entities_info_seq: t.sequence[NodeEntitiesInfo16_]


class ParticipantEntitiesInfo24_(
    IdlStruct, typename="rmw_dds_common::msg::dds_::ParticipantEntitiesInfo_"
):
    gid: Gid24_
    node_entities_info_seq: t.sequence[NodeEntitiesInfo24_]


_TYPES: dict[str, Any] = {
    OCCUPANCY_GRID: OccupancyGrid_,
    POSE_ARRAY: PoseArray_,
    COSTMAP_FILTER_INFO: CostmapFilterInfo_,
}


def dds_type(typename: str, distro: str = "jazzy") -> Any:
    """The declared DDS type class of a ROS 2 message type."""
    if typename == PARTICIPANT_ENTITIES_INFO:
        return ParticipantEntitiesInfo24_ if gid_size(distro) == 24 else ParticipantEntitiesInfo16_
    return _TYPES[typename]
