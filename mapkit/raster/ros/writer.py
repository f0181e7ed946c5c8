"""Writing a ROS map: the YAML beside its image, as map_saver writes them."""

from __future__ import annotations

import json
import os
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from mapkit._atomic import atomic_write
from mapkit._typing import PathLike
from mapkit.raster.errors import RasterError
from mapkit.raster.grid import OccupancyGrid
from mapkit.raster.ros.common import DEFAULT_FREE_THRESH, DEFAULT_OCCUPIED_THRESH, Mode
from mapkit.raster.ros.images import grid_to_image, write_image

__all__ = [
    "RosMapFiles",
    "image_target",
    "pgm_comment",
    "write_map_yaml",
    "write_ros_map",
    "yaml_text",
]


def _fmt_float(v: float) -> str:
    """Shortest round-trip text that both YAML 1.1 (PyYAML) and yaml-cpp read as a float."""
    text = repr(float(v) + 0.0)
    if "e" in text and "." not in text:
        mant, exp = text.split("e")
        text = f"{mant}.0e{exp}"
    elif "." not in text and "e" not in text and text not in ("inf", "-inf", "nan"):
        text += ".0"
    return text


_PLAIN = re.compile(r"^[A-Za-z0-9_./][A-Za-z0-9_./+@-]*$")


def _yaml_str(s: str) -> str:
    return (
        s
        if _PLAIN.match(s) and s.lower() not in ("true", "false", "null", "yes", "no", "on", "off")
        else json.dumps(s, ensure_ascii=False)
    )


def yaml_text(
    image: str,
    grid: OccupancyGrid,
    *,
    mode: str = "trinary",
    negate: bool = False,
    occupied_thresh: float = DEFAULT_OCCUPIED_THRESH,
    free_thresh: float = DEFAULT_FREE_THRESH,
    yaw: float = 0.0,
) -> str:
    """The map YAML text, in Nav2 map_saver's key order, every value as map_server parses it.

    Examples:
        >>> import numpy as np
        >>> g = OccupancyGrid(np.zeros((1, 1)), 0.025, (-12.5, 3.0))
        >>> print(yaml_text("my map.pgm", g, mode="raw"), end="")
        image: "my map.pgm"
        mode: raw
        resolution: 0.025
        origin: [-12.5, 3.0, 0.0]
        negate: 0
        occupied_thresh: 0.65
        free_thresh: 0.196
    """
    ox, oy = grid.origin
    return (
        f"image: {_yaml_str(image)}\n"
        f"mode: {mode}\n"
        f"resolution: {_fmt_float(grid.resolution)}\n"
        f"origin: [{_fmt_float(ox)}, {_fmt_float(oy)}, {_fmt_float(yaw)}]\n"
        f"negate: {1 if negate else 0}\n"
        f"occupied_thresh: {_fmt_float(occupied_thresh)}\n"
        f"free_thresh: {_fmt_float(free_thresh)}\n"
    )


@dataclass(frozen=True, slots=True)
class RosMapFiles:
    """The files :func:`write_ros_map` wrote."""

    yaml: Path
    image: Path


def write_ros_map(
    grid: OccupancyGrid,
    yaml_path: PathLike,
    *,
    mode: Mode = "trinary",
    image_format: str | None = None,
    image_path: PathLike | None = None,
    negate: bool = False,
    occupied_thresh: float = DEFAULT_OCCUPIED_THRESH,
    free_thresh: float = DEFAULT_FREE_THRESH,
) -> RosMapFiles:
    """Write a grid as a map_server map: the image, then the YAML that names it (both atomic).

    Args:
        grid: The grid.
        yaml_path: The YAML file (``NAME.yaml``).
        mode: ``trinary`` (default), ``scale`` or ``raw``.
        image_format: ``pgm`` (default) or ``png``. ``scale`` mode defaults to PNG, as Nav2's
            map_saver does: its unknown cells need transparent pixels.
        image_path: The image file; default ``NAME.pgm``/``NAME.png`` beside the YAML. The YAML
            names it relative to its own folder when it is inside it, else by absolute path.
        negate: Write inverted grey levels and ``negate: 1``.
        occupied_thresh: ``occupied_thresh`` for the YAML (the pixels are chosen to match).
        free_thresh: ``free_thresh`` for the YAML.

    Returns:
        The paths written.

    Raises:
        RasterError: For a bad mode, format or thresholds, or unknown cells in a ``scale`` PGM.
    """
    yaml_p = Path(os.fspath(yaml_path))
    grey, alpha = grid_to_image(
        grid, mode, negate=negate, occupied_thresh=occupied_thresh, free_thresh=free_thresh
    )
    img_p, fmt = image_target(yaml_p, mode, image_format, image_path)
    if alpha is not None and fmt == "pgm":
        raise RasterError("scale mode with unknown cells needs transparency: write PNG, not PGM")
    write_image(img_p, grey, alpha, image_format=fmt, comment=pgm_comment(grid))
    write_map_yaml(
        yaml_p,
        img_p,
        grid,
        mode=mode,
        negate=negate,
        occupied_thresh=occupied_thresh,
        free_thresh=free_thresh,
    )
    return RosMapFiles(yaml_p, img_p)


def pgm_comment(grid: OccupancyGrid) -> str:
    """The PGM header comment mapkit writes (map_saver's, with mapkit as creator)."""
    return f"CREATOR: mapkit {grid.resolution:.3f} m/pix"


def image_target(
    yaml_p: Path, mode: str, image_format: str | None, image_path: PathLike | None
) -> tuple[Path, str]:
    """The image file and format :func:`write_ros_map` writes for these options.

    Raises:
        RasterError: For a format other than PGM or PNG, or an image path that is the YAML's.
    """
    if image_path is not None:
        img_p = Path(os.fspath(image_path))
        fmt = image_format or ("png" if img_p.suffix.lower() == ".png" else "pgm")
    else:
        fmt = image_format or ("png" if mode == "scale" else "pgm")
        img_p = yaml_p.with_suffix("." + fmt.lower())
    fmt = fmt.lower()
    if fmt not in ("pgm", "png"):
        raise RasterError(f"image format must be pgm or png, got {image_format!r}")
    if img_p.resolve() == yaml_p.resolve():
        raise RasterError(f"{yaml_p}: the image and the YAML would be the same file")
    return img_p, fmt


def write_map_yaml(yaml_p: Path, img_p: Path, grid: OccupancyGrid, **settings: Any) -> None:
    """Write the YAML naming ``img_p`` (relative to the YAML's folder when inside it), atomically.

    ``settings`` are :func:`yaml_text`'s (``mode``, ``negate``, thresholds).
    """
    try:
        rel = os.path.relpath(img_p.resolve(), yaml_p.resolve().parent)
    except ValueError:  # other drive (Windows)
        rel = str(img_p.resolve())
    name = rel if not rel.startswith("..") else str(img_p.resolve())
    text = yaml_text(name.replace(os.sep, "/"), grid, **settings)
    atomic_write(yaml_p, text.encode("utf-8"))
