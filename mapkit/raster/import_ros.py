"""ROS maps back to ARIA maps: occupied cells become points, wall faces become lines.

:func:`import_ros` reads a map_server YAML and its image (any mode, negate, thresholds; see
:mod:`mapkit.raster.ros`) and builds a :class:`~mapkit.model.MapData`:

* every occupied cell (value >= ``occupied_value``, 65 by default: ``100`` in a trinary map) is
  a point at its cell's centre, in integer millimetres, in the map's own frame: x to the east,
  y to the north, origin kept (ARIA's own bitmap converter swaps x and y; mapkit does not);
* wall lines are extracted from the occupied cells' faces (cells with a non-occupied
  4-neighbour): maximal runs along rows, columns and both diagonals at least ``min_line_m`` long
  become segments from the first cell's centre to the last one's, so a line never leaves the
  cells it came from;
* a keepout mask (another map_server YAML, e.g. a Nav2 keepout filter mask) becomes forbidden
  areas: each connected keepout region is one rectangle (axis-aligned or rotated) when one
  rectangle covers it well, a ``ForbiddenLine`` when it is one cell thin, and otherwise a set of
  axis-aligned rectangles that cover exactly its cells.

A non-zero yaw in the YAML's ``origin`` rotates everything about the origin, as the
``nav_msgs/MapMetaData`` definition says (most ROS tools ignore the yaw; a warning is logged).
"""

from __future__ import annotations

import logging
import math
import os
from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from mapkit._typing import PathLike
from mapkit.model import MapData, MapObject, Scan
from mapkit.raster.errors import RasterError, RosMapError
from mapkit.raster.grid import OccupancyGrid, _round_mm
from mapkit.raster.ros import (
    Flavor,
    RosMapInfo,
    image_to_grid,
    open_map_image,
    pixel_values,
    read_ros_yaml,
)
from mapkit.raster.ros_image import MAX_DECODED_PIXELS, ImageSource

__all__ = [
    "cell_runs",
    "grid_to_map",
    "import_ros",
    "keepout_objects",
    "occupied_points",
    "wall_lines",
]

log_ = logging.getLogger(__name__)


def _to_world(grid: OccupancyGrid, uv: NDArray[np.float64], yaw: float) -> NDArray[np.float64]:
    """Cell coordinates (u along columns, v along rows, in cells) to world millimetres."""
    return _world(grid.resolution_mm, grid.origin_mm, uv, yaw)


def _world(
    r: float, origin_mm: tuple[float, float], uv: NDArray[np.float64], yaw: float
) -> NDArray[np.float64]:
    (ox, oy) = origin_mm
    x, y = uv[..., 0] * r, uv[..., 1] * r
    if yaw:
        c, s = math.cos(yaw), math.sin(yaw)
        x, y = c * x - s * y, s * x + c * y
    return np.stack([ox + x, oy + y], axis=-1)


def occupied_points(
    grid: OccupancyGrid, *, occupied_value: int = 65, yaw: float = 0.0
) -> NDArray[np.int64]:
    """Centres (integer mm) of the cells whose value is at least ``occupied_value``.

    Examples:
        >>> g = OccupancyGrid(np.array([[100, 0], [-1, 100]], dtype=np.int8), 0.1, (1.0, 0.0))
        >>> occupied_points(g).tolist()
        [[1050, 50], [1150, 150]]
    """
    rc = np.argwhere(grid.data >= occupied_value)
    uv = rc[:, ::-1].astype(np.float64) + 0.5
    return np.rint(_to_world(grid, uv, yaw)).astype(np.int64)


def _pair_order(major: NDArray[np.int64], pos: NDArray[np.int64]) -> NDArray[np.intp]:
    """``np.lexsort((pos, major))``, faster: one stable sort of a combined key, none if sorted."""
    if len(major) < 2:
        return np.arange(len(major))
    m0, p0 = int(major.min()), int(pos.min())
    span_m, span_p = int(major.max()) - m0 + 1, int(pos.max()) - p0 + 1
    if span_m * span_p >= 2**62:
        return np.lexsort((pos, major))
    key = major - m0  # built in place: this runs on millions of wall cells
    key *= span_p
    key += pos
    key -= p0
    if bool((key[1:] >= key[:-1]).all()):  # row-major input, as argwhere gives it
        return np.arange(len(key))
    return np.argsort(key, kind="stable")


