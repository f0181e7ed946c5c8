"""What each object is, for drawing: its kind, colour, marker and legend label."""

from __future__ import annotations

from typing import Any

from mapkit.model import MapData, MapObject

__all__ = ["COLORS", "object_kind", "type_params"]


# -- what each object is ----------------------------------------------------------------------

#: Colours of the built-in kinds (declared types use their ``Color0`` where they have one).
COLORS = {
    "points": "#3a3a3a",
    "lines": "#000000",
    "goal": "#1a9850",
    "goal_heading": "#00683a",
    "dock": "#7b3294",
    "home": "#e66101",
    "home_area": "#e66101",
    "forbidden_name": "#a50f15",
    "location": "#2166ac",
    "other_point": "#555555",
    "forbidden_area": "#d7191c",
    "forbidden_line": "#d7191c",
    "sector": "#4393c3",
    "boundary": "#c51b7d",
}

_LEGEND_LABELS = {
    "goal": "goal",
    "goal_heading": "goal with heading",
    "dock": "dock",
    "home": "robot home",
    "home_area": "robot home area",
    "location": "location",
    "other_point": "other object",
    "forbidden_area": "forbidden area",
    "forbidden_line": "forbidden line",
}

_AREA_FILL = (0.84, 0.1, 0.11, 0.08)
_HATCH = "#ec8a8c"
_HATCH_PATTERN = "///"
#: matplotlib settings for every picture (deterministic SVG ids, text kept as text, thin hatching).
_RC: dict[Any, Any] = {
    "svg.hashsalt": "mapkit",
    "svg.fonttype": "none",
    "pdf.fonttype": 42,
    "hatch.linewidth": 0.7,
}

_MARKERS = {
    "goal": "o",
    "goal_heading": "o",
    "dock": "s",
    "home": "p",
    "location": "D",
    "other_point": "X",
}


def _unquote(tok: str) -> str:
    return tok[1:-1] if len(tok) >= 2 and tok[0] == tok[-1] == '"' else tok


def type_params(m: MapData) -> dict[str, dict[str, str]]:
    """The ``Key=Value`` parameters of each type declared in ``MapInfo:``, by type name.

    The first value of a repeated key wins, as in ARIA's own reader.

    Examples:
        >>> m = MapData(info={"MapInfo": [("SectorType", "Name=Slow", '"Label=Slow zone"',
        ...                                "Color0=0x00ff00")]})
        >>> type_params(m)["Slow"]["Color0"], type_params(m)["Slow"]["Label"]
        ('0x00ff00', 'Slow zone')
    """
    out: dict[str, dict[str, str]] = {}
    for line in m.info.get("MapInfo", ()):
        if not line or not line[0].endswith("Type"):
            continue
        params: dict[str, str] = {}
        for tok in line[1:]:
            key, sep, value = _unquote(tok).partition("=")
            if sep:
                params.setdefault(key, value)
        name = params.get("Name")
        if name is not None:
            out.setdefault(name, params)
    return out


def object_kind(m: MapData, obj: MapObject, declared: dict[str, str] | None = None) -> str:
    """How :func:`render` draws an object: its kind.

    Point objects: ``goal``, ``goal_heading``, ``dock``, ``home``, ``location``, ``other_point``;
    rectangles: ``forbidden_area``, ``home_area``, ``sector``; lines: ``forbidden_line``,
    ``boundary``. Heading arrows are drawn for ``goal_heading``, ``dock`` and ``home``.

    Args:
        m: The map (its ``MapInfo:`` declarations decide declared types).
        obj: The object.
        declared: ``m.declared_types()``, when the caller has it already.

    Examples:
        >>> m = MapData(info={"MapInfo": [("DockType", "Name=DockLynx")]})
        >>> [object_kind(m, MapObject(t, 0, 0)) for t in ("Goal", "GoalWithHeading", "DockLynx")]
        ['goal', 'goal_heading', 'dock']
        >>> object_kind(m, MapObject("ForbiddenArea", 0, 0, from_to=(0, 0, 1, 1)))
        'forbidden_area'
    """
    decl = m.declared_types() if declared is None else declared
    shape = m.object_shape(obj)
    if shape == "line":
        return "forbidden_line" if obj.type == "ForbiddenLine" else "boundary"
    if shape == "rect":
        if obj.type == "ForbiddenArea":
            return "forbidden_area"
        if obj.type == "RobotHome":
            return "home_area"
        return "sector"
    base = obj.base_type
    cls = decl.get(obj.type) or decl.get(base)
    if base == "RobotHome":
        return "home"
    if base == "Dock" or cls == "DockType":
        return "dock"
    if base == "Goal" or cls == "GoalType":
        return "goal_heading" if obj.type != base else "goal"
    if cls == "LocationType":
        return "location"
    return "other_point"
