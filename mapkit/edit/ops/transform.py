"""Moving and turning the whole map: rigid motions applied to scans and objects."""

from __future__ import annotations

from collections.abc import Sequence

from mapkit.edit.checks import (
    check_coord,
    check_data_range,
    check_number,
    check_span,
)
from mapkit.edit.geometry import Rigid
from mapkit.edit.ops.common import _check_object_range
from mapkit.edit.ops.data import _update_scan
from mapkit.errors import EditError
from mapkit.model import MapData

__all__ = ["apply_motion", "recenter_motion", "transform", "transform_motion"]


# -- data: transform ---------------------------------------------------------------------------


def recenter_motion(m: MapData) -> Rigid:
    """The translation that puts the centre of the data's box at the origin.

    Rounded to a multiple of the resolution (so lattice points stay on the lattice), or to whole
    millimetres when the map has none. The identity for a map without data.
    """
    boxes = [b for b in (s.data_bounds() for s in m.scans) if b is not None]
    if not boxes:
        return Rigid()
    lo_x = min(b[0][0] for b in boxes)
    lo_y = min(b[0][1] for b in boxes)
    hi_x = max(b[1][0] for b in boxes)
    hi_y = max(b[1][1] for b in boxes)
    res = m.scan.resolution if m.scan.resolution > 0 else 1
    cx = round((lo_x + hi_x) / 2.0 / res) * res
    cy = round((lo_y + hi_y) / 2.0 / res) * res
    return Rigid(0.0, float(-cx), float(-cy))


def transform_motion(
    m: MapData,
    *,
    rotate: float = 0.0,
    translate: Sequence[float] = (0.0, 0.0),
    about: Sequence[float] = (0.0, 0.0),
    recenter: bool = False,
) -> Rigid:
    """The one motion :func:`transform` applies: recenter, rotate about ``about``, translate."""
    rot = check_number(rotate, "rotation")
    if len(translate) != 2 or len(about) != 2:
        raise EditError("a translation and a pivot are 2 numbers each")
    dx, dy = check_number(translate[0], "dx"), check_number(translate[1], "dy")
    px, py = check_coord(about[0], "pivot x"), check_coord(about[1], "pivot y")
    motion = recenter_motion(m) if recenter else Rigid()
    return motion.then(Rigid.about(rot, (px, py))).then(Rigid(0.0, dx, dy))


def apply_motion(m: MapData, motion: Rigid) -> MapData:
    """Move points, lines and every object (active and inactive) by one rigid motion.

    Template children (``ChildCairn:``) are relative to their group and stay. Zero-size anchor
    rectangles at the origin stay. ``OriginLatLongAlt:`` is kept as it is.
    """
    if motion.is_identity:
        return m
    scans = []
    for s in m.scans:
        pts = motion.apply_array(s.points) if s.num_points else None
        lns = motion.apply_array(s.lines) if s.num_lines else None
        for arr, what in ((pts, "points"), (lns, "lines")):
            if arr is not None:
                check_data_range(arr, f"transformed {what}")
        scans.append(
            _update_scan(s, points=pts, lines=lns) if (pts is not None or lns is not None) else s
        )
    objects = []
    inactive = []
    for o in m.objects:
        shape = m.object_shape(o)
        new = motion.apply_object(o, shape)
        _check_object_range(new, shape)
        objects.append(new)
    for o in m.inactive_objects:
        shape = m.object_shape(o)
        new = motion.apply_object(o, shape)
        _check_object_range(new, shape)
        inactive.append(new)
    out = m.replace(scans=tuple(scans), objects=tuple(objects), inactive_objects=tuple(inactive))
    check_span(m, out)
    return out


def transform(
    m: MapData,
    *,
    rotate: float = 0.0,
    translate: Sequence[float] = (0.0, 0.0),
    about: Sequence[float] = (0.0, 0.0),
    recenter: bool = False,
) -> MapData:
    """Move the whole map rigidly: points, lines and every object together; headings follow.

    Order: ``recenter`` (the data box's centre to the origin), then a rotation of ``rotate``
    degrees counter-clockwise about ``about``, then ``translate``. Rectangles keep their exact
    shape (new corners and angle, FORMATS.md A.7.3).

    Examples:
        >>> from mapkit.model import MapData, MapObject, Scan
        >>> m = MapData(scans=(Scan.from_arrays([[1000, 0]], [[0, 0, 1000, 0]]),),
        ...             objects=(MapObject("Dock", 1000, 0, 0, name="D"),))
        >>> t = transform(m, rotate=90, translate=(0, 500))
        >>> t.points.tolist(), t.lines.tolist()
        ([[0, 1500]], [[0, 500, 0, 1500]])
        >>> d = t.objects[0]
        >>> d.x, d.y, d.theta
        (0.0, 1500.0, 90.0)
    """
    return apply_motion(
        m, transform_motion(m, rotate=rotate, translate=translate, about=about, recenter=recenter)
    )