def _runs(
    major: NDArray[np.int64], pos: NDArray[np.int64]
) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """Maximal runs of consecutive ``pos`` values sharing a ``major`` value (vectorised).

    Returns:
        Indices (into the inputs) of each run's first and last element.
    """
    order = _pair_order(major, pos)
    mj, ps = major[order], pos[order]
    brk = np.ones(len(order), dtype=bool)
    brk[1:] = (mj[1:] != mj[:-1]) | (ps[1:] != ps[:-1] + 1)
    first = np.flatnonzero(brk)
    last = np.append(first[1:] - 1, len(order) - 1)
    return order[first], order[last]


def cell_runs(mask: NDArray[np.bool_], min_cells: int = 2) -> NDArray[np.int64]:
    """Maximal straight runs of marked cells along rows, columns and both diagonals.

    Works on the marked cells only (sorting them by row, column and diagonal), so the cost
    follows the number of marked cells, not the grid's size.

    Args:
        mask: Bool ``(height, width)``.
        min_cells: Shortest run kept (cells).

    Returns:
        ``(K, 4)`` int64 ``row0, col0, row1, col1`` of each run's first and last cell
        (rows, then columns, then the two diagonals).

    Examples:
        >>> m = np.zeros((4, 5), dtype=bool); m[1, 0:4] = True; m[0, 4] = m[1, 3] = True
        >>> cell_runs(m, 3).tolist()
        [[1, 0, 1, 3]]
        >>> cell_runs(np.eye(3, dtype=bool), 3).tolist()
        [[0, 0, 2, 2]]
    """
    return _cell_runs_rc(np.argwhere(mask).astype(np.int64), min_cells)


def _cell_runs_rc(rc: NDArray[np.int64], min_cells: int) -> NDArray[np.int64]:
    """:func:`cell_runs` of the marked cells ``rc`` (``(N, 2)`` row, col; any order)."""
    r, c = rc[:, 0], rc[:, 1]
    out = [np.zeros((0, 4), dtype=np.int64)]
    if len(rc):
        for direction in range(4):  # rows, columns, both diagonals (one key array at a time)
            major = (
                r if direction == 0 else c if direction == 1 else c - r if direction == 2 else c + r
            )
            pos = c if direction == 0 else r
            a, b = _runs(major, pos)
            keep = pos[b] - pos[a] + 1 >= min_cells
            a, b = a[keep], b[keep]
            out.append(np.stack([r[a], c[a], r[b], c[b]], axis=1))
    return np.concatenate(out)


def _run_cells(
    runs: NDArray[np.int64],
) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.int64]]:
    """Every cell of straight or diagonal runs: (run index, row, col)."""
    cnt = np.maximum(np.abs(runs[:, 2] - runs[:, 0]), np.abs(runs[:, 3] - runs[:, 1])) + 1
    rid = np.repeat(np.arange(len(runs)), cnt)
    step = np.arange(len(rid)) - np.repeat(np.cumsum(cnt) - cnt, cnt)
    dr = np.sign(runs[:, 2] - runs[:, 0])[rid]
    dc = np.sign(runs[:, 3] - runs[:, 1])[rid]
    return rid, runs[rid, 0] + dr * step, runs[rid, 1] + dc * step


def wall_lines(
    grid: OccupancyGrid, *, occupied_value: int = 65, min_line_m: float = 0.3, yaw: float = 0.0
) -> NDArray[np.int64]:
    """Wall segments (integer mm) along the faces of the occupied cells.

    Faces are occupied cells with a non-occupied 4-neighbour. Runs along rows and columns of at
    least ``min_line_m`` become lines; diagonal runs too, where most of their cells are not
    already on a row or column line. Each line joins its first and last cell centres.
    """
    occ = grid.data >= occupied_value
    if not occ.any():
        return np.zeros((0, 4), dtype=np.int64)
    faces = _faces(np.pad(occ, 1), 1, occ.shape[0] + 1)
    keep = _face_lines(np.argwhere(faces).astype(np.int64), _min_cells(min_line_m, grid.resolution))
    return _line_world(keep, grid.resolution_mm, grid.origin_mm, yaw)


def _faces(p: NDArray[np.bool_], a: int, b: int) -> NDArray[np.bool_]:
    """Face cells of rows ``a..b-1`` of a padded occupancy mask ``p`` (a False border around).

    A face is an occupied cell with a non-occupied 4-neighbour.
    """
    inner = p[a - 1 : b - 1, 1:-1] & p[a + 1 : b + 1, 1:-1] & p[a:b, :-2] & p[a:b, 2:]
    return p[a:b, 1:-1] & ~inner


