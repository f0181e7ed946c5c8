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

import json
import logging
import math
import os
import re
import struct
import zlib
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from mapkit._atomic import atomic_write
from mapkit._typing import PathLike
from mapkit.raster.errors import RasterError, RosMapError
from mapkit.raster.grid import OccupancyGrid
from mapkit.raster.ros_image import ImageSource, _Image, open_image

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

Mode = Literal["trinary", "scale", "raw"]
Flavor = Literal["ros1", "nav2"]
MODES: tuple[str, ...] = ("trinary", "scale", "raw")
DEFAULT_OCCUPIED_THRESH = 0.65
DEFAULT_FREE_THRESH = 0.196

log_ = logging.getLogger(__name__)

#: map_saver's grey levels.
SAVER_FREE, SAVER_OCCUPIED, SAVER_UNKNOWN = 254, 0, 205


# -- what the loaders make of a pixel ------------------------------------------------------------


def load_pixel_values(
    grey: NDArray[Any],
    mode: str,
    *,
    negate: bool = False,
    occupied_thresh: float = DEFAULT_OCCUPIED_THRESH,
    free_thresh: float = DEFAULT_FREE_THRESH,
    alpha: NDArray[Any] | None = None,
    flavor: Flavor = "ros1",
    maxval: int = 255,
) -> NDArray[np.int8]:
    """The cell values a map_server gives pixels, by its documented rules (vectorised).

    Args:
        grey: The pixels' channel means (0..``maxval``, may be fractional for colour images).
            For ``ros1`` this is SDL's mean over the averaged channels; for ``nav2`` the mean of
            the colour channels (and, in trinary mode, the alpha channel, as Nav2 does).
        mode: ``trinary``, ``scale`` or ``raw``.
        negate: The YAML's ``negate``.
        occupied_thresh: The YAML's ``occupied_thresh``.
        free_thresh: The YAML's ``free_thresh``.
        alpha: Opacity per pixel (0..``maxval``; ``None`` = opaque). ROS 1 treats a pixel as
            unknown in scale mode when its alpha byte is 0; Nav2 when it is not fully opaque.
        flavor: ``ros1`` (map_server 1.17) or ``nav2`` (nav2_map_server).
        maxval: Full scale of ``grey`` and ``alpha`` (255, or 65535 for 16-bit images in Nav2).

    Returns:
        int8 cell values, same shape as ``grey``.

    Examples:
        >>> load_pixel_values(np.array([0, 89, 90, 205, 206, 254]), "trinary").tolist()
        [100, 100, -1, -1, 0, 0]
        >>> load_pixel_values(np.array([255, 205, 100]), "raw").tolist()
        [-1, -51, 100]
        >>> load_pixel_values(np.array([255, 205, 100]), "raw", flavor="nav2").tolist()
        [-1, -1, 100]
    """
    g = np.asarray(grey, dtype=np.float64)
    full = float(maxval)
    if flavor == "ros1":
        avg = full - g if negate else g
        if mode == "raw":
            return np.trunc(avg).astype(np.int64).astype(np.uint8).view(np.int8)
        occ = (full - avg) / full
    elif flavor == "nav2":
        shade = g / full
        if mode == "raw":
            pct = np.floor(shade * 255.0 + 0.5)  # std::round (values are >= 0)
            out = np.where((pct >= 0) & (pct <= 100), pct, -1)
            return out.astype(np.int8)
        occ = shade if negate else 1.0 - shade
    else:
        raise RasterError(f"flavor must be ros1 or nav2, got {flavor!r}")
    out = np.full(g.shape, -1, dtype=np.int8)
    occupied = occ > occupied_thresh
    free = occ < free_thresh
    out[occupied] = 100
    out[free & ~occupied] = 0
    if mode == "trinary":
        return out
    if mode != "scale":
        raise RasterError(f"mode must be one of {', '.join(MODES)}, got {mode!r}")
    between = ~occupied & ~free
    if alpha is not None:
        a = np.asarray(alpha, dtype=np.float64)
        opaque = (a >= 1.0) if flavor == "ros1" else (a >= full)
        between &= opaque
        if flavor == "nav2":
            out[~opaque] = -1
    if not between.any():
        return out
    if occupied_thresh == free_thresh:
        raise RasterError("scale mode divides by occupied_thresh - free_thresh, which is 0")
    ratio = (occ[between] - free_thresh) / (occupied_thresh - free_thresh)
    val = np.trunc(1.0 + 98.0 * ratio) if flavor == "ros1" else np.rint(ratio * 100.0)
    out[between] = val.astype(np.int64).astype(np.uint8).view(np.int8)
    return out


