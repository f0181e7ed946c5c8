"""Map → occupancy grid, and the vectorised drawing primitives it is made of.

Everything here takes millimetres (ARIA's unit) and produces :class:`OccupancyGrid` values in
ROS's layout (metres, row 0 south). No Python loop runs per point, per line or per cell: points,
segments and polygons are drawn with numpy in one pass each.

The primitives draw into boolean masks shaped like a grid (``(height, width)``, row 0 south):

* :func:`grid_for` / :func:`grid_for_bounds`: the empty (all unknown) grid covering a map.
* :func:`burn_points`: the cell under each point.
* :func:`burn_segments`: every cell a segment passes through (a "supercover": no gap at any
  angle, both end cells included).
* :func:`burn_polygons`: every cell whose centre lies in a convex polygon (rotated rectangles such
  as forbidden areas, see :func:`object_polygons`), plus every cell its outline crosses.
* :func:`inflate`: cells within a distance of a mask.
* :func:`flood_fill`: the 4-connected regions of a free mask that contain seed cells.
* :func:`hull_mask`: the cells inside the convex hull of a mask.

Examples:
    >>> from mapkit.model import MapData, MapObject, Scan
    >>> walls = [[0, 0, 1000, 0], [1000, 0, 1000, 1000], [1000, 1000, 0, 1000], [0, 1000, 0, 0]]
    >>> m = MapData(scans=(Scan.from_arrays(lines=walls),),
    ...             objects=(MapObject("RobotHome", 500, 500),))
    >>> g = rasterize(m, 0.1, margin_m=0.2)
    >>> g.width, g.height, g.origin
    (15, 15, (-0.2, -0.2))
    >>> g.counts()["occupied"], g.counts()["free"]
    (40, 81)
"""

from __future__ import annotations

import logging
import math
from collections.abc import Iterable, Sequence
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from mapkit.model import MapData, MapObject
from mapkit.raster.errors import RasterError
from mapkit.raster.grid import FREE, OCCUPIED, UNKNOWN, OccupancyGrid

__all__ = [
    "MAX_CELLS",
    "MAX_SIDE",
    "FreeMode",
    "burn_points",
    "burn_polygons",
    "burn_segments",
    "check_options",
    "flood_fill",
    "free_from_rays",
    "grid_for",
    "grid_for_bounds",
    "hull_mask",
    "inflate",
    "map_bounds",
    "object_polygons",
    "rasterize",
    "rays_from_log",
    "seed_points",
    "segment_cells",
    "wall_mask",
]

log_ = logging.getLogger(__name__)

#: The longest side of a grid (cells): PNG's limit (2**31 - 1), below ROS's uint32 width/height.
MAX_SIDE = 2**31 - 1

#: How to decide which cells are free (see :func:`rasterize`).
FreeMode = Literal["flood", "hull", "all", "none", "rays"]

#: The largest grid :func:`rasterize` makes as one whole-grid computation (cells); a larger one is
#: made band by band (:mod:`mapkit.raster.bands`, the same cells in bounded working memory).
MAX_CELLS = 100_000_000

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


# -- primitives --------------------------------------------------------------------------------


def burn_points(
    grid: OccupancyGrid,
    points_mm: ArrayLike,
    out: NDArray[np.bool_] | None = None,
    *,
    row0: int = 0,
) -> NDArray[np.bool_]:
    """Mark the cell under each point.

    Args:
        grid: Gives the geometry (its values are not used).
        points_mm: ``(N, 2)`` x, y in mm. Points off the grid are ignored.
        out: A bool mask of the grid's shape to draw into (in place); a new one when ``None``.
        row0: Draw only the band of the grid's rows from ``row0`` (``out`` holds those rows,
            ``out[0]`` is row ``row0``); the cells are the same as on the whole grid.

    Returns:
        The mask.

    Examples:
        >>> g = grid_for_bounds(((0, 0), (300, 100)), 0.1, 0)
        >>> burn_points(g, [[0, 0], [250, 100], [5000, 0]]).astype(int).tolist()
        [[1, 0, 0, 0], [0, 0, 1, 0]]
    """
    mask = _mask_for(grid, out, row0)
    pts = np.asarray(points_mm).reshape(-1, 2)
    if not len(pts):
        return mask
    (ox, oy), r = grid.origin_mm, grid.resolution_mm
    if pts.dtype.kind in "iu" and all(float(v).is_integer() for v in (ox, oy, r)):
        # Integer millimetres on an integer grid: exact floor division, no floats.
        col = (pts[:, 0] - int(ox)) // int(r)
        row = (pts[:, 1] - int(oy)) // int(r)
        _set(mask, row.astype(np.int64), col.astype(np.int64), row0)
    else:
        uv = np.floor(_cell_units(grid, pts.astype(np.float64)))
        _set(mask, uv[:, 1].astype(np.int64), uv[:, 0].astype(np.int64), row0)
    return mask


