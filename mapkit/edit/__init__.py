"""Edits: pure functions from a map to a new map, a diff, and batches from a script.

Every edit takes a :class:`~mapkit.model.MapData` and returns a new one; a refused edit raises
:class:`~mapkit.errors.EditError` and changes nothing. What an edit does not touch is carried
over unchanged (objects, their order, info sections, unknown lines; the scans too when only
objects change). Write the result with :func:`mapkit.save`.

Objects:
    :func:`add_goal`, :func:`add_dock`, :func:`add_home`, :func:`forbid`, :func:`forbid_area`,
    :func:`forbid_line`, :func:`add_object` (any declared type, with parameters),
    :func:`remove`, :func:`rename`, :func:`move`, :func:`select`, :func:`name_references`,
    :func:`list_objects`.
Data and geometry:
    :func:`erase`, :func:`draw_line`, :func:`crop`, :func:`transform` (:class:`Rigid`),
    :func:`merge`, :func:`merge_clashes`; regions are :class:`Region` (box or polygon).
Comparing:
    :func:`diff` gives a :class:`MapDiff`.
Batches:
    :func:`load_script` / :func:`parse_script` and :func:`apply_script`.

Examples:
    >>> import mapkit
    >>> from mapkit import edit
    >>> m = mapkit.loads("2D-Map\\nDATA\\n0 0\\n100 0\\n5000 0\\n")
    >>> m2 = edit.erase(edit.add_goal(m, "Desk", 0, 0), edit.Region.box(-50, -50, 150, 50))
    >>> m2.points.tolist()
    [[5000, 0]]
    >>> print("\\n".join(edit.diff(m, m2).summary()))
    added Goal 'Desk' at (0, 0)
    points: 2 removed in (0, 0)-(100, 0) (3 -> 1)
"""

from mapkit.edit.checks import COORD_LIMIT, SPAN_LIMIT, missing_rows
from mapkit.edit.diff import DataChange, InfoChange, MapDiff, ObjectChange, ValueChange, diff
from mapkit.edit.geometry import Rigid, rect_about_centre
from mapkit.edit.listing import list_objects
from mapkit.edit.ops import (
    CLASH_POLICIES,
    add_dock,
    add_goal,
    add_home,
    add_object,
    apply_motion,
    crop,
    draw_line,
    erase,
    forbid,
    forbid_area,
    forbid_line,
    merge,
    merge_clashes,
    move,
    name_references,
    remove,
    rename,
    select,
    transform,
    transform_motion,
)
from mapkit.edit.script import Edit, apply_script, load_script, parse_script
from mapkit.edit.selection import Region

__all__ = [
    "CLASH_POLICIES",
    "COORD_LIMIT",
    "SPAN_LIMIT",
    "DataChange",
    "Edit",
    "InfoChange",
    "MapDiff",
    "ObjectChange",
    "Region",
    "Rigid",
    "ValueChange",
    "add_dock",
    "add_goal",
    "add_home",
    "add_object",
    "apply_motion",
    "apply_script",
    "crop",
    "diff",
    "draw_line",
    "erase",
    "forbid",
    "forbid_area",
    "forbid_line",
    "list_objects",
    "load_script",
    "merge",
    "merge_clashes",
    "missing_rows",
    "move",
    "name_references",
    "parse_script",
    "rect_about_centre",
    "remove",
    "rename",
    "select",
    "transform",
    "transform_motion",
]
