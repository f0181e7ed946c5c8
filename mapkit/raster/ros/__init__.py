"""ROS map_server / Nav2 maps: a YAML file and an image, written and read as map_server does.

Writing (:func:`write_ros_map`) follows map_saver: ``trinary`` images hold free 254, occupied 0 and
unknown 205; rows are flipped so north is up (the image's bottom row is the grid's row 0); PGM
(``P5``) by default, 8-bit grey PNG on request; the YAML has ``image``, ``mode``, ``resolution``,
``origin`` (x, y, yaw of the lower-left pixel), ``negate`` (0 or 1, an integer as map_server
needs), ``occupied_thresh`` and ``free_thresh``. Every pixel value is chosen so that both ROS 1's
map_server and Nav2's map_server read back the intended cell (checked against their loader rules
at write time): ``raw`` images hold the cell value itself (255 for unknown); ``scale`` images hold
the grey level each loader maps closest to the cell value, and unknown cells as transparent
pixels (so ``scale`` with unknown cells needs PNG, as in Nav2's map_saver).

Reading (:func:`read_ros_map`) implements the loaders' documented rules for any YAML and image
(any mode, negate, thresholds; PGM P2/P5/P1/P4/P3/P6 natively, PNG and other formats through
Pillow): ``flavor="ros1"`` for ROS 1 map_server (SDL_image: channel mean, negate, strict
thresholds, ``1 + 98 * ratio`` truncated in scale mode, raw bytes wrapped into int8) and
``flavor="nav2"`` for Nav2 (GraphicsMagick: ``rint(100 * ratio)`` in scale mode, raw values
outside 0..100 unknown, negate ignored in raw mode).

Examples:
    >>> import numpy as np, tempfile, pathlib
    >>> from mapkit.raster.grid import OccupancyGrid
    >>> g = OccupancyGrid(np.array([[0, 100, -1]], dtype=np.int8), 0.05, (-1.0, 2.0))
    >>> out = pathlib.Path(tempfile.mkdtemp()) / "room.yaml"
    >>> files = write_ros_map(g, out)
    >>> print(out.read_text(), end="")
    image: room.pgm
    mode: trinary
    resolution: 0.05
    origin: [-1.0, 2.0, 0.0]
    negate: 0
    occupied_thresh: 0.65
    free_thresh: 0.196
    >>> files.image.read_bytes()[-3:]
    b'\\xfe\\x00\\xcd'
    >>> read_ros_map(out) == g
    True
"""

from __future__ import annotations

from mapkit.raster.ros.common import (
    DEFAULT_FREE_THRESH,
    DEFAULT_OCCUPIED_THRESH,
    MODES,
    SAVER_FREE as SAVER_FREE,
    SAVER_OCCUPIED as SAVER_OCCUPIED,
    SAVER_UNKNOWN as SAVER_UNKNOWN,
    Flavor,
    Mode,
    log_ as log_,
)
from mapkit.raster.ros.images import (
    check_scale,
    grid_to_image,
    pixel_table,
    write_image,
)
from mapkit.raster.ros.pixels import (
    load_pixel_values,
)
from mapkit.raster.ros.reader import (
    image_to_grid,
    open_map_image,
    pixel_values,
    read_image,
    read_ros_map,
)
from mapkit.raster.ros.writer import (
    RosMapFiles,
    image_target,
    pgm_comment,
    write_map_yaml,
    write_ros_map,
    yaml_text,
)
from mapkit.raster.ros.yaml_read import (
    MAX_YAML_BYTES as MAX_YAML_BYTES,
    MAX_YAML_DEPTH as MAX_YAML_DEPTH,
    MAX_YAML_NODES as MAX_YAML_NODES,
    RosMapInfo,
    read_ros_yaml,
)

__all__ = [
    "DEFAULT_FREE_THRESH",
    "DEFAULT_OCCUPIED_THRESH",
    "MODES",
    "Flavor",
    "Mode",
    "RosMapFiles",
    "RosMapInfo",
    "check_scale",
    "grid_to_image",
    "image_target",
    "image_to_grid",
    "load_pixel_values",
    "open_map_image",
    "pgm_comment",
    "pixel_table",
    "pixel_values",
    "read_image",
    "read_ros_map",
    "read_ros_yaml",
    "write_image",
    "write_map_yaml",
    "write_ros_map",
    "yaml_text",
]