def segment_cells(grid: OccupancyGrid, segments_mm: ArrayLike) -> NDArray[np.int64]:
    """Every cell ``(row, col)`` each segment passes through, both end cells included.

    The segment is cut where it crosses grid lines; every piece of positive length marks its
    cell, and both end points mark theirs (a point on a border belongs to the cell above/right).
    Cells the segment only touches at a corner are not marked, so a diagonal line through cell
    corners marks just the diagonal cells. Computed for all segments at once; cells may repeat
    and may lie off the grid.

    Args:
        grid: Gives the geometry.
        segments_mm: ``(M, 4)`` x1, y1, x2, y2 in mm.

    Returns:
        ``(K, 2)`` int64 ``(row, col)``.

    Examples:
        >>> g = grid_for_bounds(((0, 0), (300, 300)), 0.1, 0)
        >>> sorted(set(map(tuple, segment_cells(g, [[50, 50, 250, 150]]).tolist())))
        [(0, 0), (0, 1), (1, 1), (1, 2)]
    """
    seg = np.asarray(segments_mm, dtype=np.float64).reshape(-1, 4)
    if not len(seg):
        return np.zeros((0, 2), dtype=np.int64)
    a = _cell_units(grid, seg[:, 0:2])
    b = _cell_units(grid, seg[:, 2:4])
    d = b - a
    lo = np.floor(np.minimum(a, b))
    hi = np.floor(np.maximum(a, b))
    n = (hi - lo).astype(np.int64)  # grid lines crossed along u and along v
    ilo, ihi = lo.astype(np.int64), hi.astype(np.int64)
    # Fast path: a segment inside one column (or one row) of cells covers the whole span of
    # rows (or columns) between its ends - most walls in real maps.
    simple = (n[:, 0] == 0) | (n[:, 1] == 0)
    out = [_straight_cells(ilo[simple], ihi[simple], n[simple])]
    general = ~simple
    if general.any():
        out.append(
            _crossing_cells(
                a[general],
                b[general],
                d[general],
                lo[general],
                ilo[general],
                ihi[general],
                n[general],
            )
        )
    return np.concatenate(out)


def _straight_cells(
    ilo: NDArray[np.int64], ihi: NDArray[np.int64], n: NDArray[np.int64]
) -> NDArray[np.int64]:
    """Cells of segments that stay in one column or one row: the span between their ends."""
    cnt = n.max(axis=1) + 1
    sid = np.repeat(np.arange(len(n)), cnt)
    step = np.arange(len(sid)) - np.repeat(np.cumsum(cnt) - cnt, cnt)
    along_u = n[sid, 0] > 0
    u = ilo[sid, 0] + np.where(along_u, step, 0)
    v = ilo[sid, 1] + np.where(along_u, 0, step)
    return np.stack([v, u], axis=1)


