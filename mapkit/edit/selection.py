"""Regions of the map plane and what lies in them: points (numpy), line segments (shapely).

A :class:`Region` is closed: a point on its border is inside. Points are tested in bulk (numpy
for boxes, shapely's vectorised ``intersects_xy`` for polygons). Segments are cut with shapely's
vectorised ``difference``/``intersection`` on the few segments near the region; the new ends a cut
makes are rounded to whole millimetres (ARIA stores integers) and, where plain rounding would
poke a piece back into the region (or out of it), moved to the nearest integer point that does
not. So after :func:`cut_lines` no segment runs inside the region for any length (more than
:data:`TOUCH`), and after :func:`clip_lines` no segment runs outside it.

shapely is imported inside the functions that use it, so importing mapkit stays fast.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from mapkit._typing import LineArray, PointArray
from mapkit.edit.checks import check_coord
from mapkit.errors import EditError

__all__ = ["Region", "clip_lines", "cut_lines", "lines_overlapping", "points_inside"]

#: Overlap (mm) below which a segment counts as only touching a region.
TOUCH = 1e-6


@dataclass(frozen=True)
class Region:
    """A closed box or polygon in map millimetres.

    Build one with :meth:`box` or :meth:`polygon`; both check their input.

    Attributes:
        vertices: The outline, counter-clockwise or not, without repeating the first vertex.
        is_box: True for an axis-aligned box (faster point tests).

    Examples:
        >>> r = Region.box(1000, 0, 0, 500)
        >>> r.bounds, r.area
        ((0.0, 0.0, 1000.0, 500.0), 500000.0)
        >>> Region.polygon([(0, 0), (10, 0), (0, 10)]).area
        50.0
    """

    vertices: tuple[tuple[float, float], ...]
    is_box: bool = False

    @classmethod
    def box(cls, x1: float, y1: float, x2: float, y2: float) -> Region:
        """An axis-aligned box from two opposite corners (any order).

        Raises:
            EditError: A non-finite or out-of-range coordinate, or a box without area.
        """
        x1, y1, x2, y2 = (
            check_coord(v, f"box {n}")
            for v, n in zip((x1, y1, x2, y2), ("x1", "y1", "x2", "y2"), strict=True)
        )
        if x1 == x2 or y1 == y2:
            raise EditError(f"the box ({x1:g}, {y1:g}) - ({x2:g}, {y2:g}) has no area")
        lo_x, hi_x, lo_y, hi_y = min(x1, x2), max(x1, x2), min(y1, y2), max(y1, y2)
        return cls(((lo_x, lo_y), (hi_x, lo_y), (hi_x, hi_y), (lo_x, hi_y)), is_box=True)

    @classmethod
    def polygon(cls, vertices: Any) -> Region:
        """A simple polygon from its vertices ``[(x, y), ...]`` (at least 3).

        Raises:
            EditError: Too few vertices, bad numbers, self-intersection, or no area.
        """
        import shapely

        try:
            pts = [(float(p[0]), float(p[1])) for p in vertices]
            if any(len(p) != 2 for p in vertices):
                raise TypeError
        except (TypeError, ValueError, IndexError):
            raise EditError(f"a polygon is a list of (x, y) vertices, got {vertices!r}") from None
        for i, (x, y) in enumerate(pts):
            check_coord(x, f"polygon vertex {i + 1} x")
            check_coord(y, f"polygon vertex {i + 1} y")
        if len(pts) > 1 and pts[0] == pts[-1]:
            pts = pts[:-1]
        if len(pts) < 3:
            raise EditError(f"a polygon needs at least 3 vertices, got {len(pts)}")
        geom = shapely.Polygon(pts)
        if not geom.is_valid:
            reason = shapely.is_valid_reason(geom)
            raise EditError(f"the polygon is not simple ({reason}): its edges must not cross")
        if geom.area <= 0:
            raise EditError("the polygon has no area")
        return cls(tuple(pts), is_box=False)

    @classmethod
    def from_spec(cls, box: Any = None, polygon: Any = None) -> Region | None:
        """A region from ``box = (x1, y1, x2, y2)`` or ``polygon = [(x, y), ...]`` (or ``None``).

        Raises:
            EditError: Both given, or either malformed.
        """
        if box is not None and polygon is not None:
            raise EditError("give either a box or a polygon, not both")
        if box is not None:
            if not isinstance(box, (list, tuple)) or len(box) != 4:
                raise EditError(f"a box is [x1, y1, x2, y2], got {box!r}")
            return cls.box(*box)
        return None if polygon is None else cls.polygon(polygon)

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        """``(xmin, ymin, xmax, ymax)``."""
        xs = [p[0] for p in self.vertices]
        ys = [p[1] for p in self.vertices]
        return min(xs), min(ys), max(xs), max(ys)

    @property
    def area(self) -> float:
        """Area in mm² (shoelace formula)."""
        v = self.vertices
        s = sum(
            v[i][0] * v[(i + 1) % len(v)][1] - v[(i + 1) % len(v)][0] * v[i][1]
            for i in range(len(v))
        )
        return abs(s) / 2.0

    def geometry(self) -> Any:
        """The region as a prepared shapely polygon."""
        import shapely

        geom = shapely.Polygon(self.vertices)
        shapely.prepare(geom)
        return geom

    def describe(self) -> str:
        """A short text for messages: ``box (x1, y1) - (x2, y2)`` or ``polygon of N vertices``."""
        if self.is_box:
            x0, y0, x1, y1 = self.bounds
            return f"box ({x0:g}, {y0:g}) - ({x1:g}, {y1:g})"
        return f"polygon of {len(self.vertices)} vertices"

    def to_json(self) -> dict[str, Any]:
        """``{"box": [x1, y1, x2, y2]}`` or ``{"polygon": [[x, y], ...]}``."""
        if self.is_box:
            return {"box": list(self.bounds)}
        return {"polygon": [list(p) for p in self.vertices]}


def points_inside(points: PointArray, region: Region) -> np.ndarray[Any, np.dtype[np.bool_]]:
    """Mask of the points inside the closed region (border included).

    Examples:
        >>> pts = np.array([[0, 0], [5, 5], [10, 10], [11, 0]])
        >>> points_inside(pts, Region.box(0, 0, 10, 10)).tolist()
        [True, True, True, False]
        >>> points_inside(pts, Region.polygon([(0, 0), (10, 0), (0, 10)])).tolist()
        [True, True, False, False]
    """
    x0, y0, x1, y1 = region.bounds
    x = points[:, 0]
    y = points[:, 1]
    mask = (x >= x0) & (x <= x1) & (y >= y0) & (y <= y1)
    if region.is_box or not mask.any():
        return mask
    import shapely

    idx = np.flatnonzero(mask)
    inside = shapely.intersects_xy(region.geometry(), x[idx].astype(float), y[idx].astype(float))
    mask[idx] = inside
    return mask


def _near(lines: LineArray, region: Region) -> np.ndarray[Any, np.dtype[np.intp]]:
    x0, y0, x1, y1 = region.bounds
    lx0 = np.minimum(lines[:, 0], lines[:, 2])
    lx1 = np.maximum(lines[:, 0], lines[:, 2])
    ly0 = np.minimum(lines[:, 1], lines[:, 3])
    ly1 = np.maximum(lines[:, 1], lines[:, 3])
    return np.flatnonzero((lx1 >= x0) & (lx0 <= x1) & (ly1 >= y0) & (ly0 <= y1))


def _segments(rows: np.ndarray[Any, Any]) -> Any:
    import shapely

    return shapely.linestrings(np.asarray(rows, dtype=float).reshape(-1, 2, 2))


def _overlap(rows: np.ndarray[Any, Any], geom: Any) -> np.ndarray[Any, np.dtype[np.float64]]:
    import shapely

    if len(rows) == 0:
        return np.zeros(0)
    segs = _segments(rows)
    # Zero-length rows are points: they overlap nothing.
    return np.asarray(shapely.length(shapely.intersection(segs, geom)), dtype=float)


def lines_overlapping(lines: LineArray, region: Region) -> np.ndarray[Any, np.dtype[np.bool_]]:
    """Mask of the segments that run inside the closed region for some length (not just touch)."""
    mask = np.zeros(len(lines), dtype=bool)
    idx = _near(lines, region)
    if len(idx):
        mask[idx] = _overlap(lines[idx], region.geometry()) > TOUCH
    return mask


def _pieces(
    geoms: Any, parents: np.ndarray[Any, Any]
) -> tuple[np.ndarray[Any, Any], np.ndarray[Any, Any]]:
    """Each linear part's first and last vertex ``(P, 4)`` and the index of its parent row."""
    import shapely

    merged = shapely.line_merge(geoms)
    parts, which = shapely.get_parts(merged, return_index=True)
    keep = shapely.get_type_id(parts) == 1  # LineString (skip points of a touch)
    parts, which = parts[keep], which[keep]
    if len(parts) == 0:
        return np.zeros((0, 4)), np.zeros(0, dtype=np.intp)
    coords, owner = shapely.get_coordinates(parts, return_index=True)
    starts = np.searchsorted(owner, np.arange(len(parts)), side="left")
    ends = np.searchsorted(owner, np.arange(len(parts)), side="right") - 1
    ends_xy = np.concatenate([coords[starts], coords[ends]], axis=1)
    return ends_xy, parents[which]


