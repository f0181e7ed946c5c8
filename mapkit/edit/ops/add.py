"""Adding objects: goals, docks, the robot's home, forbidden areas and lines, any declared type."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from mapkit.edit.checks import (
    check_coord,
    check_name,
    check_number,
    check_text,
)
from mapkit.edit.declared import (
    params_for_new_object,
    shape_of_class,
    type_class,
    type_key,
    with_params,
)
from mapkit.edit.ops.common import (
    _SHAPE_WORDS,
    _about_centre,
    _area,
    _check_object_range,
    _check_unique,
    _needs_name,
    _resolve_type,
    _segment,
    as_written,
)
from mapkit.errors import EditError
from mapkit.model import MapData, MapObject

__all__ = ["add_dock", "add_goal", "add_home", "add_object", "forbid", "forbid_area", "forbid_line"]


# -- objects: add ------------------------------------------------------------------------------


def add_object(
    m: MapData,
    type: str,
    *,
    at: Sequence[float] | None = None,
    heading: float | None = None,
    area: Sequence[float] | None = None,
    angle: float = 0.0,
    rotate_about: str = "centre",
    rotate_about_centre: bool | None = None,
    line: Sequence[float] | None = None,
    name: str = "",
    description: str = "",
    icon: str = "ICON",
    params: Mapping[str, Any] | None = None,
    allow_undeclared: bool = False,
    allow_duplicate: bool = False,
) -> MapData:
    """Add one object of any type: a point (``at``), a rectangle (``area``) or a line (``line``).

    The shape must fit the type's class: goal, dock and location types are points, sector
    types rectangles, boundary types lines (``RobotHome`` may be a point or a rectangle). A
    rectangle is stored as ARIA stores it: corners in a frame turned by ``angle`` about the map
    origin. By default the box given is turned about its own centre (what a person drawing it
    means: the corners are computed so it stays where it was drawn); ``rotate_about="origin"``
    turns the given corners about the map origin instead (ARIA's storage rule, the box moves). A
    goal type given a heading becomes its ``...WithHeading`` form. Parameters (``MapInfo:
    ArgDesc``) are written to a ``CairnInfo: Params`` line, missing ones with their defaults.

    Args:
        m: The map.
        type: Object type (``Goal``, ``ForbiddenArea``, a declared ``SectorType`` ...).
        at: ``(x, y)`` of a point object, mm.
        heading: Heading of a point object, degrees.
        area: ``(x1, y1, x2, y2)`` corners of a rectangle, mm.
        angle: Rectangle angle, degrees.
        rotate_about: ``"centre"`` (default): turn the rectangle about its own centre;
            ``"origin"``: about the map origin, as ARIA stores it.
        rotate_about_centre: The older spelling: ``True`` is ``"centre"``, ``False`` is
            ``"origin"``.
        line: ``(x1, y1, x2, y2)`` ends of a line object, mm.
        name: Object name.
        description: Free text.
        icon: ARIA's icon token.
        params: Parameter values by name.
        allow_undeclared: Accept a type the map does not declare.
        allow_duplicate: Accept a name another object has.

    Returns:
        The new map, with the object appended after the existing ones.

    Raises:
        EditError: Any bad input (type, name, numbers, shape, parameters, duplicates).
    """
    cls = _resolve_type(m, type, allow_undeclared)
    given = [k for k, v in (("at", at), ("area", area), ("line", line)) if v is not None]
    if len(given) != 1:
        raise EditError(
            f"give exactly one of a position, an area or a line for {type!r} (got "
            f"{', '.join(given) or 'none'})"
        )
    shape = {"at": "point", "area": "rect", "line": "line"}[given[0]]
    want = shape_of_class(cls)
    if cls == "RobotHome":
        want = None if shape in ("point", "rect") else "point or area"
    if want is not None and want != shape:
        raise EditError(
            f"{type!r} is a {cls}: it takes {_SHAPE_WORDS.get(want, want)}, "
            f"not {_SHAPE_WORDS[shape]}"
        )
    name = check_name(name)
    description = check_text(description, "description")
    if not isinstance(icon, str) or not icon or any(c.isspace() or c == '"' for c in icon):
        raise EditError(f"icon {icon!r} must be one word without spaces or quotes")
    if not name and _needs_name(m, type):
        raise EditError(f"a {type} needs a name")
    if heading is not None and shape != "point":
        raise EditError(f"only point objects have a heading; use angle for an area ({type!r})")
    if shape == "point":
        assert at is not None
        if len(at) != 2:
            raise EditError(f"a position is 2 numbers X Y, got {len(at)}")
        x, y = check_coord(at[0], "x"), check_coord(at[1], "y")
        theta = 0.0
        if heading is not None:
            theta = check_number(heading, "heading")
            if type_key(m, type, "Heading") == "Never":
                raise EditError(f"type {type!r} is declared with Heading=Never")
            if cls == "GoalType" and not type.endswith("WithHeading"):
                type = type + "WithHeading"
        obj = MapObject(type, x, y, theta, name=name, description=description, icon=icon)
    elif shape == "rect":
        assert area is not None
        ft, theta = _area(area, angle, _about_centre(rotate_about, rotate_about_centre))
        obj = MapObject(
            type, 0, 0, theta, name=name, description=description, icon=icon, from_to=ft
        )
    else:
        assert line is not None
        x1, y1, x2, y2 = _segment(line)
        obj = MapObject(
            type, x1, y1, 0, name=name, description=description, icon=icon, from_to=(x1, y1, x2, y2)
        )
    obj = as_written(obj)
    _check_object_range(obj, shape)
    _check_unique(m, name, allow_duplicate=allow_duplicate)
    params_line = params_for_new_object(m, obj.type, name, params)
    out = m.replace(objects=(*m.objects, obj))
    return with_params(out, params_line) if params_line else out


def add_goal(
    m: MapData,
    name: str,
    x: float,
    y: float,
    *,
    heading: float | None = None,
    description: str = "",
    type: str = "Goal",
    params: Mapping[str, Any] | None = None,
    allow_undeclared: bool = False,
    allow_duplicate: bool = False,
) -> MapData:
    """Add a goal: ``Goal``, ``GoalWithHeading`` when a heading is given, or a declared goal type.

    Examples:
        >>> from mapkit.model import MapData
        >>> g = add_goal(MapData(), "Desk", 1000, 0, heading=-90).objects[0]
        >>> g.type, g.x, g.y, g.theta, g.name
        ('GoalWithHeading', 1000.0, 0.0, -90.0, 'Desk')
    """
    return _add_point(
        m,
        "GoalType",
        type,
        name,
        x,
        y,
        heading,
        description,
        params,
        allow_undeclared,
        allow_duplicate,
    )


def add_dock(
    m: MapData,
    name: str,
    x: float,
    y: float,
    *,
    heading: float | None = None,
    description: str = "",
    type: str = "Dock",
    params: Mapping[str, Any] | None = None,
    allow_undeclared: bool = False,
    allow_duplicate: bool = False,
) -> MapData:
    """Add a dock (``Dock`` or a declared dock type); the heading is the docking direction."""
    return _add_point(
        m,
        "DockType",
        type,
        name,
        x,
        y,
        0.0 if heading is None else heading,
        description,
        params,
        allow_undeclared,
        allow_duplicate,
    )


def _add_point(
    m: MapData,
    cls: str,
    type: str,
    name: str,
    x: float,
    y: float,
    heading: float | None,
    description: str,
    params: Mapping[str, Any] | None,
    allow_undeclared: bool,
    allow_duplicate: bool,
) -> MapData:
    """A point object whose type must be of class ``cls`` (or undeclared, when allowed)."""
    if _resolve_type(m, type, allow_undeclared) not in (cls, None):
        raise EditError(f"{type!r} is not a {cls[:-4].lower()} type ({type_class(m, type)})")
    return add_object(
        m,
        type,
        at=(x, y),
        heading=heading,
        name=name,
        description=description,
        params=params,
        allow_undeclared=allow_undeclared,
        allow_duplicate=allow_duplicate,
    )


def add_home(
    m: MapData,
    x: float | None = None,
    y: float | None = None,
    *,
    heading: float | None = None,
    area: Sequence[float] | None = None,
    angle: float = 0.0,
    rotate_about: str = "centre",
    rotate_about_centre: bool | None = None,
    name: str = "",
    description: str = "",
    allow_duplicate: bool = False,
) -> MapData:
    """Add a ``RobotHome``: a start pose (``x``, ``y``, ``heading``) or a region (``area``)."""
    if area is not None:
        if x is not None or y is not None or heading is not None:
            raise EditError("give a home either a position (X Y, heading) or an area, not both")
        return add_object(
            m,
            "RobotHome",
            area=area,
            angle=angle,
            rotate_about=rotate_about,
            rotate_about_centre=rotate_about_centre,
            name=name,
            description=description,
            allow_duplicate=allow_duplicate,
        )
    if x is None or y is None:
        raise EditError("a home needs a position X Y or an area")
    return add_object(
        m,
        "RobotHome",
        at=(x, y),
        heading=0.0 if heading is None else heading,
        name=name,
        description=description,
        allow_duplicate=allow_duplicate,
    )


def forbid(
    m: MapData,
    *,
    area: Sequence[float] | None = None,
    line: Sequence[float] | None = None,
    angle: float = 0.0,
    rotate_about: str = "centre",
    rotate_about_centre: bool | None = None,
    name: str = "",
    description: str = "",
    allow_duplicate: bool = False,
) -> MapData:
    """Add a ``ForbiddenArea`` (``area``) or a ``ForbiddenLine`` (``line``): ``mapkit forbid``.

    See :func:`add_object` for ``angle`` and ``rotate_about`` (default: the area's own centre).
    """
    if (area is None) == (line is None):
        raise EditError("forbid takes either an area or a line (X1 Y1 X2 Y2)")
    if line is not None and angle:
        raise EditError("a forbidden line has no angle")
    kind = "ForbiddenArea" if area is not None else "ForbiddenLine"
    return add_object(
        m,
        kind,
        area=area,
        line=line,
        angle=angle,
        rotate_about=rotate_about,
        rotate_about_centre=rotate_about_centre,
        name=name,
        description=description,
        allow_duplicate=allow_duplicate,
    )


def forbid_area(
    m: MapData,
    x1: float,
    y1: float,
    x2: float,
    y2: float,
    *,
    angle: float = 0.0,
    rotate_about: str = "centre",
    rotate_about_centre: bool | None = None,
    name: str = "",
    description: str = "",
    allow_duplicate: bool = False,
) -> MapData:
    """Add a ``ForbiddenArea`` with corners ``(x1, y1)``, ``(x2, y2)`` (see :func:`forbid`)."""
    return forbid(
        m,
        area=(x1, y1, x2, y2),
        angle=angle,
        rotate_about=rotate_about,
        rotate_about_centre=rotate_about_centre,
        name=name,
        description=description,
        allow_duplicate=allow_duplicate,
    )


def forbid_line(
    m: MapData,
    x1: float,
    y1: float,
    x2: float,
    y2: float,
    *,
    name: str = "",
    description: str = "",
    allow_duplicate: bool = False,
) -> MapData:
    """Add a ``ForbiddenLine`` from ``(x1, y1)`` to ``(x2, y2)``."""
    return forbid(
        m,
        line=(x1, y1, x2, y2),
        name=name,
        description=description,
        allow_duplicate=allow_duplicate,
    )