def _crossing_cells(
    a: NDArray[np.float64],
    b: NDArray[np.float64],
    d: NDArray[np.float64],
    lo: NDArray[np.float64],
    ilo: NDArray[np.int64],
    ihi: NDArray[np.int64],
    n: NDArray[np.int64],
) -> NDArray[np.int64]:
    """Cells of general segments: cut at every grid line, one sample per piece."""
    m = len(a)
    ids = np.arange(m)
    parts_id = [ids, ids]
    parts_t = [np.zeros(m), np.ones(m)]
    for axis in (0, 1):
        cnt = n[:, axis]
        total = int(cnt.sum())
        sid = np.repeat(ids, cnt)
        start = np.cumsum(cnt) - cnt
        k = lo[sid, axis] + 1 + (np.arange(total) - np.repeat(start, cnt))
        parts_id.append(sid)
        parts_t.append((k - a[sid, axis]) / d[sid, axis])
    sid = np.concatenate(parts_id)
    t = np.clip(np.concatenate(parts_t), 0.0, 1.0)
    order = np.argsort(sid * 2.0 + t, kind="stable")
    sid, t = sid[order], t[order]
    # One sample inside every piece of positive length (a piece that is only a shared corner
    # touches its cells at a point: it crosses none of them), plus both end points.
    keep = (sid[1:] == sid[:-1]) & (t[1:] - t[:-1] > _EPS)
    mid_id = sid[1:][keep]
    mid_t = 0.5 * (t[1:][keep] + t[:-1][keep])
    u = np.concatenate([a[:, 0], b[:, 0], a[mid_id, 0] + mid_t * d[mid_id, 0]])
    v = np.concatenate([a[:, 1], b[:, 1], a[mid_id, 1] + mid_t * d[mid_id, 1]])
    sid = np.concatenate([ids, ids, mid_id])
    # Keep every cell within [lo, hi] (rounding near a crossing may step one cell outside).
    iu = np.clip(np.floor(u).astype(np.int64), ilo[sid, 0], ihi[sid, 0])
    iv = np.clip(np.floor(v).astype(np.int64), ilo[sid, 1], ihi[sid, 1])
    return np.stack([iv, iu], axis=1)


def burn_segments(
    grid: OccupancyGrid,
    segments_mm: ArrayLike,
    out: NDArray[np.bool_] | None = None,
    *,
    row0: int = 0,
) -> NDArray[np.bool_]:
    """Mark every cell a segment passes through (no gaps at any angle).

    Args:
        grid: Gives the geometry.
        segments_mm: ``(M, 4)`` x1, y1, x2, y2 in mm. Parts off the grid are ignored.
        out: A bool mask of the grid's shape to draw into (in place); a new one when ``None``.
        row0: Draw only the band of rows from ``row0`` (see :func:`burn_points`).

    Returns:
        The mask.

    Examples:
        >>> g = grid_for_bounds(((0, 0), (300, 200)), 0.1, 0)
        >>> burn_segments(g, [[0, 0, 300, 200]]).astype(int)[::-1].tolist()
        [[0, 0, 0, 1], [0, 1, 1, 0], [1, 1, 0, 0]]
    """
    mask = _mask_for(grid, out, row0)
    cells = segment_cells(grid, segments_mm)
    if len(cells):
        _set(mask, cells[:, 0], cells[:, 1], row0)
    return mask


def object_polygons(objects: Iterable[MapObject]) -> list[NDArray[np.float64]]:
    """World corners (mm) of rectangle objects, one ``(4, 2)`` array each (ARIA's rotation rule)."""
    return [
        np.array(o.corners(), dtype=np.float64)
        for o in objects
        if o.from_to is not None and o.is_finite
    ]


