"""Writing map images: thresholds, the grey level of each cell value, PGM and PNG bytes."""

from __future__ import annotations

import os
import struct
import zlib
from typing import Any

import numpy as np
from numpy.typing import NDArray

from mapkit._atomic import atomic_write
from mapkit._typing import PathLike
from mapkit.raster.errors import RasterError
from mapkit.raster.grid import OccupancyGrid
from mapkit.raster.ros.common import (
    DEFAULT_FREE_THRESH,
    DEFAULT_OCCUPIED_THRESH,
    MODES,
    SAVER_FREE,
    SAVER_OCCUPIED,
    SAVER_UNKNOWN,
    Mode,
    log_,
)
from mapkit.raster.ros.pixels import load_pixel_values

__all__ = ["check_scale", "grid_to_image", "pixel_table", "write_image"]


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