# -- writing -------------------------------------------------------------------------------------


def _check_thresholds(occupied_thresh: float, free_thresh: float) -> None:
    if not (0.0 <= free_thresh < occupied_thresh <= 1.0):
        raise RasterError(
            f"thresholds must satisfy 0 <= free_thresh < occupied_thresh <= 1, got free "
            f"{free_thresh!r}, occupied {occupied_thresh!r}"
        )


def _pixel_lut(
    mode: str, negate: bool, occupied_thresh: float, free_thresh: float
) -> tuple[NDArray[np.uint8], NDArray[np.bool_]]:
    """Grey level (and opacity) to write for each int8 cell value, indexed by ``value & 0xFF``."""
    levels = np.arange(256)
    lut = np.zeros(256, dtype=np.uint8)
    opaque = np.ones(256, dtype=bool)
    values = levels.astype(np.uint8).view(np.int8).astype(np.int64)  # index -> cell value
    if mode == "raw":
        return levels.astype(np.uint8), opaque
    kw: dict[str, Any] = {
        "negate": negate,
        "occupied_thresh": occupied_thresh,
        "free_thresh": free_thresh,
    }
    # What each grey level reads back as, in both loaders (grey as written, before negate).
    ros1 = load_pixel_values(levels, mode, flavor="ros1", **kw).astype(np.int64)
    nav2 = load_pixel_values(levels, mode, flavor="nav2", **kw).astype(np.int64)

    def pick(want: int, preferred: int) -> int:
        pref = 255 - preferred if negate else preferred
        both = np.flatnonzero((ros1 == want) & (nav2 == want))
        if len(both):
            return int(both[np.argmin(np.abs(both - pref))])
        # Scale mode: the level each loader reads closest to the value (ROS 1 first).
        cost = np.abs(ros1 - want) * 1000 + np.abs(nav2 - want) * 10 + np.abs(levels - pref) / 1000
        cost[(ros1 < 0) | (nav2 < 0)] = np.inf
        if not np.isfinite(cost).any():
            raise RasterError(f"no grey level reads back as {want} with these thresholds")
        return int(np.argmin(cost))

    free_px = pick(0, SAVER_FREE)
    occ_px = pick(100, SAVER_OCCUPIED)
    if mode == "trinary":
        unk = np.flatnonzero((ros1 == -1) & (nav2 == -1))
        if not len(unk):
            raise RasterError(
                f"thresholds free {free_thresh} / occupied {occupied_thresh} leave no grey level "
                "that map_server reads as unknown"
            )
        pref = 255 - SAVER_UNKNOWN if negate else SAVER_UNKNOWN
        unk_px = int(unk[np.argmin(np.abs(unk - pref))])
        # map_saver's rule for in-between values: <= free -> free, >= occupied -> occupied.
        free_int, occ_int = round(free_thresh * 100), round(occupied_thresh * 100)
        lut[:] = unk_px
        lut[(values >= 0) & (values <= free_int)] = free_px
        lut[(values >= occ_int) & (values <= 100)] = occ_px
        return lut, opaque
    # scale
    table = np.array([pick(v, round(255 * (100 - v) / 100)) for v in range(101)], dtype=np.uint8)
    table[0], table[100] = free_px, occ_px
    inside = (values >= 0) & (values <= 100)
    lut[inside] = table[values[inside]]
    # Unknown cells are transparent. ROS 1 checks the thresholds before the alpha, so the grey
    # level under a transparent pixel must lie between them (Nav2 reads any transparent pixel
    # as unknown): the level nearest map_saver's 205 that ROS 1 reads as unknown when clear.
    clear = load_pixel_values(levels, "scale", alpha=np.zeros(256), flavor="ros1", **kw)
    unk = np.flatnonzero(clear == -1)
    pref = 255 - SAVER_UNKNOWN if negate else SAVER_UNKNOWN
    lut[~inside] = unk[np.argmin(np.abs(unk - pref))] if len(unk) else pref
    opaque[~inside] = False
    return lut, opaque


