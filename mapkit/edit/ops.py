"""Edits: pure functions from a :class:`~mapkit.model.MapData` to a new one.

Every function checks its input and raises :class:`~mapkit.errors.EditError` with a clear
message before anything is built, so a refused edit changes nothing. Everything an edit does not
touch is carried over as the same value: object order, unknown lines, info sections, and (for
edits of objects only) the scans themselves, so the file's other bytes stay identical.

Objects are picked by a *selector*: a name, compared case-insensitively as ARIA does, or ``#N``,
the N-th active object (1-based, the numbering ``mapkit objects`` shows). A name several objects
share must be narrowed by ``type`` or replaced by ``#N``.

Examples:
    >>> from mapkit.formats.map import loads, dumps
    >>> m = loads("2D-Map\\nDATA\\n")
    >>> m = add_goal(m, "Kitchen", 1000, 2000, heading=90)
    >>> m = forbid_area(m, 0, 0, 2000, 1000, angle=30, rotate_about_centre=True, name="Stairs")
    >>> [(o.type, o.name) for o in m.objects]
    [('GoalWithHeading', 'Kitchen'), ('ForbiddenArea', 'Stairs')]
    >>> m = rename(move(m, "kitchen", 1500, 2000), "Kitchen", "Galley")
    >>> print(dumps(remove(m, "Stairs")), end="")
    2D-Map
    Resolution: 0
    Cairn: GoalWithHeading 1500 2000 90.000000 "" ICON "Galley"
    DATA
"""

from __future__ import annotations

import difflib
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import replace
from typing import Any

import numpy as np

from mapkit._text import plural
from mapkit.edit.checks import (
    check_coord,
    check_data_range,
    check_name,
    check_number,
    check_span,
    check_text,
    check_type_name,
)
from mapkit.edit.declared import (
    params_for_new_object,
    rename_params,
    shape_of_class,
    type_class,
    type_key,
    unquote,
    with_params,
    without_params,
)
from mapkit.edit.geometry import Rigid, is_anchor, object_centre, rect_about_centre
from mapkit.edit.rows import first_occurrences, isin_rows
from mapkit.edit.selection import Region, clip_lines, cut_lines, points_inside
from mapkit.errors import EditError
from mapkit.model import INFO_KEYWORDS, MapData, MapObject, Scan

__all__ = [
    "CLASH_POLICIES",
    "add_dock",
    "add_goal",
    "add_home",
    "add_object",
    "apply_motion",
    "crop",
    "draw_line",
    "erase",
    "forbid",
    "forbid_area",
    "forbid_line",
    "merge",
    "merge_clashes",
    "move",
    "name_references",
    "recenter_motion",
    "remove",
    "rename",
    "select",
    "transform",
    "transform_motion",
]