def _convex_fill(mask: NDArray[np.bool_], polys_uv: NDArray[np.float64], row0: int = 0) -> None:
    """Set cells whose centre lies in (or on) a convex polygon; ``polys_uv`` is ``(P, K, 2)``.

    ``mask`` holds the grid's rows from ``row0`` (all of them when 0); the rows are computed in
    the whole grid's coordinates, so a band gets exactly the cells of the whole grid.
    """
    h, w = mask.shape
    if not len(polys_uv):
        return
    vmin = polys_uv[..., 1].min(axis=1)
    vmax = polys_uv[..., 1].max(axis=1)
    r0 = np.clip(np.ceil(vmin - 0.5 - _EPS), row0, row0 + h).astype(np.int64)
    r1 = np.clip(np.floor(vmax - 0.5 + _EPS), row0 - 1, row0 + h - 1).astype(np.int64)
    cnt = np.maximum(r1 - r0 + 1, 0)
    total = int(cnt.sum())
    if not total:
        return
    pid = np.repeat(np.arange(len(polys_uv)), cnt)
    rows = r0[pid] + (np.arange(total) - np.repeat(np.cumsum(cnt) - cnt, cnt))
    yc = rows + 0.5
    pa = polys_uv[pid]  # (T, K, 2)
    pb = np.roll(pa, -1, axis=1)
    ya, yb, xa, xb = pa[..., 1], pb[..., 1], pa[..., 0], pb[..., 0]
    y = yc[:, None]
    within = (np.minimum(ya, yb) - _EPS <= y) & (y <= np.maximum(ya, yb) + _EPS)
    flat = np.abs(yb - ya) < _EPS
    with np.errstate(divide="ignore", invalid="ignore"):
        x = xa + (y - ya) * (xb - xa) / (yb - ya)
    xlo = np.where(flat, np.minimum(xa, xb), x)
    xhi = np.where(flat, np.maximum(xa, xb), x)
    lo = np.where(within, xlo, np.inf).min(axis=1)
    hi = np.where(within, xhi, -np.inf).max(axis=1)
    ok = np.isfinite(lo) & np.isfinite(hi)
    c0 = np.clip(np.ceil(lo[ok] - 0.5 - _EPS), 0, w).astype(np.int64)
    c1 = np.clip(np.floor(hi[ok] - 0.5 + _EPS), -1, w - 1).astype(np.int64)
    rows = rows[ok]
    keep = c1 >= c0
    rows, c0, c1 = rows[keep], c0[keep], c1[keep]
    if not len(rows):
        return
    r0, r1 = int(rows.min()), int(rows.max()) + 1
    cols = np.arange(w)
    if len(np.unique(rows)) == len(rows):  # one span per row (e.g. a hull): compare directly
        mask[rows - row0] |= (cols >= c0[:, None]) & (cols <= c1[:, None])
        return
    diff = np.zeros((r1 - r0, w + 1), dtype=np.int32)
    np.add.at(diff, (rows - r0, c0), 1)
    np.add.at(diff, (rows - r0, c1 + 1), -1)
    mask[r0 - row0 : r1 - row0] |= np.cumsum(diff[:, :w], axis=1) > 0


def burn_polygons(
    grid: OccupancyGrid,
    polygons_mm: Sequence[ArrayLike],
    out: NDArray[np.bool_] | None = None,
    *,
    outline: bool = True,
    row0: int = 0,
) -> NDArray[np.bool_]:
    """Mark every cell whose centre lies in a convex polygon, and (``outline``) every cell its
    edges cross.

    With the outline a polygon smaller than a cell still marks the cells it touches, so a keepout
    zone is never lost.

    Args:
        grid: Gives the geometry.
        polygons_mm: Convex polygons, each ``(K, 2)`` x, y in mm (any K >= 1, any orientation);
            e.g. :func:`object_polygons` of forbidden areas.
        out: A bool mask of the grid's shape to draw into (in place); a new one when ``None``.
        outline: Also mark the cells the edges cross.
        row0: Draw only the band of rows from ``row0`` (see :func:`burn_points`).

    Returns:
        The mask.

    Examples:
        >>> g = grid_for_bounds(((0, 0), (500, 500)), 0.1, 0)
        >>> square = [[[100, 100], [400, 100], [400, 300], [100, 300]]]
        >>> mask = burn_polygons(g, square, outline=False)
        >>> mask.astype(int)[::-1].tolist()  # doctest: +NORMALIZE_WHITESPACE
        [[0, 0, 0, 0, 0, 0], [0, 0, 0, 0, 0, 0], [0, 0, 0, 0, 0, 0], [0, 1, 1, 1, 0, 0],
         [0, 1, 1, 1, 0, 0], [0, 0, 0, 0, 0, 0]]
    """
    mask = _mask_for(grid, out, row0)
    polys = [np.asarray(p, dtype=np.float64).reshape(-1, 2) for p in polygons_mm]
    polys = [p for p in polys if len(p)]
    if not polys:
        return mask
    k = max(len(p) for p in polys)
    padded = np.stack([np.concatenate([p, np.repeat(p[-1:], k - len(p), axis=0)]) for p in polys])
    _convex_fill(mask, _cell_units(grid, padded), row0)
    if outline:
        edges = np.concatenate([padded, np.roll(padded, -1, axis=1)], axis=2).reshape(-1, 4)
        burn_segments(grid, edges, out=mask, row0=row0)
    return mask