def pixel_table(
    mode: str,
    negate: bool = False,
    occupied_thresh: float = DEFAULT_OCCUPIED_THRESH,
    free_thresh: float = DEFAULT_FREE_THRESH,
) -> tuple[NDArray[np.uint8], NDArray[np.bool_]]:
    """Grey level and opacity written for each cell value (index ``value & 0xFF``), checked.

    The table :func:`grid_to_image` applies; the streamed writer applies it band by band.

    Raises:
        RasterError: For a bad mode or thresholds, or ``negate`` in raw mode.
    """
    if mode not in MODES:
        raise RasterError(f"mode must be one of {', '.join(MODES)}, got {mode!r}")
    _check_thresholds(occupied_thresh, free_thresh)
    if mode == "raw" and negate:
        raise RasterError("negate is not supported in raw mode (Nav2 ignores it, ROS 1 applies it)")
    return _pixel_lut(mode, negate, occupied_thresh, free_thresh)


def check_scale(
    counts: NDArray[np.int64],
    lut: NDArray[np.uint8],
    negate: bool,
    occupied_thresh: float,
    free_thresh: float,
) -> None:
    """Refuse unknown cells no grey level keeps unknown; warn for values the thresholds squash.

    ``counts`` is the number of cells of each value, indexed by ``value & 0xFF`` (256 entries):
    the whole grid at once, or summed band by band.

    Raises:
        RasterError: When the grid has unknown cells and no grey level lies between the
            thresholds (ROS 1 would read them as free or occupied).
    """
    kw: dict[str, Any] = {
        "negate": negate,
        "occupied_thresh": occupied_thresh,
        "free_thresh": free_thresh,
    }
    values = np.arange(256).astype(np.uint8).view(np.int8).astype(np.int64)
    unknown = int(counts[(values < 0) | (values > 100)].sum())
    pending = f"thresholds free {free_thresh!r} / occupied {occupied_thresh!r}"
    if unknown:
        clear = load_pixel_values(
            lut.astype(np.int64), "scale", alpha=np.zeros(256), flavor="ros1", **kw
        )
        if ((clear != -1) & ((values < 0) | (values > 100))).any():
            raise RasterError(
                f"scale mode with {pending} leaves no grey level between them: ROS 1 map_server "
                f"would read the {unknown:,} unknown cells as free or occupied; widen the "
                "thresholds or use trinary mode"
            )
    present = np.flatnonzero(counts[:101])
    back = load_pixel_values(lut[present].astype(np.int64), "scale", flavor="ros1", **kw).astype(
        np.int64
    )
    off = np.abs(back - present)
    squashed = off > 1  # one grey level per value at best: 1 off is rounding, more is loss
    if squashed.any():
        log_.warning(
            "scale mode with %s: %d of the %d cell values in this grid read back more "
            "than 1 off in ROS 1 map_server (up to %d off); widen the thresholds to keep "
            "them",
            pending,
            int(squashed.sum()),
            len(present),
            int(off.max()),
        )


def grid_to_image(
    grid: OccupancyGrid,
    mode: Mode = "trinary",
    *,
    negate: bool = False,
    occupied_thresh: float = DEFAULT_OCCUPIED_THRESH,
    free_thresh: float = DEFAULT_FREE_THRESH,
) -> tuple[NDArray[np.uint8], NDArray[np.uint8] | None]:
    """The grey image (north up) and, in scale mode with unknown cells, its alpha channel.

    Args:
        grid: The grid.
        mode: ``trinary`` (map_saver's 254/0/205), ``scale`` or ``raw`` (the cell value as grey
            level, 255 for unknown).
        negate: Invert the grey levels (the YAML then says ``negate: 1``).
        occupied_thresh: The threshold the YAML will give.
        free_thresh: The threshold the YAML will give.

    Returns:
        ``(grey, alpha)``: ``(height, width)`` uint8 arrays; ``alpha`` is ``None`` unless needed.

    Raises:
        RasterError: For a bad mode or thresholds, or ``negate`` in raw mode (Nav2 ignores it).

    Examples:
        >>> g = OccupancyGrid(np.array([[0, 100], [-1, 0]], dtype=np.int8), 0.1, (0, 0))
        >>> grid_to_image(g)[0].tolist()   # north (row 1) first
        [[205, 254], [254, 0]]
    """
    lut, opaque = pixel_table(mode, negate, occupied_thresh, free_thresh)
    if mode == "scale":
        check_scale(
            np.bincount(grid.data.view(np.uint8).ravel(), minlength=256),
            lut,
            negate,
            occupied_thresh,
            free_thresh,
        )
    idx = grid.data[::-1].view(np.uint8)
    grey = lut[idx]
    alpha = None
    if mode == "scale" and not opaque.all():
        transparent = ~opaque[idx]
        if transparent.any():
            alpha = np.where(transparent, 0, 255).astype(np.uint8)
    return grey, alpha


