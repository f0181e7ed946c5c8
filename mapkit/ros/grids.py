"""What the map server serves, from an ARIA ``.map`` or a map_server YAML, and its ROS messages.

:func:`served_map` turns a file into a :class:`ServedMap`: the occupancy grid (from mapkit's
rasteriser for a ``.map``, from the map_server YAML + image reader for a ``.yaml``), the keepout
mask of its forbidden areas and lines on the same grid, and the goals, homes and docks as poses
in metres. The ``*_message`` functions build the ROS messages (``nav_msgs/OccupancyGrid``,
``nav_msgs/MapMetaData``, ``geometry_msgs/PoseArray``); they import the message packages when
called, so this module imports without ROS.

Failures are :class:`MapLoadError` values carrying the ``nav_msgs/LoadMap`` result code that
``change_map`` answers with (1 map does not exist, 2 invalid map data, 3 invalid map metadata,
255 undefined failure).
"""

from __future__ import annotations

import hashlib
import math
import os
import stat
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from mapkit.errors import FormatError, MapkitError
from mapkit.model import MapData
from mapkit.raster.grid import OccupancyGrid
from mapkit.ros.node import ros_import

__all__ = [
    "LOAD_INVALID_DATA",
    "LOAD_INVALID_METADATA",
    "LOAD_NOT_FOUND",
    "LOAD_SUCCESS",
    "LOAD_UNDEFINED",
    "MapLoadError",
    "Pose",
    "ServedMap",
    "grid_message",
    "map_poses",
    "metadata_message",
    "pose_array_message",
    "served_map",
]

#: ``nav_msgs/LoadMap`` result codes (the same numbers as ROS's map_server).
LOAD_SUCCESS = 0
LOAD_NOT_FOUND = 1
LOAD_INVALID_DATA = 2
LOAD_INVALID_METADATA = 3
LOAD_UNDEFINED = 255


class MapLoadError(MapkitError):
    """A map could not be loaded for serving; ``code`` is the ``nav_msgs/LoadMap`` result."""

    def __init__(self, message: str, code: int) -> None:
        super().__init__(message)
        self.code = code


@dataclass(frozen=True)
class Pose:
    """A named pose on the map in ROS units: metres and radians (yaw counter-clockwise from x)."""

    x: float
    y: float
    yaw: float
    name: str = ""
    type: str = ""


@dataclass(frozen=True)
class ServedMap:
    """Everything the map server publishes for one map.

    Attributes:
        path: The file it came from.
        grid: The occupancy grid (``/map``).
        keepout: Forbidden areas and lines as a mask on the same grid (100 forbidden, -1
            elsewhere: Nav2's keepout-filter convention), ``None`` for a map_server YAML.
        goals: Goals (any goal type, with or without heading).
        homes: Robot homes.
        docks: Docks.
        sha256: SHA-256 of the file's bytes.
        md5: MD5 of the file's bytes (ARIA's map checksum).
        yaw: The origin's yaw in radians (a map_server YAML's third ``origin`` value; published
            in ``info.origin.orientation`` as map_server does).
    """

    path: str
    grid: OccupancyGrid
    keepout: OccupancyGrid | None
    goals: tuple[Pose, ...]
    homes: tuple[Pose, ...]
    docks: tuple[Pose, ...]
    sha256: str
    md5: str
    yaw: float = 0.0

    @property
    def name(self) -> str:
        """The file's name without folders."""
        return os.path.basename(self.path)


def _pose(obj: Any) -> Pose:
    return Pose(obj.x / 1000.0, obj.y / 1000.0, math.radians(obj.theta), obj.name, obj.type)


def map_poses(m: MapData) -> tuple[tuple[Pose, ...], tuple[Pose, ...], tuple[Pose, ...]]:
    """Goals, homes and docks of a map as poses in metres and radians.

    Goals are ``Goal``/``GoalWithHeading`` and every type the map declares as a ``GoalType`` (with
    or without ``WithHeading``); docks likewise with ``Dock`` and ``DockType``; homes are
    ``RobotHome`` objects (point or rectangle: their pose).

    Examples:
        >>> from mapkit.model import MapData, MapObject
        >>> m = MapData(objects=(MapObject("GoalWithHeading", 1000, -500, 90, name="Desk"),
        ...                      MapObject("RobotHome", 0, 0), MapObject("ForbiddenArea", 0, 0,
        ...                      from_to=(0, 0, 1, 1))))
        >>> goals, homes, docks = map_poses(m)
        >>> goals[0].x, goals[0].y, round(goals[0].yaw, 4), goals[0].name, len(homes), len(docks)
        (1.0, -0.5, 1.5708, 'Desk', 1, 0)
    """
    declared = m.declared_types()
    goal_types = {"Goal"} | {t for t, k in declared.items() if k == "GoalType"}
    dock_types = {"Dock"} | {t for t, k in declared.items() if k == "DockType"}
    goals, homes, docks = [], [], []
    for obj in m.objects:
        base = obj.base_type
        if obj.type == "RobotHome":
            homes.append(_pose(obj))
        elif obj.is_point and base in goal_types:
            goals.append(_pose(obj))
        elif obj.is_point and base in dock_types:
            docks.append(_pose(obj))
    return tuple(goals), tuple(homes), tuple(docks)


def _keepout(m: MapData, grid: OccupancyGrid) -> OccupancyGrid:
    from mapkit.raster.masks import keepout_mask

    return keepout_mask(m, grid)