def _min_cells(min_line_m: float, resolution: float) -> int:
    """Shortest line in cells (at least 2; huge ratios saturate instead of overflowing)."""
    ratio = min_line_m / resolution - 1e-9
    return max(2, math.ceil(ratio) if ratio < 2.0**62 else 1 << 62)


def _face_lines(rc: NDArray[np.int64], n: int) -> NDArray[np.int64]:
    """Runs of face cells (``(N, 2)`` row, col) kept as wall lines (row0, col0, row1, col1).

    Runs along rows and columns of at least ``n`` cells are kept; diagonal runs too, where most
    of their cells are not already on a row or column line (looked up among the straight runs'
    cells, so memory follows the number of faces, not the grid's size).
    """
    runs = _cell_runs_rc(rc, 2)
    axis = (runs[:, 0] == runs[:, 2]) | (runs[:, 1] == runs[:, 3])
    length = np.maximum(np.abs(runs[:, 2] - runs[:, 0]), np.abs(runs[:, 3] - runs[:, 1])) + 1
    straight = runs[axis & (length >= n)]
    diag = runs[~axis & (length * math.sqrt(2) >= n)]
    if len(diag):
        rid, rr, cc = _run_cells(diag)
        hit = _on_runs(rr, cc, straight, rc)
        hits = np.bincount(rid, weights=hit, minlength=len(diag))
        diag = diag[hits / np.bincount(rid, minlength=len(diag)) < 0.5]
    return np.concatenate([straight, diag])


def _on_runs(
    rr: NDArray[np.int64], cc: NDArray[np.int64], straight: NDArray[np.int64], rc: NDArray[np.int64]
) -> NDArray[np.bool_]:
    """Which cells ``(rr, cc)`` lie on one of the row or column runs ``straight``.

    Runs of one row (or column) are disjoint, so each cell is looked up by binary search among
    the runs' starts: no run is expanded into its cells.
    """
    hit = np.zeros(len(rr), dtype=bool)
    big_c, big_r = int(rc[:, 1].max()) + 1, int(rc[:, 0].max()) + 1
    row_runs = straight[straight[:, 0] == straight[:, 2]]
    col_runs = straight[straight[:, 0] != straight[:, 2]]
    for runs, major, minor, size in ((row_runs, 0, 1, big_c), (col_runs, 1, 0, big_r)):
        if not len(runs):
            continue
        starts = runs[:, major] * size + np.minimum(runs[:, minor], runs[:, minor + 2])
        ends = runs[:, major] * size + np.maximum(runs[:, minor], runs[:, minor + 2])
        order = np.argsort(starts)
        starts, ends = starts[order], ends[order]
        keys = (rr if major == 0 else cc) * size + (cc if major == 0 else rr)
        at = np.searchsorted(starts, keys, side="right") - 1
        hit |= (at >= 0) & (ends[np.maximum(at, 0)] >= keys)
    return hit


def _line_world(
    keep: NDArray[np.int64], r: float, origin_mm: tuple[float, float], yaw: float
) -> NDArray[np.int64]:
    uv = np.stack([keep[:, [1, 0]], keep[:, [3, 2]]], axis=1).astype(np.float64) + 0.5
    xy = _world(r, origin_mm, uv, yaw)
    return np.rint(xy.reshape(-1, 4)).astype(np.int64)


def _rect_object(corners_xy: NDArray[np.float64], theta_deg: float) -> MapObject:
    """A ForbiddenArea whose world corners are ``corners_xy``, in ARIA's rotated frame."""
    t = math.radians(theta_deg)
    c, s = math.cos(t), math.sin(t)
    # Undo the rotation about the map origin: frame coordinates of the corners.
    fx = c * corners_xy[:, 0] + s * corners_xy[:, 1]
    fy = -s * corners_xy[:, 0] + c * corners_xy[:, 1]
    ft = (
        round(float(fx.min())),
        round(float(fy.min())),
        round(float(fx.max())),
        round(float(fy.max())),
    )
    return MapObject("ForbiddenArea", 0, 0, theta_deg, from_to=ft)


def _axis_rects(cells: NDArray[np.int64]) -> NDArray[np.int64]:
    """Axis-aligned rectangles (row0, col0, row1, col1) covering exactly a set of cells.

    Row runs with the same column span in consecutive rows merge into one rectangle.
    """
    r, c = cells[:, 0], cells[:, 1]
    a, b = _runs(r, c)
    runs = np.stack([r[a], c[a], c[b]], axis=1)  # row, first col, last col
    a2, b2 = _runs(runs[:, 1] * (int(c.max()) + 2) + runs[:, 2], runs[:, 0])
    return np.stack([runs[a2, 0], runs[a2, 1], runs[b2, 0], runs[b2, 2]], axis=1)