def _pgm_bytes(grey: NDArray[np.uint8], comment: str) -> bytes:
    h, w = grey.shape
    header = f"P5\n# {comment}\n{w} {h}\n255\n".encode("ascii")
    return header + np.ascontiguousarray(grey).tobytes()


def _png_chunk(kind: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))


def _png_bytes(grey: NDArray[np.uint8], alpha: NDArray[np.uint8] | None, level: int = 6) -> bytes:
    h, w = grey.shape
    if alpha is None:
        pix, color_type, bpp = grey, 0, 1
    else:
        pix, color_type, bpp = np.stack([grey, alpha], axis=2).reshape(h, w * 2), 4, 2
    raw = np.zeros((h, w * bpp + 1), dtype=np.uint8)  # filter byte 0 ("none") per row
    raw[:, 1:] = pix
    ihdr = struct.pack(">IIBBBBB", w, h, 8, color_type, 0, 0, 0)
    return b"".join(
        [
            b"\x89PNG\r\n\x1a\n",
            _png_chunk(b"IHDR", ihdr),
            _png_chunk(b"IDAT", zlib.compress(raw.tobytes(), level)),
            _png_chunk(b"IEND", b""),
        ]
    )


def write_image(
    path: PathLike,
    grey: NDArray[np.uint8],
    alpha: NDArray[np.uint8] | None = None,
    *,
    image_format: str | None = None,
    comment: str = "CREATOR: mapkit",
) -> None:
    """Write a grey image atomically: PGM ``P5`` or PNG (8-bit grey, grey+alpha when ``alpha``).

    Args:
        path: The file.
        grey: ``(height, width)`` uint8, first row at the top.
        alpha: Optional opacity (PNG only).
        image_format: ``pgm`` or ``png``; by default from the suffix (PGM unless ``.png``).
        comment: The PGM header comment.

    Raises:
        RasterError: For an unknown format, or alpha with PGM.
    """
    fmt = (image_format or ("png" if os.fspath(path).lower().endswith(".png") else "pgm")).lower()
    if fmt == "pgm":
        if alpha is not None:
            raise RasterError(f"{os.fspath(path)}: PGM has no alpha channel; use PNG")
        atomic_write(path, _pgm_bytes(grey, comment))
    elif fmt == "png":
        atomic_write(path, _png_bytes(grey, alpha))
    else:
        raise RasterError(f"image format must be pgm or png, got {image_format!r}")


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


# -- reading -------------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class RosMapInfo:
    """A map YAML as map_server reads it.

    Attributes:
        source: The YAML file.
        image: The ``image`` value as written.
        image_path: The image file (relative names resolved against the YAML's folder).
        resolution: Metres per pixel.
        origin: ``(x, y, yaw)`` of the lower-left pixel.
        negate: 0 or 1.
        occupied_thresh: Occupied threshold.
        free_thresh: Free threshold.
        mode: ``trinary`` (the default when absent), ``scale`` or ``raw``.
    """

    source: Path
    image: str
    image_path: Path
    resolution: float
    origin: tuple[float, float, float]
    negate: int
    occupied_thresh: float
    free_thresh: float
    mode: str


_INT = re.compile(r"[-+]?(?:0[xX][0-9a-fA-F]+|0[0-7]*|[1-9][0-9]*)")
_FLOAT = re.compile(r"[-+]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][-+]?[0-9]+)?")
_SPECIAL_FLOATS = {
    **{s + v: math.inf for s in ("", "+") for v in (".inf", ".Inf", ".INF")},
    **{"-" + v: -math.inf for v in (".inf", ".Inf", ".INF")},
    **{v: math.nan for v in (".nan", ".NaN", ".NAN")},
}
#: Largest map YAML read (a real one is a few hundred bytes).
MAX_YAML_BYTES = 1 << 16
#: Deepest nesting of lists and mappings read (composing recurses once per level).
MAX_YAML_DEPTH = 64
#: Most YAML values read (a real map YAML has about 15); bounds the time composing takes.
MAX_YAML_NODES = 4096


