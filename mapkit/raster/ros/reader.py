"""Reading a ROS map's image into an occupancy grid, as map_server or nav2_map_server would."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from mapkit._typing import PathLike
from mapkit.raster.errors import RosMapError
from mapkit.raster.grid import OccupancyGrid
from mapkit.raster.ros.common import Flavor
from mapkit.raster.ros.pixels import load_pixel_values
from mapkit.raster.ros.yaml_read import RosMapInfo, read_ros_yaml
from mapkit.raster.ros_image import ImageSource, _Image, open_image

__all__ = ["image_to_grid", "open_map_image", "pixel_values", "read_image", "read_ros_map"]


def pixel_values(img: _Image, info: RosMapInfo, *, flavor: Flavor = "ros1") -> NDArray[np.int8]:
    """Cell values of decoded pixels under a YAML's settings, by the loader's rules.

    Works pixel by pixel, so a band of rows gives the same values as the whole image does.

    Returns:
        int8 ``(h, w)`` in the image's row order (first row at the top).
    """
    ch = img.channels
    kw: dict[str, Any] = {
        "negate": bool(info.negate),
        "occupied_thresh": info.occupied_thresh,
        "free_thresh": info.free_thresh,
        "flavor": flavor,
    }
    if flavor == "ros1":
        data8 = (
            ch if ch.dtype == np.uint8 else (ch >> 8).astype(np.uint8)
        )  # libpng strips to 8 bits
        if img.maxval < 255 and not img.bilevel:
            data8 = (ch.astype(np.int64) * 255 // img.maxval).astype(np.uint8)  # SDL rescales
        n = data8.shape[2]
        avg_n = n if (info.mode == "trinary" or not img.has_alpha) else n - 1
        alpha = None if n == 1 else data8[..., n - 1]
        if avg_n == 1 and n == 1:
            lut = load_pixel_values(np.arange(256), info.mode, **kw)
            values: NDArray[np.int8] = lut[data8[..., 0]]
            return values
        grey = data8[..., :avg_n].sum(axis=2, dtype=np.int64) / avg_n
        return load_pixel_values(grey, info.mode, alpha=alpha, **kw)
    full = img.maxval
    rgb: NDArray[Any]
    alpha_ch: NDArray[Any] | None = None
    if img.palette_rgba is not None:
        rgb = img.palette_rgba[..., :3]
        if (img.palette_rgba[..., 3] < 255).any():
            alpha_ch = img.palette_rgba[..., 3]
    elif ch.shape[2] == 1:
        rgb = ch
    else:
        rgb = ch[..., :3]
        if img.has_alpha:
            alpha_ch = ch[..., 3]
    if img.bilevel == "pbm":
        rgb = (1 - rgb.astype(np.int64)) * 255
    elif img.bilevel == "png":
        rgb = rgb.astype(np.int64) * 255
    grey = rgb.astype(np.float64).mean(axis=2) if rgb.shape[2] > 1 else rgb[..., 0]
    if info.mode == "trinary" and alpha_ch is not None:
        grey = (rgb.astype(np.float64).sum(axis=2) + alpha_ch) / 4.0
    return load_pixel_values(grey, info.mode, alpha=alpha_ch, maxval=full, **kw)


def image_to_grid(img: _Image, info: RosMapInfo, *, flavor: Flavor = "ros1") -> OccupancyGrid:
    """The grid of a decoded image under a YAML's settings (rows flipped: north up in files)."""
    data = np.ascontiguousarray(pixel_values(img, info, flavor=flavor)[::-1])
    return OccupancyGrid(data, info.resolution, (info.origin[0], info.origin[1]))


def read_image(path: PathLike) -> _Image:
    """Decode a whole image file (PNM natively, anything else through Pillow).

    Raises:
        RosMapError: Naming the file, for anything that is not a readable image.
    """
    return open_image(Path(os.fspath(path))).read_all()


def open_map_image(info: RosMapInfo, *, flavor: Flavor = "ros1") -> ImageSource:
    """Open a YAML's image as the flavor's map_server would (header checks only).

    Raises:
        RosMapError: For an image the loader refuses (ROS 1: PGM deeper than 8 bits).
    """
    src = open_image(info.image_path)
    if flavor == "ros1" and src.pnm and src.maxval > 255:
        raise RosMapError(
            f"16-bit PGM images (maxval {src.maxval}) fail to load in ROS 1 "
            "map_server; use 8-bit (or --flavor nav2)",
            source=str(info.image_path),
        )
    return src


def read_ros_map(path: PathLike, *, flavor: Flavor = "ros1") -> OccupancyGrid:
    """Read a map_server map (YAML + image) into the grid map_server would publish.

    The grid's ``resolution`` is the YAML's value as a double (map_server's message holds it as
    float32); the origin's yaw is not part of the grid (see :func:`read_ros_yaml`).

    Args:
        path: The YAML file.
        flavor: ``ros1`` (map_server 1.17, the default) or ``nav2``.

    Raises:
        RosMapError: For what map_server would refuse, naming the file (and line).
    """
    info = read_ros_yaml(path, flavor=flavor)
    return image_to_grid(open_map_image(info, flavor=flavor).read_all(), info, flavor=flavor)
