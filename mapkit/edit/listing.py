"""A map's objects as rows of plain data (what ``mapkit objects`` prints)."""

from __future__ import annotations

from typing import Any

from mapkit.edit.declared import object_params
from mapkit.edit.geometry import object_centre
from mapkit.model import MapData

__all__ = ["list_objects"]


def list_objects(
    m: MapData, *, type: str | None = None, inactive: bool = False
) -> list[dict[str, Any]]:
    """One JSON-ready dict per object, numbered as selectors number them (``#N``).

    Args:
        m: The map.
        type: Only this type or base type (case-insensitive; ``Goal`` includes ``GoalWithHeading``).
        inactive: Also list ``_Cairn:`` and ``ChildCairn:`` objects (``index`` is then ``None``).

    Returns:
        Dicts with ``index`` (1-based), ``list``, ``type``, ``base_type``, ``shape``, ``name``,
        ``description``, ``icon``, ``x``, ``y``, ``theta``, ``from_to``, ``centre``, ``corners``
        (world corners of a rectangle, ends of a line) and ``params`` (by name).

    Examples:
        >>> from mapkit.model import MapObject
        >>> m = MapData(objects=(MapObject("ForbiddenArea", 0, 0, 90, from_to=(0, 0, 100, 50)),))
        >>> row = list_objects(m)[0]
        >>> row["shape"], row["centre"], row["corners"][1]
        ('rect', [-25.0, 50.0], [0.0, 100.0])
    """
    want = type.lower() if type else None
    groups = [("objects", m.objects)]
    if inactive:
        groups += [("inactive_objects", m.inactive_objects), ("child_objects", m.child_objects)]
    rows = []
    for where, objs in groups:
        for i, o in enumerate(objs):
            if want and o.type.lower() != want and o.base_type.lower() != want:
                continue
            shape = m.object_shape(o)
            corners = None
            if shape == "rect":
                corners = [[round(x, 3) + 0.0, round(y, 3) + 0.0] for x, y in o.corners()]
            elif shape == "line" and o.from_to is not None:
                corners = [list(o.from_to[:2]), list(o.from_to[2:])]
            cx, cy = object_centre(o, shape)
            rows.append(
                {
                    "index": i + 1 if where == "objects" else None,
                    "list": where,
                    "type": o.type,
                    "base_type": o.base_type,
                    "shape": shape,
                    "name": o.name,
                    "description": o.description,
                    "icon": o.icon,
                    "x": o.x,
                    "y": o.y,
                    "theta": o.theta,
                    "from_to": list(o.from_to) if o.from_to is not None else None,
                    "centre": [round(cx, 3) + 0.0, round(cy, 3) + 0.0],
                    "corners": corners,
                    "params": object_params(m, o),
                }
            )
    return rows