def _as_int(text: str) -> int | None:
    """A 32-bit integer as yaml-cpp reads one (C++ stream, base from the prefix), else ``None``.

    Examples:
        >>> [_as_int(t) for t in ("1", "010", "0x1F", "-0", "09", "1.0", "true", "9" * 5000)]
        [1, 8, 31, 0, None, None, None, None]
    """
    t = text.strip()
    if len(t) > 40 or not _INT.fullmatch(t):  # overflows long before 40 characters
        return None
    body = t.lstrip("+-")
    value = (
        int(body, 16)
        if body[:2] in ("0x", "0X")
        else int(body, 8)
        if body[:1] == "0"
        else int(body)
    )
    value = -value if t.startswith("-") else value
    return value if -(1 << 31) <= value < (1 << 31) else None


def _as_float(text: str) -> float | None:
    """A double as yaml-cpp reads one (``.inf``, ``.nan``; overflow fails), else ``None``.

    Examples:
        >>> [_as_float(t) for t in ("5e-2", "-.inf", "1e309", "0x10", "1" * 5000 + "x")]
        [0.05, -inf, None, None, None]
    """
    t = text.strip()
    if t in _SPECIAL_FLOATS:
        return _SPECIAL_FLOATS[t]
    if not _FLOAT.fullmatch(t):  # linear: no nested or overlapping repeats
        return None
    value = float(t)
    return value if math.isfinite(value) else None  # the C++ stream fails on overflow


def _compose(data: bytes, src: str) -> Any:
    """The YAML node graph (aliases are not expanded; recursion and size are bounded)."""
    import yaml

    loader = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
    try:
        text = data.decode("utf-8-sig")
        depth = nodes = 0
        for event in yaml.parse(text, Loader=loader):  # no recursion: the nesting is bounded
            if isinstance(event, yaml.NodeEvent):
                nodes += 1
                if nodes > MAX_YAML_NODES:
                    raise RosMapError(f"not a map YAML: over {MAX_YAML_NODES:,} values", source=src)
            if isinstance(event, yaml.CollectionStartEvent):
                depth += 1
                if depth > MAX_YAML_DEPTH:
                    mark = event.start_mark
                    raise RosMapError(
                        f"not a map YAML: nested over {MAX_YAML_DEPTH} levels",
                        source=src,
                        line=None if mark is None else mark.line + 1,
                    )
            elif isinstance(event, yaml.CollectionEndEvent):
                depth -= 1
        return yaml.compose(text, Loader=loader)
    except (yaml.YAMLError, UnicodeDecodeError) as err:
        line = getattr(getattr(err, "problem_mark", None), "line", None)
        raise RosMapError(
            f"not valid YAML: {err}".splitlines()[0],
            source=src,
            line=None if line is None else line + 1,
        ) from err


