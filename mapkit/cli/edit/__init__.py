"""Map editing commands: objects, geometry, merge, diff and scripted batches.

Each command: options -> one call into :mod:`mapkit.edit` -> a report of what changed (a diff of
the map before and after) -> an atomic write. Edits change MAP in place unless ``-o OUT`` is
given; ``--backup`` keeps the previous file as ``MAP.bak``; ``--dry-run`` writes nothing. A
refused edit exits 1 with one line saying why, and MAP is left byte for byte as it was.

Negative numbers can be given as plain arguments (``mapkit add-goal office.map A -1000 -250``).
"""

from __future__ import annotations

from mapkit.cli.edit.add import (
    add_dock_cmd as add_dock_cmd,
    add_goal_cmd as add_goal_cmd,
    add_home_cmd as add_home_cmd,
    add_object_cmd as add_object_cmd,
    forbid_cmd as forbid_cmd,
)
from mapkit.cli.edit.data import (
    crop_cmd as crop_cmd,
    draw_line_cmd as draw_line_cmd,
    erase_cmd as erase_cmd,
    merge_cmd as merge_cmd,
    transform_cmd as transform_cmd,
)
from mapkit.cli.edit.objects import (
    move_cmd as move_cmd,
    objects_cmd as objects_cmd,
    remove_cmd as remove_cmd,
    rename_cmd as rename_cmd,
)
from mapkit.cli.edit.scripts import (
    diff_cmd as diff_cmd,
    edit_cmd as edit_cmd,
)

#: Every command of this package, for ``mapkit/cli/main.py`` to register.
COMMANDS = [
    add_goal_cmd,
    add_dock_cmd,
    add_home_cmd,
    forbid_cmd,
    add_object_cmd,
    objects_cmd,
    remove_cmd,
    rename_cmd,
    move_cmd,
    erase_cmd,
    draw_line_cmd,
    transform_cmd,
    crop_cmd,
    merge_cmd,
    diff_cmd,
    edit_cmd,
]

__all__ = ["COMMANDS"]
