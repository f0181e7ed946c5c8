"""Grids for maps: the bounds of a map, the all-unknown grid that covers them, and the cell
arithmetic the rasteriser's primitives share."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from mapkit.model import MapData
from mapkit.raster.errors import RasterError
from mapkit.raster.grid import UNKNOWN, OccupancyGrid

__all__ = ["MAX_SIDE", "grid_for", "grid_for_bounds", "map_bounds"]


#: The longest side of a grid (cells): PNG's limit (2**31 - 1), below ROS's uint32 width/height.
MAX_SIDE = 2**31 - 1
_EPS = 1e-9
_Bounds = tuple[tuple[float, float], tuple[float, float]]
# -- grids -------------------------------------------------------------------------------------


def map_bounds(m: MapData, *, objects: bool = True) -> _Bounds | None:
    """Extents in mm of every scan's points and line ends and (optionally) every object.

    Rectangles count with their rotated corners, lines with both ends, point objects with
    their position. ``None`` when the map has nothing at all.
    """
    lo = np.array([np.inf, np.inf])
    hi = -lo
    for scan in m.scans:
        for arr, xs, ys in ((scan.points, [0], [1]), (scan.lines, [0, 2], [1, 3])):
            if len(arr):
                lo = np.minimum(
                    lo, [min(arr[:, i].min() for i in xs), min(arr[:, i].min() for i in ys)]
                )
                hi = np.maximum(
                    hi, [max(arr[:, i].max() for i in xs), max(arr[:, i].max() for i in ys)]
                )
    if objects and m.objects:
        xy = np.array([c for o in m.objects for c in o.corners()], dtype=np.float64)
        xy = xy[np.all(np.isfinite(xy), axis=1)]
        if len(xy):
            lo = np.minimum(lo, xy.min(axis=0))
            hi = np.maximum(hi, xy.max(axis=0))
    if not np.all(np.isfinite(lo)):
        return None
    return (float(lo[0]), float(lo[1])), (float(hi[0]), float(hi[1]))


def grid_for_bounds(
    bounds_mm: _Bounds | None, resolution: float = 0.05, margin_m: float = 0.5
) -> OccupancyGrid:
    """The all-unknown grid covering a box plus a margin, its origin on a multiple of the
    resolution.

    The maximum bound is always inside the last cell (no off-by-one): ``width`` is
    ``floor((xmax + margin - origin) / resolution) + 1``.

    Args:
        bounds_mm: ``((xmin, ymin), (xmax, ymax))`` in mm; ``None`` gives a grid around (0, 0).
        resolution: Metres per cell.
        margin_m: Metres added on every side.

    Returns:
        A grid filled with -1. Its ``data`` is a read-only broadcast view that takes no memory,
        so the geometry of a grid of any size can be made (see :mod:`mapkit.raster.bands`).

    Raises:
        RasterError: For a resolution that is not positive, a negative margin, or a grid wider or
            taller than a map_server image can be (2**31 - 1 pixels).

    Examples:
        >>> g = grid_for_bounds(((0, 0), (1000, 500)), 0.1, 0)
        >>> g.width, g.height, g.origin, g.bounds_mm()
        (11, 6, (0.0, 0.0), ((0.0, 0.0), (1100.0, 600.0)))
    """
    if not (isinstance(resolution, (int, float)) and math.isfinite(resolution) and resolution > 0):
        raise RasterError(f"resolution must be a positive number of metres, got {resolution!r}")
    if not (math.isfinite(margin_m) and margin_m >= 0):
        raise RasterError(f"margin must be zero or more metres, got {margin_m!r}")
    r = round(resolution * 1000.0, 6)
    (x0, y0), (x1, y1) = bounds_mm if bounds_mm is not None else ((0.0, 0.0), (0.0, 0.0))
    mm = margin_m * 1000.0
    cx0 = math.floor((x0 - mm) / r + _EPS)
    cy0 = math.floor((y0 - mm) / r + _EPS)
    width = math.floor((x1 + mm) / r + _EPS) - cx0 + 1
    height = math.floor((y1 + mm) / r + _EPS) - cy0 + 1
    if max(width, height) > MAX_SIDE:
        raise RasterError(
            f"a {width} x {height} grid at {resolution:g} m is too large: an image side is at most "
            f"{MAX_SIDE:,} pixels (PNG, and ROS's uint32 sizes); use a coarser --resolution"
        )
    origin = (round(cx0 * r / 1000.0, 9), round(cy0 * r / 1000.0, 9))
    return OccupancyGrid(_unknown_cells(height, width), resolution, origin)


def _unknown_cells(height: int, width: int) -> NDArray[np.int8]:
    """A read-only ``(height, width)`` view of -1 that takes no memory (one shared byte)."""
    return np.broadcast_to(np.array(UNKNOWN, dtype=np.int8), (height, width))


def grid_for(m: MapData, resolution: float = 0.05, margin_m: float = 0.5) -> OccupancyGrid:
    """The all-unknown grid covering a map's data and objects plus a margin.

    See :func:`grid_for_bounds` for the rules; the box is :func:`map_bounds`.
    """
    return grid_for_bounds(map_bounds(m), resolution, margin_m)


def _cell_units(grid: OccupancyGrid, xy: NDArray[Any]) -> NDArray[np.float64]:
    """World mm → continuous cell coordinates (u = column axis, v = row axis)."""
    (ox, oy), r = grid.origin_mm, grid.resolution_mm
    out = np.empty(xy.shape, dtype=np.float64)
    out[..., 0] = (xy[..., 0] - ox) / r
    out[..., 1] = (xy[..., 1] - oy) / r
    return out


def _mask_for(
    grid: OccupancyGrid, out: NDArray[np.bool_] | None, row0: int = 0
) -> NDArray[np.bool_]:
    """The mask to draw into: ``out`` checked, or a new one (rows ``row0`` up of the grid)."""
    if out is None:
        return np.zeros((grid.height - row0, grid.width) if row0 else grid.data.shape, dtype=bool)
    if row0 == 0 and out.shape == grid.data.shape and out.dtype == np.bool_:
        return out
    if not (
        out.dtype == np.bool_
        and out.ndim == 2
        and out.shape[1] == grid.width
        and row0 >= 0
        and row0 + out.shape[0] <= grid.height
    ):
        raise ValueError(
            f"out must be a bool array of shape {grid.data.shape}, or a band of its "
            f"rows from row0 ({row0}) with {grid.width} columns"
        )
    return out


def _set(
    mask: NDArray[np.bool_], rows: NDArray[np.int64], cols: NDArray[np.int64], row0: int = 0
) -> None:
    """Set cells ``(rows, cols)`` of the grid in ``mask``, the band of rows from ``row0``."""
    h, w = mask.shape
    if not len(rows):
        return
    if row0:
        rows = rows - row0
    if rows.min() < 0 or rows.max() >= h or cols.min() < 0 or cols.max() >= w:
        ok = (rows >= 0) & (rows < h) & (cols >= 0) & (cols < w)
        rows, cols = rows[ok], cols[ok]
    mask.reshape(-1)[rows * w + cols] = True