def read_ros_yaml(path: PathLike, *, flavor: Flavor = "ros1") -> RosMapInfo:
    """Read a map YAML by map_server's rules (keys, types, relative image path).

    ``negate`` must be an integer for ROS 1 (Nav2 also takes ``true``/``false``); ``origin`` needs
    at least 3 numbers (exactly 3 for Nav2); ``mode`` is case-sensitive; numbers may be quoted or
    use exponents; extra keys are ignored. Numbers are read as yaml-cpp does (a value the C++
    stream cannot hold, such as ``1e309`` or a 5,000-digit integer, is refused); a key given twice
    and non-finite thresholds are refused (map_server's result would be undefined).

    Raises:
        RosMapError: Naming the file and line of what map_server would reject.
    """
    import yaml

    from mapkit.raster.ros_image import open_regular

    p = Path(os.fspath(path))
    src = str(p)
    with open_regular(p, "map YAML") as fh:
        try:
            text = fh.read(MAX_YAML_BYTES + 1)
        except OSError as err:
            raise RosMapError(f"cannot read: {err.strerror or err}", source=src) from err
    if len(text) > MAX_YAML_BYTES:
        raise RosMapError(f"not a map YAML: larger than {MAX_YAML_BYTES:,} bytes", source=src)
    node = _compose(text, src)
    if not isinstance(node, yaml.MappingNode):
        raise RosMapError(
            "a map YAML is a mapping of keys (image, resolution, origin, ...)", source=src, line=1
        )
    keys: dict[str, Any] = {}
    for k, v in node.value:
        if isinstance(k, yaml.ScalarNode):
            if k.value in keys:
                raise RosMapError(
                    f"key {k.value!r} is given twice (lines "
                    f"{keys[k.value].start_mark.line + 1} and "
                    f"{k.start_mark.line + 1})",
                    source=src,
                    line=k.start_mark.line + 1,
                )
            keys[k.value] = v

    def need(key: str) -> Any:
        if key not in keys:
            raise RosMapError(
                f"missing required key {key!r} (map_server fails with 'bad conversion')", source=src
            )
        return keys[key]

    def scalar(key: str) -> tuple[str, int]:
        v = need(key)
        line = v.start_mark.line + 1
        if not isinstance(v, yaml.ScalarNode):
            raise RosMapError(f"{key} must be a single value", source=src, line=line)
        return v.value, line

    def number(key: str) -> float:
        value, line = scalar(key)
        f = _as_float(value)
        if f is None:
            raise RosMapError(f"{key} must be a number, got {value!r}", source=src, line=line)
        return f

    image, line = scalar("image")
    if not image:
        raise RosMapError("the image tag cannot be an empty string", source=src, line=line)
    resolution = number("resolution")
    if not (math.isfinite(resolution) and resolution > 0):
        raise RosMapError(
            f"resolution must be a positive number, got {resolution!r}",
            source=src,
            line=keys["resolution"].start_mark.line + 1,
        )
    onode = need("origin")
    oline = onode.start_mark.line + 1
    if not isinstance(onode, yaml.SequenceNode):
        raise RosMapError("origin must be a list [x, y, yaw]", source=src, line=oline)
    nums = [_as_float(n.value) if isinstance(n, yaml.ScalarNode) else None for n in onode.value]
    if any(n is None for n in nums):
        raise RosMapError("origin must hold numbers", source=src, line=oline)
    if len(nums) < 3 or (flavor == "nav2" and len(nums) != 3):
        need_n = "exactly 3" if flavor == "nav2" else "at least 3"
        raise RosMapError(
            f"origin needs {need_n} numbers (x, y, yaw), got {len(nums)}", source=src, line=oline
        )
    ox, oy, yaw = (float(n) for n in nums[:3])  # type: ignore[arg-type]
    if not all(math.isfinite(v) for v in (ox, oy, yaw)):
        raise RosMapError("origin must be finite", source=src, line=oline)
    nvalue, nline = scalar("negate")
    negate = _as_int(nvalue)
    if negate is None and flavor == "nav2" and nvalue.strip().lower() in ("true", "false"):
        negate = int(nvalue.strip().lower() == "true")
    if negate is None:
        raise RosMapError(
            f"negate must be an integer 0 or 1, got {nvalue!r} (map_server reads it as an int)",
            source=src,
            line=nline,
        )
    occ = number("occupied_thresh")
    free = number("free_thresh")
    for key, value in (("occupied_thresh", occ), ("free_thresh", free)):
        if not math.isfinite(value):
            raise RosMapError(
                f"{key} must be a finite number, got {value!r} (map_server's result is undefined)",
                source=src,
                line=keys[key].start_mark.line + 1,
            )
    mode = "trinary"
    if "mode" in keys:
        mvalue, mline = scalar("mode")
        if mvalue not in MODES:
            raise RosMapError(
                f"mode must be trinary, scale or raw (case-sensitive), got {mvalue!r}",
                source=src,
                line=mline,
            )
        mode = mvalue
    if mode == "scale" and occ == free:
        raise RosMapError(
            f"scale mode divides by occupied_thresh - free_thresh, which is 0 here ({occ!r})",
            source=src,
            line=keys["free_thresh"].start_mark.line + 1,
        )
    img_path = Path(image) if os.path.isabs(image) else p.parent / image
    return RosMapInfo(
        p, image, img_path, resolution, (ox, oy, yaw), int(negate != 0), occ, free, mode
    )


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
