"""Picking objects by selector, and removing, renaming and moving them."""

from __future__ import annotations

import difflib
from collections.abc import Iterable, Sequence
from dataclasses import replace

from mapkit._text import plural
from mapkit.edit.checks import (
    check_coord,
    check_name,
    check_number,
)
from mapkit.edit.declared import (
    rename_params,
    type_class,
    unquote,
    without_params,
)
from mapkit.edit.geometry import Rigid, object_centre
from mapkit.edit.ops.common import (
    _check_object_range,
    _check_unique,
    _label,
    _needs_name,
    as_written,
)
from mapkit.errors import EditError
from mapkit.model import INFO_KEYWORDS, MapData, MapObject

__all__ = ["move", "name_references", "remove", "rename", "select"]


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