def keepout_objects(
    mask: OccupancyGrid, *, keepout_value: int = 100, yaw: float = 0.0, fill: float = 0.85
) -> list[MapObject]:
    """Forbidden areas (and lines) for the keepout regions of a mask grid.

    Args:
        mask: A keepout mask as map_server reads it (keepout cells 100).
        keepout_value: Cells with at least this value are keepout.
        yaw: The mask's origin yaw (radians).
        fill: A region is one rectangle when its cells fill at least this share of the smallest
            (rotated) rectangle around them; otherwise it is split into axis-aligned rectangles.

    Returns:
        ``ForbiddenArea`` rectangles and ``ForbiddenLine`` segments in world millimetres.
    """
    from scipy import ndimage
    from shapely import MultiPoint

    keep = mask.data >= keepout_value
    labels, n = ndimage.label(keep, structure=np.ones((3, 3), dtype=int))
    if not n:
        return []
    out: list[MapObject] = []
    yaw_deg = math.degrees(yaw)
    for idx, sl in enumerate(ndimage.find_objects(labels), start=1):  # one step per region
        if sl is None:
            continue
        cells = np.argwhere(labels[sl] == idx) + np.array([sl[0].start, sl[1].start])
        count = len(cells)
        rows = int(sl[0].stop - sl[0].start)
        cols = int(sl[1].stop - sl[1].start)
        if count == rows * cols and (min(rows, cols) > 1 or count == 1):
            uv = np.array(
                [
                    [cells[:, 1].min(), cells[:, 0].min()],
                    [cells[:, 1].max() + 1, cells[:, 0].max() + 1],
                ],
                dtype=np.float64,
            )
            out.append(_rect_object(_box_corners(mask, uv, yaw), yaw_deg))
            continue
        centres = cells[:, ::-1].astype(np.float64) + 0.5
        rect = MultiPoint(centres).minimum_rotated_rectangle
        if rect.geom_type == "Polygon":
            pts = np.array(rect.exterior.coords)[:4]
        else:  # collinear centres: a thin line of cells
            pts = np.array(rect.coords)
        e0 = pts[1] - pts[0]
        e1 = pts[2] - pts[1] if len(pts) > 2 else np.array([-e0[1], e0[0]]) * 0
        len0, len1 = float(np.hypot(*e0)), float(np.hypot(*e1))
        thin = len(pts) == 2 or min(len0, len1) <= 1.5
        if thin and max(len0, len1) >= 2.0:
            axis = e0 if len0 >= len1 else e1
            centre = pts.mean(axis=0)
            half = axis / 2.0
            ends = np.array([centre - half, centre + half])
            xy = _to_world(mask, ends, yaw)
            x1, y1, x2, y2 = (round(float(v)) for v in xy.reshape(-1))
            out.append(MapObject("ForbiddenLine", x1, y1, 0, from_to=(x1, y1, x2, y2)))
            continue
        # The rectangle around the centres, grown by half a cell, covers the cells' squares.
        angle = math.atan2(e0[1], e0[0])
        u = np.array([math.cos(angle), math.sin(angle)])
        v = np.array([-u[1], u[0]])
        pu, pv = centres @ u, centres @ v
        area = (pu.max() - pu.min() + 1.0) * (pv.max() - pv.min() + 1.0)
        if count >= fill * area:
            lo_u, hi_u = pu.min() - 0.5, pu.max() + 0.5
            lo_v, hi_v = pv.min() - 0.5, pv.max() + 0.5
            quad = np.array(
                [lo_u * u + lo_v * v, hi_u * u + lo_v * v, hi_u * u + hi_v * v, lo_u * u + hi_v * v]
            )
            theta = _norm_deg(math.degrees(angle) + yaw_deg)
            out.append(_rect_object(_to_world(mask, quad, yaw), theta))
            continue
        for r0, c0, r1, c1 in _axis_rects(cells):
            uv = np.array([[c0, r0], [c1 + 1, r1 + 1]], dtype=np.float64)
            out.append(_rect_object(_box_corners(mask, uv, yaw), yaw_deg))
    return out