def inflate(mask: NDArray[np.bool_], radius_mm: float, resolution: float) -> NDArray[np.bool_]:
    """Cells whose centre is within ``radius_mm`` of the centre of a marked cell.

    Args:
        mask: Bool mask.
        radius_mm: Inflation radius in mm (0 or less returns a copy).
        resolution: Metres per cell.

    Returns:
        A new mask.

    Examples:
        >>> m = np.zeros((5, 5), dtype=bool); m[2, 2] = True
        >>> inflate(m, 100, 0.1).astype(int).tolist()
        [[0, 0, 0, 0, 0], [0, 0, 1, 0, 0], [0, 1, 1, 1, 0], [0, 0, 1, 0, 0], [0, 0, 0, 0, 0]]
    """
    if radius_mm <= 0 or not mask.any():
        return mask.copy()
    from scipy import ndimage

    r_cells = radius_mm / (resolution * 1000.0)
    pad = math.ceil(r_cells) + 1
    rows = np.flatnonzero(mask.any(axis=1))
    cols = np.flatnonzero(mask.any(axis=0))
    r0, r1 = max(rows[0] - pad, 0), min(rows[-1] + pad + 1, mask.shape[0])
    c0, c1 = max(cols[0] - pad, 0), min(cols[-1] + pad + 1, mask.shape[1])
    sub = mask[r0:r1, c0:c1]
    dist = ndimage.distance_transform_edt(~sub)
    out = np.zeros_like(mask)
    out[r0:r1, c0:c1] = dist <= r_cells + _EPS
    return out


def free_from_rays(
    grid: OccupancyGrid,
    rays_mm: ArrayLike,
    hits: ArrayLike | None = None,
    out: NDArray[np.bool_] | None = None,
    *,
    chunk: int = 20_000,
    row0: int = 0,
) -> NDArray[np.bool_]:
    """Cells laser beams pass through: every cell a ray crosses, except the cells it hit.

    Args:
        grid: Gives the geometry.
        rays_mm: ``(K, 4)`` sensor x, y and beam end x, y in mm (world frame).
        hits: ``(K,)`` bool, whether each beam ended on an obstacle (default: all did); the end
            cell of a hit is not free, the end of a max-range reading is.
        out: A bool mask to draw into (in place); a new one when ``None``.
        chunk: Rays per vectorised batch (bounds the memory: a batch holds every crossed cell).
        row0: Draw only the band of rows from ``row0`` (see :func:`burn_points`); only the rays
            that reach the band are traced.

    Returns:
        The mask of cells some beam passed through.

    Examples:
        >>> g = grid_for_bounds(((0, 0), (500, 0)), 0.1, 0)
        >>> free_from_rays(g, [[50, 50, 450, 50]]).astype(int).tolist()
        [[1, 1, 1, 1, 0, 0]]
    """
    mask = _mask_for(grid, out, row0)
    rays = np.asarray(rays_mm, dtype=np.float64).reshape(-1, 4)
    hit = np.ones(len(rays), dtype=bool) if hits is None else np.asarray(hits, dtype=bool)
    if hit.shape != (len(rays),):
        raise RasterError(f"hits must have one flag per ray ({len(rays)}), got shape {hit.shape}")
    if row0 or len(mask) != grid.height:  # a band: only the rays whose rows reach it
        (_, oy), r = grid.origin_mm, grid.resolution_mm
        lo = (np.minimum(rays[:, 1], rays[:, 3]) - oy) / r
        hi = (np.maximum(rays[:, 1], rays[:, 3]) - oy) / r
        near = (hi >= row0 - 1) & (lo < row0 + len(mask) + 1)
        rays, hit = rays[near], hit[near]
    ended = np.zeros_like(mask)
    for i in range(0, len(rays), max(1, chunk)):  # one step per batch of rays
        part = rays[i : i + chunk]
        cells = segment_cells(grid, part)
        _set(mask, cells[:, 0], cells[:, 1], row0)
        burn_points(grid, part[hit[i : i + chunk], 2:4], out=ended, row0=row0)
    mask &= ~ended
    return mask


