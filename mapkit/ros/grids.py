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

Big maps. A ``.map`` is rasterised band by band (:class:`~mapkit.raster.bands.BandRaster`), and
a YAML's 8-bit PGM read band by band (:func:`~mapkit.raster.image_stream.pgm_bands`): only the
grid itself (one byte a cell) and its keepout mask are kept, as the messages need them. The
messages are serialised from the grid's bytes (:func:`grid_message`), not through rospy's own
``int8[]`` code, which packs a Python list of one object a cell (8 bytes a cell, twice over).

ROS 1's limit, checked before any work (:func:`check_ros1_size`): every roscpp node (rviz,
move_base, amcl, map_server's clients) drops a message whose length is over 1,000,000,000 bytes
("a message of over a gigabyte was predicted in tcpros", ``TransportPublisherLink`` and
``ServiceServerLink`` in ros_comm); a ``nav_msgs/OccupancyGrid`` is one byte a cell plus about
100 bytes, so a grid over :data:`ROS1_MAX_CELLS` cells cannot reach them (rospy subscribers take
up to the wire format's uint32 length, 4,294,967,295 bytes). The 415 x 270 m site at 2 cm is
282 M cells, well inside; at 1 cm (1.1 G cells) it is refused with this explanation.
"""

from __future__ import annotations

import hashlib
import io
import math
import os
import stat
import struct
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from mapkit.errors import FormatError, MapkitError
from mapkit.model import MapData
from mapkit.raster.export import ROS1_MAX_CELLS, ROS1_MAX_MESSAGE_BYTES
from mapkit.raster.grid import OccupancyGrid
from mapkit.ros.node import ros_import

__all__ = [
    "LOAD_INVALID_DATA",
    "LOAD_INVALID_METADATA",
    "LOAD_NOT_FOUND",
    "LOAD_SUCCESS",
    "LOAD_UNDEFINED",
    "ROS1_MAX_CELLS",
    "ROS1_MAX_MESSAGE_BYTES",
    "MapLoadError",
    "Pose",
    "ServedMap",
    "check_ros1_size",
    "grid_message",
    "map_poses",
    "metadata_message",
    "packed_response",
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


def check_ros1_size(width: int, height: int, source: str = "") -> None:
    """Refuse a grid too large for a ROS 1 ``nav_msgs/OccupancyGrid`` (before it is made).

    Raises:
        MapLoadError: (code 2, invalid map data) naming the limit and where it bites.
    """
    cells = int(width) * int(height)
    if cells > ROS1_MAX_CELLS:
        where = f"{source}: " if source else ""
        raise MapLoadError(
            f"{where}a {width} x {height} grid ({cells:,} cells) is too large for ROS 1: a "
            f"nav_msgs/OccupancyGrid carries one byte a cell, and every roscpp node (rviz, "
            f"move_base, amcl) drops messages over {ROS1_MAX_MESSAGE_BYTES:,} bytes, so at most "
            f"{ROS1_MAX_CELLS:,} cells; use a coarser --resolution (the files `mapkit rasterize` "
            f"writes have no such limit)",
            LOAD_INVALID_DATA,
        )


def _keepout(m: MapData, grid: OccupancyGrid) -> OccupancyGrid:
    """The keepout mask on the grid, made band by band into one int8 array."""
    from mapkit.raster.masks import keepout_bands

    data = np.empty((grid.height, grid.width), dtype=np.int8)
    for r0, band in keepout_bands(m, grid):
        data[r0 : r0 + len(band)] = band
    data.flags.writeable = False
    return OccupancyGrid(data, grid.resolution, grid.origin)


def served_map(
    path: str | os.PathLike[str], resolution: float = 0.05, *, progress: Any = None, **raster: Any
) -> ServedMap:
    """Load a file for serving: an ARIA ``.map`` (rasterised) or a map_server YAML.

    Args:
        path: ``.map`` file, or ``.yaml``/``.yml`` map_server description; a ``file://`` URL
            (as ``change_map`` requests carry) is accepted too.
        resolution: Metres per cell for a ``.map`` (a YAML carries its own).
        progress: Called as ``progress(rows, total)`` with rows of work just finished.
        **raster: More options for :func:`mapkit.raster.rasterize.rasterize` (``free``,
            ``margin_m``, ``inflate_mm`` ...).

    Returns:
        The map, ready to publish.

    Raises:
        MapLoadError: With code 1 when the file does not exist, 2 when it is not a valid map or
            its grid is too large for a ROS 1 message (checked before rasterising, see
            :func:`check_ros1_size`), 3 when the resolution (or YAML metadata) is invalid, 255
            otherwise.
    """
    from mapkit.formats.map import loads
    from mapkit.raster.bands import BandRaster

    text = os.fspath(path)
    if text.startswith("file://"):
        text = text[len("file://") :]
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
        grid, yaw = _read_yaml_grid(p, progress)
        return ServedMap(str(p), grid, None, (), (), (), sha256, md5, yaw)
    if not (math.isfinite(resolution) and resolution > 0):
        raise MapLoadError(
            f"resolution must be a positive number of metres, got {resolution!r}",
            LOAD_INVALID_METADATA,
        )
    try:
        m = loads(data, source=str(p))
    except FormatError as err:
        raise MapLoadError(str(err), LOAD_INVALID_DATA) from err
    try:
        bands = BandRaster(m, resolution, **raster)
    except (MapkitError, ValueError) as err:
        raise MapLoadError(f"{p}: {err}", LOAD_INVALID_METADATA) from err
    check_ros1_size(bands.grid.width, bands.grid.height, str(p))
    grid = bands.to_grid(
        None
        if progress is None
        else lambda rows: progress(rows, bands.work_rows + bands.grid.height)
    )
    goals, homes, docks = map_poses(m)
    keepout = _keepout(m, grid)
    if progress is not None:
        progress(grid.height, bands.work_rows + grid.height)
    return ServedMap(str(p), grid, keepout, goals, homes, docks, sha256, md5)


def _read_yaml_grid(p: Path, progress: Any = None) -> tuple[OccupancyGrid, float]:
    from mapkit.raster.image_stream import pgm_bands
    from mapkit.raster.ros import read_ros_map, read_ros_yaml
    from mapkit.raster.ros_image import image_size

    try:
        info = read_ros_yaml(p)
        size = image_size(info.image_path)
        if size is not None:
            check_ros1_size(*size, source=str(info.image_path))
        pgm = pgm_bands(info)  # an 8-bit PGM is read a band at a time
        grid = pgm.to_grid() if pgm is not None else read_ros_map(p)
        if progress is not None:
            progress(grid.height, grid.height)
        return grid, info.origin[2]
    except FormatError as err:
        # A YAML that map_server would not accept is bad metadata; a bad image is bad data.
        code = (
            LOAD_INVALID_METADATA
            if str(err.source).lower().endswith((".yaml", ".yml"))
            else LOAD_INVALID_DATA
        )
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


def _cells_of(msg: Any) -> Any:
    return msg.__dict__.get("mapkit_cells")


def _serialize_packed(msg: Any, grid_msg: Any, tail: int, parent: Any, buff: Any) -> None:
    """``parent.serialize`` of ``msg`` with ``grid_msg.data`` written from its packed cells.

    The message is serialised with empty data (its uint32 length 0 sits ``tail`` bytes before
    the end: the fields after ``data``), then the length and the cells' bytes are put there.
    """
    cells = _cells_of(grid_msg)
    if cells is None:
        parent.serialize(msg, buff)
        return
    tmp = io.BytesIO()
    parent.serialize(msg, tmp)
    raw = tmp.getvalue()
    cut = len(raw) - tail - 4
    buff.write(raw[:cut])
    buff.write(struct.pack("<I", cells.nbytes))
    buff.write(cells.data)
    buff.write(raw[cut + 4 :])


_PACKED: dict[str, Any] = {}


def _packed_grid_class() -> Any:
    cls = _PACKED.get("grid")
    if cls is None:
        base = ros_import("nav_msgs.msg").OccupancyGrid

        class PackedOccupancyGrid(base):  # type: ignore[misc, valid-type]
            """``nav_msgs/OccupancyGrid`` whose cells are serialised from a numpy int8 array."""

            def serialize(self, buff: Any) -> None:
                _serialize_packed(self, self, 0, base, buff)

        cls = _PACKED["grid"] = PackedOccupancyGrid
    return cls


def packed_response(kind: str, grid_msg: Any, **fields: Any) -> Any:
    """A ``nav_msgs`` ``GetMap`` or ``LoadMap`` response carrying :func:`grid_message`'s cells.

    rospy's generated response classes serialise the map's ``int8[]`` field inline, through a
    Python list; this subclass writes the packed cells instead (the same bytes on the wire).

    Args:
        kind: ``"GetMap"`` or ``"LoadMap"``.
        grid_msg: The map, from :func:`grid_message`.
        **fields: Other fields (``result`` for ``LoadMap``).
    """
    cls = _PACKED.get(kind)
    if cls is None:
        base = getattr(ros_import("nav_msgs.srv"), f"{kind}Response")
        tail = 1 if kind == "LoadMap" else 0  # LoadMap's uint8 result follows the map

        class PackedResponse(base):  # type: ignore[misc, valid-type]
            def serialize(self, buff: Any) -> None:
                _serialize_packed(self, self.map, tail, base, buff)

        cls = _PACKED[kind] = PackedResponse
    return cls(map=grid_msg, **fields)


def grid_message(
    grid: OccupancyGrid,
    frame_id: str = "map",
    stamp: Any = None,
    load_time: Any = None,
    yaw: float = 0.0,
) -> Any:
    """A ``nav_msgs/OccupancyGrid`` for a grid: row-major from the southern row, int8 cells.

    The cells stay in the grid's numpy array (``msg.mapkit_cells``; ``msg.data`` is empty) and
    are written straight into the serialised message: no Python list of one object a cell, so
    a map of hundreds of millions of cells is published in about its own size of memory.
    """
    msg = _packed_grid_class()()
    _header(msg, frame_id, stamp)
    _info(msg.info, grid, load_time, yaw)
    msg.mapkit_cells = np.ascontiguousarray(grid.data, dtype=np.int8).reshape(-1)
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