def _candidates(radius: int) -> np.ndarray[Any, Any]:
    """Integer offsets around floor(p), nearest first is decided per point by the caller."""
    r = np.arange(-radius + 1, radius + 1)
    gx, gy = np.meshgrid(r, r)
    return np.stack([gx.ravel(), gy.ravel()], axis=1)


def _round_pieces(
    pieces: np.ndarray[Any, Any], original: np.ndarray[Any, Any], geom: Any, inside: bool
) -> tuple[np.ndarray[Any, Any], np.ndarray[Any, Any]]:
    """Round the cut ends of pieces to integers that keep each piece on its side of the border."""
    import shapely

    out = pieces.copy()
    ok_rows = np.ones(len(out), dtype=bool)
    offsets = _candidates(2)  # 16 integer points around each cut end
    for end in (0, 1):
        need = np.flatnonzero(~original[:, end])
        if len(need) == 0:
            continue
        e = out[need, 2 * end : 2 * end + 2]
        other = out[need, 2 - 2 * end : 4 - 2 * end]
        base = np.floor(e)
        cand = base[:, None, :] + offsets[None, :, :]  # (n, 16, 2)
        dist = np.hypot(cand[..., 0] - e[:, None, 0], cand[..., 1] - e[:, None, 1])
        order = np.argsort(dist, axis=1, kind="stable")
        cand = np.take_along_axis(cand, order[..., None], axis=1)
        chosen = np.full((len(need), 2), np.nan)
        pending = np.ones(len(need), dtype=bool)
        for k in range(cand.shape[1]):
            if not pending.any():
                break
            rows = np.flatnonzero(pending)
            c = cand[rows, k]
            seg = (
                np.concatenate([other[rows], c], axis=1)
                if end == 1
                else np.concatenate([c, other[rows]], axis=1)
            )
            segs = _segments(seg)
            op = shapely.difference if inside else shapely.intersection
            good = np.asarray(shapely.length(op(segs, geom)), dtype=float) <= TOUCH
            chosen[rows[good]] = c[good]
            pending[rows[good]] = False
        chosen[pending] = np.rint(e[pending])
        ok_rows[need[pending]] = False
        out[need, 2 * end : 2 * end + 2] = chosen
    out = np.rint(out)
    nonzero = (out[:, 0] != out[:, 2]) | (out[:, 1] != out[:, 3])
    keep = ok_rows & nonzero
    return out[keep], keep