def _box_corners(grid: OccupancyGrid, uv: NDArray[np.float64], yaw: float) -> NDArray[np.float64]:
    (u0, v0), (u1, v1) = uv
    quad = np.array([[u0, v0], [u1, v0], [u1, v1], [u0, v1]], dtype=np.float64)
    return _to_world(grid, quad, yaw)


def _norm_deg(a: float) -> float:
    """Fold an angle to (-90, 90]: a rectangle is the same turned by 180 degrees."""
    a = math.fmod(a, 180.0)
    if a > 90.0:
        a -= 180.0
    elif a <= -90.0:
        a += 180.0
    return a + 0.0


def grid_to_map(
    grid: OccupancyGrid,
    *,
    occupied_value: int = 65,
    lines: bool = True,
    min_line_m: float = 0.3,
    yaw: float = 0.0,
    keepout: OccupancyGrid | None = None,
    keepout_yaw: float = 0.0,
) -> MapData:
    """An ARIA map from an occupancy grid (points, wall lines, optional keepout areas).

    Examples:
        >>> g = OccupancyGrid(np.array([[100, 100, 100, 100, 100, 100, 100]], dtype=np.int8),
        ...                   0.05, (0.0, 0.0))
        >>> m = grid_to_map(g)
        >>> m.scan.num_points, m.lines.tolist(), m.scan.resolution
        (7, [[25, 25, 325, 25]], 50)
    """
    if not (math.isfinite(min_line_m) and min_line_m >= 0):
        raise RasterError(f"min_line_m must be zero or more metres, got {min_line_m!r}")
    _check_extent(grid.resolution, (*grid.origin, yaw), grid.width, grid.height, "<grid>")
    pts = occupied_points(grid, occupied_value=occupied_value, yaw=yaw)
    segs = (
        wall_lines(grid, occupied_value=occupied_value, min_line_m=min_line_m, yaw=yaw)
        if lines
        else np.zeros((0, 4), dtype=np.int64)
    )
    objects: list[MapObject] = []
    if keepout is not None:
        objects = keepout_objects(keepout, yaw=keepout_yaw)
    scan = Scan.from_arrays(pts, segs, resolution=max(1, round(grid.resolution_mm)))
    return MapData(scans=(scan,), objects=tuple(objects))


#: Cells per row band when importing (8 M: the band's image rows and a few masks of its size).
BAND_CELLS = 1 << 23
#: Largest keepout mask read (it is labelled whole).
MAX_KEEPOUT_CELLS = MAX_DECODED_PIXELS
#: ARIA reads coordinates as 32-bit integers (millimetres).
_ARIA_LIMIT_MM = 2**31 - 1


def _check_extent(
    resolution: float, origin: tuple[float, float, float], width: int, height: int, source: str
) -> tuple[float, tuple[float, float]]:
    """Resolution and origin in mm, when the whole map fits ARIA's 32-bit millimetre range.

    Raises:
        RosMapError: Naming ``source``, when some cell would lie beyond it.
    """
    r = _round_mm(resolution)
    origin_mm = (_round_mm(origin[0]), _round_mm(origin[1]))
    corners = np.array([[0, 0], [width, 0], [width, height], [0, height]], dtype=np.float64)
    with np.errstate(all="ignore"):
        xy = _world(r, origin_mm, corners, origin[2]) if math.isfinite(r) else np.array([np.inf])
    if not (np.isfinite(xy).all() and np.abs(xy).max() <= _ARIA_LIMIT_MM):
        raise RosMapError(
            f"the map ({width} x {height} cells of {resolution!r} m from origin "
            f"{origin[0]!r}, {origin[1]!r}) reaches beyond the +-{_ARIA_LIMIT_MM // 1000:,}"
            " m an ARIA map can hold (32-bit millimetres)",
            source=source,
        )
    return r, origin_mm