def flood_fill(open_mask: NDArray[np.bool_], seeds_rc: ArrayLike) -> NDArray[np.bool_]:
    """The 4-connected regions of ``open_mask`` that contain a seed cell.

    A 4-connected fill cannot slip between two diagonal wall cells, so any 8-connected wall
    (a scanned wall, a drawn line) bounds it.

    Args:
        open_mask: Cells the fill may enter.
        seeds_rc: ``(N, 2)`` ``(row, col)`` seed cells; seeds off the grid or on closed cells
            are ignored.

    Returns:
        A new mask (all False when no seed is usable).

    Examples:
        >>> o = np.array([[1, 1, 0, 1], [1, 1, 0, 1]], dtype=bool)
        >>> flood_fill(o, [[0, 0]]).astype(int).tolist()
        [[1, 1, 0, 0], [1, 1, 0, 0]]
    """
    from scipy import ndimage

    seeds = np.asarray(seeds_rc, dtype=np.int64).reshape(-1, 2)
    h, w = open_mask.shape
    ok = (seeds[:, 0] >= 0) & (seeds[:, 0] < h) & (seeds[:, 1] >= 0) & (seeds[:, 1] < w)
    seeds = seeds[ok]
    seeds = seeds[open_mask[seeds[:, 0], seeds[:, 1]]]
    if not len(seeds):
        return np.zeros_like(open_mask, dtype=bool)
    labels, _ = ndimage.label(open_mask)
    ids = np.unique(labels[seeds[:, 0], seeds[:, 1]])
    lut = np.zeros(int(labels.max()) + 1, dtype=bool)
    lut[ids] = True
    filled: NDArray[np.bool_] = lut[labels]
    return filled


def hull_mask(mask: NDArray[np.bool_], extra_rc: ArrayLike | None = None) -> NDArray[np.bool_]:
    """Cells whose centre lies in the convex hull of the marked cells' centres (and ``extra_rc``).

    Examples:
        >>> m = np.zeros((4, 4), dtype=bool); m[0, 0] = m[3, 3] = m[0, 3] = True
        >>> hull_mask(m).astype(int).tolist()
        [[1, 1, 1, 1], [0, 1, 1, 1], [0, 0, 1, 1], [0, 0, 0, 1]]
    """
    out = np.zeros(mask.shape, dtype=bool)
    poly = _hull_polygon([_row_extremes(mask)], extra_rc)
    if poly is not None:
        _convex_fill(out, poly[None])
    return out


def _row_extremes(mask: NDArray[np.bool_], row0: int = 0) -> NDArray[np.int64]:
    """``(col, row)`` of the first and last marked cell of every row with one (rows from
    ``row0``)."""
    rows = np.flatnonzero(mask.any(axis=1))
    if not len(rows):
        return np.zeros((0, 2), dtype=np.int64)
    sub = mask[rows]
    first = sub.argmax(axis=1)
    last = mask.shape[1] - 1 - sub[:, ::-1].argmax(axis=1)
    rows = rows + row0
    return np.concatenate([np.stack([first, rows], axis=1), np.stack([last, rows], axis=1)])


def _hull_polygon(
    extremes: list[NDArray[np.int64]], extra_rc: ArrayLike | None = None
) -> NDArray[np.float64] | None:
    """The convex hull (cell units) of the centres of ``(col, row)`` cells and ``extra_rc``."""
    pts = [e for e in extremes if len(e)]
    if extra_rc is not None:
        e = np.asarray(extra_rc, dtype=np.int64).reshape(-1, 2)
        pts.append(e[:, ::-1])
    if not pts:
        return None
    uv = np.unique(np.concatenate(pts), axis=0).astype(np.float64) + 0.5  # (col, row) centres
    if not len(uv):
        return None
    poly = uv
    if len(uv) >= 3:
        from scipy.spatial import ConvexHull, QhullError

        try:
            poly = uv[ConvexHull(uv).vertices]
        except QhullError:  # all collinear: the segment between the extremes
            order = np.lexsort((uv[:, 1], uv[:, 0]))
            poly = uv[[order[0], order[-1]]]
    return poly


# -- the map -----------------------------------------------------------------------------------

_SEED_TYPES = ("Goal", "Dock", "RobotHome")