def _split(lines: LineArray, region: Region, inside: bool) -> LineArray:
    import shapely

    lines = np.asarray(lines, dtype=np.int64).reshape(-1, 4)
    if len(lines) == 0:
        return lines
    idx = _near(lines, region)
    geom = region.geometry()
    keep_rows = np.zeros(len(lines), dtype=bool) if inside else np.ones(len(lines), dtype=bool)
    if len(idx) == 0:
        return lines[keep_rows]  # type: ignore[no-any-return]
    segs = _segments(lines[idx])
    overlap = np.asarray(shapely.length(shapely.intersection(segs, geom)), dtype=float)
    covered = np.asarray(shapely.covered_by(segs, geom), dtype=bool)
    touching = overlap > TOUCH
    whole = covered & touching
    partial = touching & ~covered
    if inside:
        keep_rows[idx[whole]] = True
    else:
        keep_rows[idx[touching]] = False
    part_idx = idx[partial]
    if len(part_idx) == 0:
        return lines[keep_rows]  # type: ignore[no-any-return]
    op = shapely.intersection if inside else shapely.difference
    ends, parent = _pieces(op(segs[partial], geom), part_idx)
    orig = lines[parent].astype(float)
    start_is_orig = (ends[:, 0:2] == orig[:, 0:2]).all(axis=1) | (ends[:, 0:2] == orig[:, 2:4]).all(
        axis=1
    )
    end_is_orig = (ends[:, 2:4] == orig[:, 0:2]).all(axis=1) | (ends[:, 2:4] == orig[:, 2:4]).all(
        axis=1
    )
    rounded, ok = _round_pieces(ends, np.stack([start_is_orig, end_is_orig], axis=1), geom, inside)
    # Keep file order: each surviving row, with a cut row's pieces in its place.
    kept_idx = np.flatnonzero(keep_rows)
    rows = np.concatenate([lines[kept_idx], rounded.astype(np.int64)])
    order = np.argsort(np.concatenate([kept_idx, parent[ok]]), kind="stable")
    return rows[order]


def cut_lines(lines: LineArray, region: Region) -> LineArray:
    """The segments with every part inside the closed region removed (pieces outside kept).

    Examples:
        >>> lines = np.array([[-10, 5, 20, 5], [0, 20, 5, 20]])
        >>> cut_lines(lines, Region.box(0, 0, 10, 10)).tolist()
        [[-10, 5, 0, 5], [10, 5, 20, 5], [0, 20, 5, 20]]
    """
    return _split(lines, region, inside=False)


def clip_lines(lines: LineArray, region: Region) -> LineArray:
    """The parts of the segments inside the closed region.

    Examples:
        >>> lines = np.array([[-10, 5, 20, 5], [0, 20, 5, 20]])
        >>> clip_lines(lines, Region.box(0, 0, 10, 10)).tolist()
        [[0, 5, 10, 5]]
    """
    return _split(lines, region, inside=True)