def _stream_cells(
    src: ImageSource,
    info: RosMapInfo,
    *,
    flavor: Flavor,
    occupied_value: int,
    lines: bool,
    band_rows: int | None,
    progress: Callable[[int, int], None] | None,
    to_world: Callable[[NDArray[np.int64]], NDArray[np.int64]],
) -> tuple[list[NDArray[np.int64]], list[NDArray[np.int64]]]:
    """Occupied points (``to_world`` of their cells) and face cells (row, col), band by band
    from the southern row up."""
    w, h = src.width, src.height
    rows = max(1, band_rows if band_rows else BAND_CELLS // w)
    occupied: list[NDArray[np.int64]] = []
    faces: list[NDArray[np.int64]] = []
    for g0 in range(0, h, rows):
        g1 = min(h, g0 + rows)
        lo, hi = max(0, g0 - 1), min(h, g1 + 1)  # one halo row each side, for the faces
        band = pixel_values(src.read_rows(h - hi, h - lo), info, flavor=flavor)[::-1]
        occ = band >= occupied_value
        a = g0 - lo
        cells = np.argwhere(occ[a : a + g1 - g0]).astype(np.int64)
        cells[:, 0] += g0
        occupied.append(to_world(cells))
        if lines and len(cells):
            f = np.argwhere(_faces(np.pad(occ, 1), a + 1, a + 1 + g1 - g0)).astype(np.int64)
            f[:, 0] += g0
            faces.append(f)
        if progress is not None:
            progress(g1, h)
    return occupied, faces


def import_ros(
    yaml_path: PathLike,
    *,
    keepout: PathLike | None = None,
    flavor: Flavor = "ros1",
    occupied_value: int = 65,
    lines: bool = True,
    min_line_m: float = 0.3,
    band_rows: int | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> MapData:
    """Read a map_server map (and optionally a keepout mask) as an ARIA map.

    The image is read in row bands (binary PGM straight from the file), so memory follows the
    band and the map's occupied cells, not the image: a 20,768 x 13,612 PGM imports in a few
    hundred MB. The result is the same as :func:`grid_to_map` of the whole grid.

    Args:
        yaml_path: The map's YAML.
        keepout: A keepout mask's YAML (Nav2 keepout filter mask); its keepout cells become
            forbidden areas.
        flavor: Read the images as ``ros1`` map_server or ``nav2`` does.
        occupied_value: Cells with at least this value are walls.
        lines: Extract wall lines (else points only).
        min_line_m: Shortest wall line, in metres.
        band_rows: Rows per band (default: about :data:`BAND_CELLS` cells).
        progress: Called after each band with the rows done so far and the image's height.

    Returns:
        The map (category ``2D-Map``).

    Raises:
        RosMapError: For a YAML or image map_server would refuse, or a map beyond what an ARIA
            map can hold.
        RasterError: For bad options.
    """
    if not (math.isfinite(min_line_m) and min_line_m >= 0):
        raise RasterError(f"min_line_m must be zero or more metres, got {min_line_m!r}")
    info = read_ros_yaml(yaml_path, flavor=flavor)
    src = open_map_image(info, flavor=flavor)
    r, origin = _check_extent(info.resolution, info.origin, src.width, src.height, str(info.source))
    minfo, msrc = None, None
    if keepout is not None:  # checked before the long work
        minfo = read_ros_yaml(keepout, flavor=flavor)
        msrc = open_map_image(minfo, flavor=flavor)
        _check_extent(minfo.resolution, minfo.origin, msrc.width, msrc.height, str(minfo.source))
        if msrc.width * msrc.height > MAX_KEEPOUT_CELLS:
            raise RosMapError(
                f"keepout mask of {msrc.width} x {msrc.height} cells: mapkit reads "
                f"masks up to {MAX_KEEPOUT_CELLS:,} cells",
                source=str(msrc.path),
            )
    yaw = info.origin[2]
    if yaw:
        log_.warning(
            "%s: origin yaw %.6g rad: rotating the map by it (most ROS tools ignore yaw)",
            os.fspath(yaml_path),
            yaw,
        )

    def to_world(cells: NDArray[np.int64]) -> NDArray[np.int64]:  # as occupied_points does
        uv = cells[:, ::-1].astype(np.float64) + 0.5
        return np.rint(_world(r, origin, uv, yaw)).astype(np.int64)

    occupied, faces = _stream_cells(
        src,
        info,
        flavor=flavor,
        occupied_value=occupied_value,
        lines=lines,
        band_rows=band_rows,
        progress=progress,
        to_world=to_world,
    )
    pts = np.concatenate(occupied)
    del occupied
    segs = np.zeros((0, 4), dtype=np.int64)
    if lines and faces:
        face_cells = np.concatenate(faces)
        faces.clear()
        keep = _face_lines(face_cells, _min_cells(min_line_m, info.resolution))
        del face_cells
        segs = _line_world(keep, r, origin, yaw)
    objects: list[MapObject] = []
    if minfo is not None and msrc is not None:
        mask = image_to_grid(msrc.read_all(), minfo, flavor=flavor)
        objects = keepout_objects(mask, yaw=minfo.origin[2])
    scan = Scan.from_arrays(pts, segs, resolution=max(1, round(r)))
    return MapData(scans=(scan,), objects=tuple(objects))
