"""What the object edits share: labels, name and range checks, declared types, rotated areas."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from typing import Any

from mapkit.edit.checks import (
    check_coord,
    check_number,
    check_type_name,
)
from mapkit.edit.declared import (
    type_class,
    type_key,
)
from mapkit.edit.geometry import rect_about_centre
from mapkit.errors import EditError
from mapkit.model import MapData, MapObject

__all__ = ["ROTATE_ABOUT", "as_written"]


# -- objects: helpers --------------------------------------------------------------------------


def _label(obj: MapObject) -> str:
    return f"{obj.type} {obj.name!r}" if obj.name else f"unnamed {obj.type}"


def _check_unique(m: MapData, name: str, *, allow_duplicate: bool, skip: int | None = None) -> None:
    if not name or allow_duplicate:
        return
    low = name.lower()
    for i, o in enumerate(m.objects):
        if i != skip and o.name.lower() == low:
            raise EditError(
                f"an object named {name!r} already exists (#{i + 1} {o.type}); names are compared "
                "case-insensitively as ARIA does. Pick another name or allow duplicates "
                "(--allow-duplicate)"
            )


def as_written(obj: MapObject) -> MapObject:
    """The object as ARIA writes it: coordinates to whole mm (``%.0f``), heading to 6 decimals.

    New and moved objects are stored this way, so what an edit reports is what the file holds.

    Examples:
        >>> g = as_written(MapObject("Goal", 1.5, 2.5, 0.1234567, name="g"))
        >>> g.x, g.y, g.theta
        (2.0, 2.0, 0.123457)
    """
    if not obj.is_finite:
        return obj  # inf/nan: ARIA writes it as it is ("inf"), and rounding has no meaning
    ft = None
    if obj.from_to is not None:
        fx, fy, tx, ty = (float(round(v)) for v in obj.from_to)
        ft = (fx, fy, tx, ty)
    x, y = float(round(obj.x)), float(round(obj.y))
    return replace(obj, x=x, y=y, theta=round(obj.theta, 6), from_to=ft)


def _check_object_range(obj: MapObject, shape: str) -> None:
    check_coord(obj.x, f"{_label(obj)}: x")
    check_coord(obj.y, f"{_label(obj)}: y")
    if obj.from_to is not None:
        corners = (
            obj.corners()
            if shape == "rect"
            else ((obj.from_to[0], obj.from_to[1]), (obj.from_to[2], obj.from_to[3]))
        )
        for cx, cy in corners:
            check_coord(cx, f"{_label(obj)}: corner x")
            check_coord(cy, f"{_label(obj)}: corner y")


def _needs_name(m: MapData, type: str) -> bool:
    """Goals and docks need a name (ARIA finds them by it), as do types with NameRequired=1."""
    return (
        type_class(m, type) in ("GoalType", "DockType") or type_key(m, type, "NameRequired") == "1"
    )


def _declared_list(m: MapData) -> str:
    d = m.declared_types()
    return ", ".join(f"{k} ({v})" for k, v in d.items()) or "none"


def _resolve_type(m: MapData, type: str, allow_undeclared: bool) -> str | None:
    check_type_name(type)
    cls = type_class(m, type)
    if cls == "CairnGroupType":
        raise EditError(
            f"{type!r} is a group template (CairnGroupType); mapkit does not add groups"
        )
    if cls is None and not allow_undeclared:
        raise EditError(
            f"type {type!r} is not declared in this map's MapInfo: and is not built into ARIA "
            f"(declared: {_declared_list(m)}). Declare it first, or add it anyway "
            "(--allow-undeclared)"
        )
    return cls


def _area(
    area: Sequence[Any], angle: float, about_centre: bool
) -> tuple[tuple[float, float, float, float], float]:
    if len(area) != 4:
        raise EditError(f"an area is 4 numbers X1 Y1 X2 Y2, got {len(area)}")
    names = ("X1", "Y1", "X2", "Y2")
    x1, y1, x2, y2 = (check_coord(v, f"area {n}") for v, n in zip(area, names, strict=True))
    angle = check_number(angle, "angle")
    if x1 == x2 or y1 == y2:
        raise EditError(
            f"the area ({x1:g}, {y1:g}) - ({x2:g}, {y2:g}) has no area (degenerate rectangle)"
        )
    ft = rect_about_centre(x1, y1, x2, y2, angle) if about_centre else (x1, y1, x2, y2)
    return ft, angle


ROTATE_ABOUT = ("centre", "origin")


def _about_centre(rotate_about: str, rotate_about_centre: bool | None) -> bool:
    """Whether an area's ``angle`` turns it about its own centre (the default) or the origin."""
    if rotate_about == "center":
        rotate_about = "centre"
    if rotate_about not in ROTATE_ABOUT:
        raise EditError(f"rotate about {rotate_about!r}: give 'centre' or 'origin'")
    if rotate_about_centre is None:
        return rotate_about == "centre"
    if not rotate_about_centre and rotate_about == "centre":
        return False  # the old spelling of "about the origin": rotate_about_centre=False
    if rotate_about_centre and rotate_about == "origin":
        raise EditError("rotate about the centre or the origin, not both")
    return True


def _segment(line: Sequence[Any], what: str = "line") -> tuple[float, float, float, float]:
    if len(line) != 4:
        raise EditError(f"a {what} is 4 numbers X1 Y1 X2 Y2, got {len(line)}")
    names = ("X1", "Y1", "X2", "Y2")
    x1, y1, x2, y2 = (check_coord(v, f"{what} {n}") for v, n in zip(line, names, strict=True))
    if x1 == x2 and y1 == y2:
        raise EditError(f"the {what} ({x1:g}, {y1:g}) - ({x2:g}, {y2:g}) has no length")
    return x1, y1, x2, y2


_SHAPE_WORDS = {"point": "a position", "rect": "an area", "line": "a line"}