def seed_points(m: MapData) -> NDArray[np.float64]:
    """Where the robot can be: goals, docks and homes (positions, or centres of home rectangles).

    Point objects of the built-in types ``Goal``/``GoalWithHeading``/``Dock``/``RobotHome`` and
    of any type declared as ``GoalType`` or ``DockType`` in ``MapInfo:``.

    Returns:
        ``(N, 2)`` x, y in mm.
    """
    declared = {k for k, v in m.declared_types().items() if v in ("GoalType", "DockType")}
    out = []
    for o in m.objects:
        if o.base_type in _SEED_TYPES or o.type in declared or o.base_type in declared:
            if o.from_to is None:
                out.append((o.x, o.y))
            else:
                c = np.array(o.corners())
                out.append(tuple(c.mean(axis=0)))
    arr = np.array(out, dtype=np.float64).reshape(-1, 2)
    return arr[np.all(np.isfinite(arr), axis=1)]


def _forbidden(m: MapData) -> tuple[list[NDArray[np.float64]], NDArray[np.float64]]:
    """Forbidden areas (polygons) and forbidden lines (segments) of a map."""
    areas = [o for o in m.objects if o.type == "ForbiddenArea" and m.object_shape(o) == "rect"]
    lines = [o.from_to for o in m.objects if o.type == "ForbiddenLine" and o.from_to is not None]
    return object_polygons(areas), np.array(lines, dtype=np.float64).reshape(-1, 4)


def wall_mask(
    m: MapData, grid: OccupancyGrid, *, forbidden_as_walls: bool = False
) -> NDArray[np.bool_]:
    """Cells holding a point or crossed by a line of any scan (and, optionally, forbidden zones)."""
    walls = np.zeros(grid.data.shape, dtype=bool)
    for scan in m.scans:
        burn_points(grid, scan.points, out=walls)
        burn_segments(grid, scan.lines, out=walls)
    if forbidden_as_walls:
        polys, segs = _forbidden(m)
        burn_polygons(grid, polys, out=walls)
        burn_segments(grid, segs, out=walls)
    return walls


def rays_from_log(log: Any, *, max_range: float = 16000.0) -> NDArray[np.float64]:
    """The beams of a ``.2d`` log as ``(K, 4)`` rays: laser origin and hit point, world mm.

    Each scan is placed at its ``robotGlobal:`` pose when the log has one (the localised pose),
    else at its odometry pose, so the log must be in the map's frame: recorded while the robot
    was localised on this map, or simulated from it. Beams without a return give no ray.

    Args:
        log: A path, the log's bytes, or a :class:`~mapkit.model.scan.LaserLog`.
        max_range: Readings farther than this (mm) are left out.

    Returns:
        The rays.

    Raises:
        LogFormatError: When the log cannot be read.
    """
    from mapkit.formats.laser2d import iter_log
    from mapkit.model.scan import LaserLog, LaserScan, LogRecord, laser_to_robot, robot_to_world

    records: Iterable[LogRecord]
    if isinstance(log, LaserLog):
        header, records = log.header, log.records
    else:
        reader = iter_log(log)
        header, records = reader.header, reader
    out: list[NDArray[np.float64]] = []
    for rec in records:
        if not isinstance(rec, LaserScan) or rec.xy is None:
            continue
        laser = header.laser(rec.laser)
        pose = rec.robot_global if rec.robot_global is not None else rec.robot
        hits = rec.global_points(laser, pose=pose, max_range=max_range)
        if len(hits) == 0:
            continue
        origin = robot_to_world(laser_to_robot(np.zeros((1, 2)), laser.pose), pose)[0]
        out.append(np.column_stack([np.broadcast_to(origin, hits.shape), hits]))
    return np.concatenate(out) if out else np.zeros((0, 4))


def check_options(
    free: str, inflate_mm: float, *, log: Any = None, rays_mm: ArrayLike | None = None
) -> tuple[FreeMode, NDArray[np.float64] | None]:
    """Check :func:`rasterize`'s free-space options; returns the free mode and the rays.

    A ``.2d`` ``log`` is read into rays (the mode is then ``"rays"``).

    Raises:
        RasterError: For a bad or inconsistent option.
    """
    if free not in ("flood", "hull", "all", "none", "rays"):
        raise RasterError(f"free must be one of flood, hull, all, none, rays; got {free!r}")
    if log is None and (free == "rays") != (rays_mm is not None):
        raise RasterError('free="rays" and rays_mm go together: give both or neither')
    if log is not None:
        if rays_mm is not None:
            raise RasterError("give a .2d log or rays_mm, not both")
        rays_mm, free = rays_from_log(log), "rays"
    if not (math.isfinite(inflate_mm) and inflate_mm >= 0):
        raise RasterError(f"inflation must be zero or more millimetres, got {inflate_mm!r}")
    rays = None if rays_mm is None else np.asarray(rays_mm, dtype=np.float64).reshape(-1, 4)
    return free, rays  # type: ignore[return-value]


