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

from mapkit.edit.ops.add import (
    add_dock,
    add_goal,
    add_home,
    add_object,
    forbid,
    forbid_area,
    forbid_line,
)
from mapkit.edit.ops.common import (
    ROTATE_ABOUT as ROTATE_ABOUT,
    as_written as as_written,
)
from mapkit.edit.ops.data import (
    crop,
    draw_line,
    erase,
    rows_not_in as rows_not_in,
)
from mapkit.edit.ops.merge import (
    CLASH_POLICIES,
    merge,
    merge_clashes,
)
from mapkit.edit.ops.objects import (
    move,
    name_references,
    remove,
    rename,
    select,
)
from mapkit.edit.ops.transform import (
    apply_motion,
    recenter_motion,
    transform,
    transform_motion,
)

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