#: What :func:`merge` does with an object of OTHER whose name a different BASE object has.
CLASH_POLICIES = ("keep", "rename", "base", "other", "error")


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
    turns the given corners about the map origin instead (ARIA's storage rule, the box moves). A goal type given a heading becomes its
    ``...WithHeading`` form. Parameters (``MapInfo: ArgDesc``) are written to a ``CairnInfo:
    Params`` line, missing ones with their defaults.

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


# -- objects: select, remove, rename, move -------------------------------------------------------


def _type_matches(obj: MapObject, type: str | None) -> bool:
    if type is None:
        return True
    t = type.lower()
    return obj.type.lower() == t or obj.base_type.lower() == t


def select(m: MapData, selector: str, *, type: str | None = None) -> list[int]:
    """Indices (0-based) of the active objects a selector names; never empty.

    Args:
        m: The map.
        selector: A name (case-insensitive) or ``#N`` (1-based position).
        type: Only objects of this type (or base type, so ``Goal`` includes ``GoalWithHeading``).

    Raises:
        EditError: Nothing matches (with the nearest names), or ``#N`` is out of range.

    Examples:
        >>> from mapkit.model import MapData
        >>> a, b = MapObject("Goal", 0, 0, name="A"), MapObject("GoalWithHeading", 1, 1, name="a")
        >>> m = MapData(objects=(a, b))
        >>> select(m, "A"), select(m, "#2"), select(m, "a", type="GoalWithHeading")
        ([0, 1], [1], [1])
    """
    if not isinstance(selector, str):
        raise EditError(f"an object is picked by name or #N, got {selector!r}")
    if selector.startswith("#") and selector[1:].isdigit():
        n = int(selector[1:])
        if not 1 <= n <= len(m.objects):
            raise EditError(
                f"there is no object {selector}: the map has {plural(len(m.objects), 'object')}"
            )
        if not _type_matches(m.objects[n - 1], type):
            raise EditError(f"object {selector} is a {m.objects[n - 1].type}, not a {type}")
        return [n - 1]
    low = selector.lower()
    hits = [i for i, o in enumerate(m.objects) if o.name.lower() == low and _type_matches(o, type)]
    if not hits:
        names = sorted({o.name for o in m.objects if o.name})
        close = difflib.get_close_matches(selector, names, n=3, cutoff=0.6)
        hint = f"; did you mean {', '.join(repr(c) for c in close)}?" if close else ""
        of_type = f" of type {type}" if type else ""
        raise EditError(f"no object named {selector!r}{of_type} in the map{hint}")
    return hits


def _select_one(m: MapData, selector: str, type: str | None) -> int:
    hits = select(m, selector, type=type)
    if len(hits) > 1:
        listed = ", ".join(f"#{i + 1} {m.objects[i].type}" for i in hits[:8])
        more = f" and {len(hits) - 8} more" if len(hits) > 8 else ""
        raise EditError(
            f"{len(hits)} objects are named {selector!r} ({listed}{more}); pick one with #N "
            "(see mapkit objects) or narrow with a type"
        )
    return hits[0]


def _drop_orphan_params(m: MapData, names: Iterable[str]) -> MapData:
    remaining = {o.name.lower() for o in m.objects}
    for n in {x.lower(): x for x in names if x}.values():
        if n.lower() not in remaining:
            m = without_params(m, n)
    return m


def remove(
    m: MapData, *selectors: str, type: str | None = None, all_matches: bool = False
) -> MapData:
    """Remove objects (and their ``CairnInfo: Params`` lines).

    Args:
        m: The map.
        *selectors: Names or ``#N``.
        type: Only objects of this type.
        all_matches: Remove every object a shared name picks (otherwise that is an error).

    Raises:
        EditError: No selector, an unknown name, or an ambiguous one.
    """
    if not selectors:
        raise EditError("name at least one object to remove")
    doomed: set[int] = set()
    for sel in selectors:
        doomed.update(select(m, sel, type=type) if all_matches else [_select_one(m, sel, type)])
    removed = [m.objects[i].name for i in doomed]
    out = m.replace(objects=tuple(o for i, o in enumerate(m.objects) if i not in doomed))
    return _drop_orphan_params(out, removed)


def rename(
    m: MapData,
    name: str,
    new_name: str,
    *,
    type: str | None = None,
    allow_duplicate: bool = False,
) -> MapData:
    """Rename one object (``name`` or ``#N``); its ``CairnInfo: Params`` line follows the new name.

    Other info lines that mention the old name (routes, tasks) are left as they are: see
    :func:`name_references`.
    """
    i = _select_one(m, name, type)
    new_name = check_name(new_name, "new name")
    obj = m.objects[i]
    if not new_name and _needs_name(m, obj.type):
        raise EditError(f"a {obj.type} needs a name")
    _check_unique(m, new_name, allow_duplicate=allow_duplicate, skip=i)
    objects = list(m.objects)
    objects[i] = replace(obj, name=new_name)
    out = m.replace(objects=tuple(objects))
    if obj.name and obj.name.lower() != new_name.lower() and new_name:
        shared = any(o.name.lower() == obj.name.lower() for j, o in enumerate(m.objects) if j != i)
        out = rename_params(out, obj.name, new_name, keep_old=shared)
    elif obj.name and not new_name:
        out = _drop_orphan_params(out, [obj.name])
    elif obj.name != new_name and obj.name.lower() == new_name.lower():
        out = rename_params(out, obj.name, new_name)
    return out


def move(
    m: MapData,
    name: str,
    x: float | None = None,
    y: float | None = None,
    *,
    by: Sequence[float] | None = None,
    heading: float | None = None,
    type: str | None = None,
) -> MapData:
    """Move one object (``name`` or ``#N``) to ``(x, y)`` or by ``by = (dx, dy)``; set its heading.

    A point object's position is ``(x, y)``; a line or rectangle is moved so that its centre is
    there (its size and turn kept). A rectangle's ``heading`` turns it about its own centre to that
    world angle; lines have none. A ``Goal`` given a heading becomes ``GoalWithHeading``.

    Raises:
        EditError: Unknown or ambiguous selector, bad numbers, or both ``(x, y)`` and ``by``.
    """
    i = _select_one(m, name, type)
    obj = m.objects[i]
    shape = m.object_shape(obj)
    if (x is None) != (y is None):
        raise EditError("give both X and Y")
    if x is not None and by is not None:
        raise EditError("give either a position X Y or an offset, not both")
    if x is None and by is None and heading is None:
        raise EditError("nothing to do: give a position, an offset or a heading")
    cx, cy = object_centre(obj, shape)
    if x is not None:
        dx, dy = check_coord(x, "x") - cx, check_coord(y, "y") - cy
    elif by is not None:
        if len(by) != 2:
            raise EditError(f"an offset is 2 numbers DX DY, got {len(by)}")
        dx, dy = check_number(by[0], "dx"), check_number(by[1], "dy")
    else:
        dx = dy = 0.0
    new = Rigid(0.0, dx, dy).apply_object(obj, shape) if (dx or dy) else obj
    if heading is not None:
        h = check_number(heading, "heading")
        if shape == "line":
            raise EditError(f"{_label(obj)} is a line: it has no heading")
        if shape == "point":
            t = new.type
            if type_class(m, t) == "GoalType" and not t.endswith("WithHeading"):
                t += "WithHeading"
            new = replace(new, theta=h, type=t)
        else:
            ncx, ncy = object_centre(new, shape)
            new = Rigid.about(h - new.theta, (ncx, ncy)).apply_object(new, shape)
    new = as_written(new)
    _check_object_range(new, shape)
    objects = list(m.objects)
    objects[i] = new
    return m.replace(objects=tuple(objects))


def name_references(m: MapData, name: str) -> list[tuple[str, int, tuple[str, ...]]]:
    """Info lines (other than ``CairnInfo: Params``) that mention a name as a whole token.

    Returns:
        ``(section, index in the section, line)`` for each, e.g. ``("RouteInfo", 2, ('GoalAfter',
        '"Goal1"'))``.
    """
    if not name:
        return []
    out = []
    for key in INFO_KEYWORDS:
        for j, line in enumerate(m.info.get(key, ())):
            if key == "CairnInfo" and line and line[0] == "Params":
                continue
            if any(unquote(tok) == name for tok in line[1:]):
                out.append((key, j, line))
    return out


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
        >>> from mapkit.model import MapData
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


# -- merge -------------------------------------------------------------------------------------


def merge_clashes(base: MapData, other: MapData) -> list[tuple[MapObject, MapObject]]:
    """Pairs ``(base object, other object)`` with the same name (case-insensitive) that differ."""
    by_name: dict[str, list[MapObject]] = {}
    for o in base.objects:
        if o.name:
            by_name.setdefault(o.name.lower(), []).append(o)
    out = []
    for o in other.objects:
        for b in by_name.get(o.name.lower(), []) if o.name else []:
            if b != o:
                out.append((b, o))
    return out


def _free_name(name: str, taken: set[str]) -> str:
    k = 2
    while f"{name} {k}".lower() in taken:
        k += 1
    return f"{name} {k}"


def _merge_mapinfo(base: MapData, other: MapData) -> tuple[tuple[str, ...], ...]:
    """Base's MapInfo lines plus other's type declarations (with their ArgDesc lines) base lacks."""
    have = set(base.declared_types())
    lines = list(base.info.get("MapInfo", ()))
    adding = False
    for line in other.info.get("MapInfo", ()):
        if line and line[0].endswith("Type"):
            name = next((unquote(t)[5:] for t in line[1:] if unquote(t).startswith("Name=")), None)
            adding = name is not None and name not in have
        elif not (line and line[0] == "ArgDesc"):
            adding = False
        if adding:
            lines.append(line)
    return tuple(lines)


def merge(
    base: MapData, other: MapData, *, region: Region | None = None, on_clash: str = "keep"
) -> MapData:
    """Mapper3's Insert Map: data from OTHER goes into BASE; objects of both are kept.

    With a ``region``, the data inside it comes from OTHER (BASE's points and line parts there are
    removed) and the rest from BASE; without one, OTHER's points and lines are added (rows BASE
    already has are not repeated). Scans are matched by source name (primary with primary).

    OTHER's objects are appended; an object equal to one BASE has is not repeated. Name clashes
    (same name, different object, see :func:`merge_clashes`) follow ``on_clash``: ``keep`` both,
    ``rename`` OTHER's (``"Name 2"``), keep ``base``'s only, keep ``other``'s only, or ``error``.
    Type declarations and ``CairnInfo: Params`` lines that OTHER's objects need are added; every
    other info section is BASE's.

    Raises:
        EditError: A bad policy, a clash with ``error``, data out of range, or an OTHER source
            BASE cannot take.
    """
    if on_clash not in CLASH_POLICIES:
        raise EditError(f"on_clash must be one of {', '.join(CLASH_POLICIES)}, got {on_clash!r}")
    if region is not None and not isinstance(region, Region):
        raise EditError(f"merge needs a Region, got {region!r}")
    # Data.
    scans = list(base.scans)
    for j, os_ in enumerate(other.scans):
        if j == 0:
            i: int | None = 0
        else:
            i = next((k for k, s in enumerate(scans) if s.name.lower() == os_.name.lower()), None)
        if i is None:
            if any(s.name == "" for s in scans):
                raise EditError(
                    f"OTHER has a scan source {os_.name!r} that BASE lacks, and BASE's "
                    "sources have no names to put it beside"
                )
            scans.append(Scan(name=os_.name, display=os_.display, resolution=os_.resolution))
            i = len(scans) - 1
        bs = scans[i]
        if region is not None:
            keep_base = ~points_inside(bs.points, region)
            take = points_inside(os_.points, region)
            pts = np.concatenate([bs.points[keep_base], os_.points[take]])
            lns = np.concatenate([cut_lines(bs.lines, region), clip_lines(os_.lines, region)])
        else:
            add_p = os_.points[rows_not_in(os_.points, bs.points)]
            add_l = os_.lines[rows_not_in(os_.lines, bs.lines)]
            check_data_range(add_p, "OTHER's points")
            check_data_range(add_l, "OTHER's lines")
            pts = np.concatenate([bs.points, add_p])
            lns = np.concatenate([bs.lines, add_l])
        same_p = len(pts) == len(bs.points) and np.array_equal(pts, bs.points)
        same_l = len(lns) == len(bs.lines) and np.array_equal(lns, bs.lines)
        if not (same_p and same_l):
            scans[i] = _update_scan(
                bs, points=None if same_p else pts, lines=None if same_l else lns
            )
    # Objects.
    clashes = merge_clashes(base, other)
    if clashes and on_clash == "error":
        listed = ", ".join(repr(o.name) for _, o in clashes[:10])
        clash_words = plural(len(clashes), "name clash", "name clashes")
        raise EditError(f"{clash_words} between the maps: {listed}")
    clash_names = {o.name.lower() for _, o in clashes}
    objects = list(base.objects)
    if on_clash == "other":
        objects = [o for o in objects if o.name.lower() not in clash_names or not o.name]
    taken = {o.name.lower() for o in objects if o.name}
    renamed: dict[str, str] = {}
    added: list[MapObject] = []
    for o in other.objects:
        if o in base.objects:
            continue
        if o.name and o.name.lower() in clash_names:
            if on_clash == "base":
                continue
            if on_clash == "rename":
                new_name = _free_name(o.name, taken | {a.name.lower() for a in added})
                renamed[o.name.lower()] = new_name
                o = replace(o, name=new_name)
        added.append(o)
        if o.name:
            taken.add(o.name.lower())
    objects.extend(added)
    inactive = list(base.inactive_objects) + [
        o for o in other.inactive_objects if o not in base.inactive_objects
    ]
    children = list(base.child_objects) + [
        o for o in other.child_objects if o not in base.child_objects
    ]
    out = base.replace(
        scans=tuple(scans),
        objects=tuple(objects),
        inactive_objects=tuple(inactive),
        child_objects=tuple(children),
    )
    # Declarations and parameters the added objects need.
    mapinfo = _merge_mapinfo(base, other)
    if mapinfo != base.info.get("MapInfo", ()):
        info = dict(out.info)
        info["MapInfo"] = mapinfo
        out = out.replace(info=info)
    if on_clash == "other":
        out = _drop_orphan_params(out, [b.name for b, _ in clashes])
    base_params = {
        unquote(ln[1]).lower()
        for ln in out.info.get("CairnInfo", ())
        if len(ln) > 1 and ln[0] == "Params"
    }
    added_names = {o.name.lower() for o in added if o.name}
    for line in other.info.get("CairnInfo", ()):
        if len(line) < 2 or line[0] != "Params":
            continue
        n = unquote(line[1]).lower()
        target = renamed.get(n, unquote(line[1]))
        if target.lower() in added_names and (
            target.lower() not in base_params or on_clash == "other"
        ):
            out = with_params(out, ("Params", f'"{target}"', *line[2:]))
    for line in other.info.get("CairnInfo", ()):
        if line and line[0] == "GroupMember" and line not in out.info.get("CairnInfo", ()):
            info = dict(out.info)
            info["CairnInfo"] = (*out.info.get("CairnInfo", ()), line)
            out = out.replace(info=info)
    for o in added:
        _check_object_range(o, out.object_shape(o))
    check_span(base, out)
    return out