def rasterize(
    m: MapData,
    resolution: float = 0.05,
    *,
    margin_m: float = 0.5,
    free: FreeMode = "flood",
    inflate_mm: float = 0,
    forbidden_as_walls: bool = False,
    log: Any = None,
    like: OccupancyGrid | None = None,
    rays_mm: ArrayLike | None = None,
) -> OccupancyGrid:
    """A map as an occupancy grid: walls occupied, reachable space free, the rest unknown.

    Occupied cells are those holding a point or crossed by a line of any scan (plus forbidden
    areas and lines with ``forbidden_as_walls``), grown by ``inflate_mm``. Free cells depend on
    ``free``:

    * ``"flood"`` (default): the 4-connected space reachable from the goals, docks and homes
      without crossing a wall, kept inside the convex hull of the walls (so a gap in a scanned
      wall does not make the whole margin free). A map without any such object falls back to
      ``"hull"`` (logged as a warning).
    * ``"hull"``: everything inside the convex hull of the walls.
    * ``"all"``: every cell that is not a wall.
    * ``"none"``: nothing (only walls and unknown).
    * ``"rays"``: the cells laser beams ``rays_mm`` pass through (see :func:`free_from_rays`).

    Args:
        m: The map.
        resolution: Metres per cell.
        margin_m: Unknown border added around the map's bounds, in metres.
        free: How free space is decided (see above).
        inflate_mm: Grow occupied cells by this radius (mm).
        forbidden_as_walls: Also mark forbidden areas and lines occupied.
        log: A ``.2d`` laser log (path or :class:`~mapkit.model.scan.LaserLog`) whose beams
            give the free space (``free`` is then ``"rays"``); see :func:`rays_from_log`.
        rays_mm: ``(K, 4)`` beams (sensor x, y, end x, y in mm) for ``free="rays"``, each ending
            on an obstacle.
        like: Use this grid's geometry (shape, resolution, origin) instead of one fitted to the
            map (``resolution`` and ``margin_m`` are then ignored); e.g. to compare two maps
            cell by cell, or to draw a mask on the same grid as a map.

    Returns:
        The grid (see :func:`grid_for` for its geometry). A grid of more than :data:`MAX_CELLS`
        cells is made band by band (:class:`mapkit.raster.bands.BandRaster`, the same cells):
        then only the result (one byte a cell) grows with the map.

    Raises:
        RasterError: For a bad option or a grid too large.
    """
    free, rays_mm = check_options(free, inflate_mm, log=log, rays_mm=rays_mm)
    if like is not None:
        grid = like.with_data(_unknown_cells(like.height, like.width))
    else:
        grid = grid_for(m, resolution, margin_m)
    if grid.width * grid.height > MAX_CELLS:
        from mapkit.raster.bands import BandRaster

        return BandRaster(
            m,
            free=free,
            inflate_mm=inflate_mm,
            rays_mm=rays_mm,
            like=grid,
            forbidden_as_walls=forbidden_as_walls,
        ).to_grid()
    walls = wall_mask(m, grid, forbidden_as_walls=forbidden_as_walls)
    open_ = ~walls
    if free == "flood":
        seeds = grid.world_to_cell(seed_points(m))
        reach = flood_fill(open_, seeds)
        if reach.any():
            space = reach & hull_mask(walls, seeds[grid.inside(seeds)])
        else:
            log_.warning("no goal, dock or home in free space to flood from: using the walls' hull")
            space = hull_mask(walls) & open_
    elif free == "hull":
        space = hull_mask(walls) & open_
    elif free == "all":
        space = open_
    elif free == "rays":
        space = free_from_rays(grid, np.asarray(rays_mm)) & open_
    else:
        space = np.zeros_like(walls)
    occupied = inflate(walls, inflate_mm, grid.resolution) if inflate_mm else walls
    data = np.full(walls.shape, UNKNOWN, dtype=np.int8)
    data[space] = FREE
    data[occupied] = OCCUPIED
    return grid.with_data(data)