def served_map(path: str | os.PathLike[str], resolution: float = 0.05, **raster: Any) -> ServedMap:
    """Load a file for serving: an ARIA ``.map`` (rasterised) or a map_server YAML.

    Args:
        path: ``.map`` file, or ``.yaml``/``.yml`` map_server description; a ``file://`` URL
            (as ``change_map`` requests carry) is accepted too.
        resolution: Metres per cell for a ``.map`` (a YAML carries its own).
        **raster: More options for :func:`mapkit.raster.rasterize.rasterize` (``free``,
            ``margin_m``, ``inflate_mm`` ...).

    Returns:
        The map, ready to publish.

    Raises:
        MapLoadError: With code 1 when the file does not exist, 2 when it is not a valid map, 3
            when the resolution (or YAML metadata) is invalid, 255 otherwise.
    """
    from mapkit.formats.map import loads
    from mapkit.raster.rasterize import rasterize

    text = os.fspath(path)
    if text.startswith("file://"):
        text = text[len("file://"):]
    p = Path(text)
    try:
        if not stat.S_ISREG(os.stat(p).st_mode) and not p.is_dir():  # a pipe would block
            raise MapLoadError(f"{p}: not a regular file (a device or pipe)", LOAD_NOT_FOUND)
        data = p.read_bytes()
    except ValueError as err:  # a NUL byte in the name
        raise MapLoadError(f"{text!r}: not a valid file name", LOAD_NOT_FOUND) from err
    except FileNotFoundError as err:
        raise MapLoadError(f"{p}: no such map file", LOAD_NOT_FOUND) from err
    except IsADirectoryError as err:
        raise MapLoadError(f"{p}: is a folder, not a map file", LOAD_NOT_FOUND) from err
    except OSError as err:
        raise MapLoadError(f"{p}: {err.strerror}", LOAD_UNDEFINED) from err
    sha256, md5 = hashlib.sha256(data).hexdigest(), hashlib.md5(data).hexdigest()
    suffix = p.suffix.lower()
    if suffix in (".yaml", ".yml"):
        grid, yaw = _read_yaml_grid(p)
        return ServedMap(str(p), grid, None, (), (), (), sha256, md5, yaw)
    if not (math.isfinite(resolution) and resolution > 0):
        raise MapLoadError(f"resolution must be a positive number of metres, got {resolution!r}",
                           LOAD_INVALID_METADATA)
    try:
        m = loads(data, source=str(p))
    except FormatError as err:
        raise MapLoadError(str(err), LOAD_INVALID_DATA) from err
    try:
        grid = rasterize(m, resolution, **raster)
    except (MapkitError, ValueError) as err:
        raise MapLoadError(f"{p}: {err}", LOAD_INVALID_METADATA) from err
    goals, homes, docks = map_poses(m)
    return ServedMap(str(p), grid, _keepout(m, grid), goals, homes, docks, sha256, md5)


def _read_yaml_grid(p: Path) -> tuple[OccupancyGrid, float]:
    from mapkit.raster.ros import image_to_grid, open_map_image, read_ros_yaml

    try:
        info = read_ros_yaml(p)
        return image_to_grid(open_map_image(info).read_all(), info), info.origin[2]
    except FormatError as err:
        # A YAML that map_server would not accept is bad metadata; a bad image is bad data.
        code = LOAD_INVALID_METADATA if str(err.source).lower().endswith((".yaml", ".yml")) \
            else LOAD_INVALID_DATA
        raise MapLoadError(str(err), code) from err


# -- messages -------------------------------------------------------------------------------


def _header(msg: Any, frame_id: str, stamp: Any) -> None:
    msg.header.frame_id = frame_id
    if stamp is not None:
        msg.header.stamp = stamp


def _info(info: Any, grid: OccupancyGrid, load_time: Any, yaw: float = 0.0) -> Any:
    if load_time is not None:
        info.map_load_time = load_time
    info.resolution = grid.resolution
    info.width = grid.width
    info.height = grid.height
    info.origin.position.x, info.origin.position.y = grid.origin
    # map_server: tf2::Quaternion::setEulerZYX(yaw, 0, 0), a rotation about z.
    info.origin.orientation.z = math.sin(yaw / 2.0)
    info.origin.orientation.w = math.cos(yaw / 2.0)
    return info


def metadata_message(grid: OccupancyGrid, load_time: Any = None, yaw: float = 0.0) -> Any:
    """A ``nav_msgs/MapMetaData`` for a grid (``load_time`` a ``rospy.Time``; origin ``yaw``)."""
    msgs = ros_import("nav_msgs.msg")
    return _info(msgs.MapMetaData(), grid, load_time, yaw)


def grid_message(grid: OccupancyGrid, frame_id: str = "map", stamp: Any = None,
                 load_time: Any = None, yaw: float = 0.0) -> Any:
    """A ``nav_msgs/OccupancyGrid`` for a grid: row-major from the southern row, int8 cells."""
    msgs = ros_import("nav_msgs.msg")
    msg = msgs.OccupancyGrid()
    _header(msg, frame_id, stamp)
    _info(msg.info, grid, load_time, yaw)
    msg.data = np.ascontiguousarray(grid.data, dtype=np.int8).ravel().tolist()
    return msg


def pose_array_message(poses: tuple[Pose, ...], frame_id: str = "map", stamp: Any = None) -> Any:
    """A ``geometry_msgs/PoseArray`` of poses (z 0, yaw as a quaternion about z)."""
    gm = ros_import("geometry_msgs.msg")
    msg = gm.PoseArray()
    _header(msg, frame_id, stamp)
    for pose in poses:
        p = gm.Pose()
        p.position.x, p.position.y = pose.x, pose.y
        p.orientation.z, p.orientation.w = math.sin(pose.yaw / 2), math.cos(pose.yaw / 2)
        msg.poses.append(p)
    return msg
