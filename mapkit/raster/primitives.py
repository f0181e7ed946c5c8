"""The rasteriser's primitives: points, segments and polygons burnt into cells, inflation, free
space from rays, flood fill and hulls."""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from mapkit.model import MapObject
from mapkit.raster.cells import (
    _EPS as _EPS,
    _Bounds as _Bounds,
    _cell_units as _cell_units,
    _mask_for as _mask_for,
    _set as _set,
    _unknown_cells as _unknown_cells,
)
from mapkit.raster.errors import RasterError
from mapkit.raster.grid import OccupancyGrid

__all__ = [
    "burn_points",
    "burn_polygons",
    "burn_segments",
    "flood_fill",
    "free_from_rays",
    "hull_mask",
    "inflate",
    "object_polygons",
    "segment_cells",
]


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
        >>> from mapkit.raster.cells import grid_for_bounds
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
        >>> from mapkit.raster.cells import grid_for_bounds
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
        >>> from mapkit.raster.cells import grid_for_bounds
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
        >>> from mapkit.raster.cells import grid_for_bounds
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
        >>> from mapkit.raster.cells import grid_for_bounds
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
