"""Editing the scan data: erase a region, draw a line, crop."""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import replace
from typing import Any

import numpy as np

from mapkit.edit.checks import (
    check_data_range,
    check_span,
)
from mapkit.edit.geometry import is_anchor
from mapkit.edit.ops.common import _segment
from mapkit.edit.ops.objects import _drop_orphan_params
from mapkit.edit.rows import first_occurrences, isin_rows
from mapkit.edit.selection import Region, clip_lines, cut_lines, points_inside
from mapkit.errors import EditError
from mapkit.model import MapData, MapObject, Scan

__all__ = ["crop", "draw_line", "erase", "rows_not_in"]


# -- data: helpers -----------------------------------------------------------------------------


def _sort_rows(a: np.ndarray[Any, Any]) -> np.ndarray[Any, Any]:
    if len(a) == 0:
        return a
    keys = tuple(a[:, k] for k in reversed(range(a.shape[1])))
    return a[np.lexsort(keys)]


def _update_scan(scan: Scan, points: Any = None, lines: Any = None) -> Scan:
    """New data for a scan, boxes recomputed; an array flagged sorted is sorted (and stays flagged).

    Arrays not flagged keep the order given, so erasing keeps the file order of what is left.
    """
    ps, ls = scan.points_sorted, scan.lines_sorted
    if points is not None and ps:
        points = _sort_rows(np.asarray(points))
    if lines is not None and ls:
        lines = _sort_rows(np.asarray(lines))
    new = scan.with_data(points=points, lines=lines)
    return replace(new, points_sorted=ps, lines_sorted=ls)


def _scan_indices(m: MapData, sources: Iterable[str] | None) -> list[int]:
    if sources is None:
        return list(range(len(m.scans)))
    out = []
    for s in sources:
        hits = [
            i
            for i, sc in enumerate(m.scans)
            if sc.name.lower() == s.lower() or (s == "" and sc.is_default)
        ]
        if not hits:
            raise EditError(
                f"no scan source {s!r}; the map has {', '.join(repr(sc.name) for sc in m.scans)}"
            )
        out.extend(hits)
    return sorted(set(out))


def rows_not_in(
    a: np.ndarray[Any, Any], b: np.ndarray[Any, Any]
) -> np.ndarray[Any, np.dtype[np.bool_]]:
    """Mask of the rows of ``a`` that do not occur in ``b`` (vectorised)."""
    return ~isin_rows(a, b)


# -- data: erase, draw, crop -------------------------------------------------------------------


def erase(m: MapData, region: Region, *, sources: Iterable[str] | None = None) -> MapData:
    """Remove the points inside a closed region and cut away the parts of lines inside it.

    Objects are not touched. Scans the region misses are kept as they are.

    Args:
        m: The map.
        region: A :class:`~mapkit.edit.selection.Region`.
        sources: Scan sources to erase from (default: all).
    """
    if not isinstance(region, Region):
        raise EditError(f"erase needs a Region, got {region!r}")
    scans = list(m.scans)
    for i in _scan_indices(m, sources):
        s = scans[i]
        inside = points_inside(s.points, region)
        new_lines = cut_lines(s.lines, region)
        changed_lines = len(new_lines) != len(s.lines) or not np.array_equal(new_lines, s.lines)
        if inside.any() or changed_lines:
            scans[i] = _update_scan(
                s,
                points=s.points[~inside] if inside.any() else None,
                lines=new_lines if changed_lines else None,
            )
    if all(a is b for a, b in zip(scans, m.scans, strict=False)):
        return m
    return m.replace(scans=tuple(scans))


def draw_line(
    m: MapData,
    x1: float,
    y1: float,
    x2: float,
    y2: float,
    *,
    source: str | None = None,
    as_points: bool = False,
) -> MapData:
    """Add a line segment to the map data (``LINES``), or, ``as_points``, a row of points.

    Points are placed every ``Resolution`` mm (20 when the map has none) on the resolution
    lattice, as a scanned map's points are; ones already present are not repeated.
    """
    ax, ay, bx, by_ = _segment((x1, y1, x2, y2))
    idx = _scan_indices(m, None if source is None else [source])[0]
    s = m.scans[idx]
    if as_points:
        res = s.resolution if s.resolution > 0 else 20
        n = int(np.ceil(np.hypot(bx - ax, by_ - ay) / res)) + 1
        t = np.linspace(0.0, 1.0, n)
        pts = np.stack([ax + t * (bx - ax), ay + t * (by_ - ay)], axis=1)
        pts = (np.rint(pts / res) * res).astype(np.int64)
        pts = pts[first_occurrences(pts)]
        pts = pts[rows_not_in(pts, s.points)]
        if len(pts) == 0:
            return m
        check_data_range(pts, "draw-line")
        new = _update_scan(s, points=np.concatenate([s.points, pts]))
    else:
        row = np.rint(np.array([[ax, ay, bx, by_]])).astype(np.int64)
        new = _update_scan(s, lines=np.concatenate([s.lines, row]))
    out = m.with_scan(new, idx)
    check_span(m, out)
    return out


def _object_overlaps(m: MapData, obj: MapObject, region: Region) -> bool:
    import shapely

    shape = m.object_shape(obj)
    geom = region.geometry()
    if shape == "point":
        return bool(shapely.intersects_xy(geom, obj.x, obj.y))  # False for inf or nan
    if not obj.is_finite:
        return False  # at infinity: outside every region
    if shape == "line":
        assert obj.from_to is not None
        fx, fy, tx, ty = obj.from_to
        return bool(shapely.intersects(geom, shapely.LineString([(fx, fy), (tx, ty)])))
    return bool(shapely.intersects(geom, shapely.Polygon(obj.corners()).buffer(0)))


def crop(m: MapData, region: Region, *, keep_objects: bool = False) -> MapData:
    """Keep only the data inside a closed region; drop the objects wholly outside it.

    Args:
        m: The map.
        region: What to keep.
        keep_objects: Keep every object, even those outside.
    """
    if not isinstance(region, Region):
        raise EditError(f"crop needs a Region, got {region!r}")
    scans = []
    for s in m.scans:
        inside = points_inside(s.points, region)
        new_lines = clip_lines(s.lines, region)
        same_lines = len(new_lines) == len(s.lines) and np.array_equal(new_lines, s.lines)
        if inside.all() and same_lines:
            scans.append(s)
            continue
        scans.append(
            _update_scan(
                s,
                points=None if inside.all() else s.points[inside],
                lines=None if same_lines else new_lines,
            )
        )
    out = m.replace(scans=tuple(scans))
    if keep_objects:
        return out
    gone = [o for o in m.objects if not is_anchor(o) and not _object_overlaps(m, o, region)]
    if not gone:
        return out
    gone_ids = {id(o) for o in gone}
    out = out.replace(objects=tuple(o for o in m.objects if id(o) not in gone_ids))
    return _drop_orphan_params(out, [o.name for o in gone])
