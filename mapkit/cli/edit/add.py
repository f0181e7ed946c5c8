"""Commands that add objects: add-goal, add-dock, add-home, forbid, add-object."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import click

from mapkit import edit as editing
from mapkit.cli.edit.common import (
    _SETTINGS,
    _allow_dup,
    _allow_undeclared,
    _apply,
    _area_opts,
    _description,
    _map_arg,
    _param_opt,
    _params,
    _rotate_about,
    _writes,
)
from mapkit.model import MapData

__all__ = ["add_dock_cmd", "add_goal_cmd", "add_home_cmd", "add_object_cmd", "forbid_cmd"]


# -- objects -----------------------------------------------------------------------------------


def _point_command(
    name: str, fn: Callable[..., MapData], default_type: str, help: str
) -> click.Command:
    """``add-goal`` and ``add-dock``: NAME X Y and the options of a typed point object."""

    @click.command(name, context_settings=_SETTINGS, help=help)
    @_map_arg
    @click.argument("name")
    @click.argument("x", type=float)
    @click.argument("y", type=float)
    @click.option("--heading", type=float, help="Heading in degrees.")
    @_description
    @click.option(
        "--type",
        "type_",
        default=default_type,
        show_default=True,
        help="A type of this kind the map declares.",
    )
    @_param_opt
    @_allow_dup
    @_allow_undeclared
    @_writes
    def command(
        map_file: str,
        name: str,
        x: float,
        y: float,
        heading: float | None,
        description: str,
        type_: str,
        params: tuple[str, ...],
        allow_duplicate: bool,
        allow_undeclared: bool,
        **opts: Any,
    ) -> None:
        _apply(
            map_file,
            opts,
            lambda m: fn(
                m,
                name,
                x,
                y,
                heading=heading,
                description=description,
                type=type_,
                params=_params(params),
                allow_duplicate=allow_duplicate,
                allow_undeclared=allow_undeclared,
            ),
        )

    return command


add_goal_cmd = _point_command(
    "add-goal",
    editing.add_goal,
    "Goal",
    """Add a goal NAME at X Y (millimetres).

    With --heading it is a GoalWithHeading (a declared goal type T becomes TWithHeading).

    \b
    Example:
      mapkit add-goal office.map Kitchen 12000 -3500 --heading 90
    """,
)

add_dock_cmd = _point_command(
    "add-dock",
    editing.add_dock,
    "Dock",
    """Add a dock NAME at X Y (millimetres).

    The heading (default 0) is the direction the robot docks in.

    \b
    Example:
      mapkit add-dock office.map "Dock 1" -2800 -2900 --heading -90
    """,
)


@click.command("add-home", context_settings=_SETTINGS)
@_map_arg
@click.argument("x", type=float, required=False)
@click.argument("y", type=float, required=False)
@click.option("--heading", type=float, help="Start heading in degrees (default 0).")
@_area_opts
@click.option("--name", default="", help="Name of the home.")
@_description
@_allow_dup
@_writes
def add_home_cmd(
    map_file: str,
    x: float | None,
    y: float | None,
    heading: float | None,
    area: tuple[float, ...],
    angle: float,
    rotate_about: str,
    rotate_about_centre: bool,
    name: str,
    description: str,
    allow_duplicate: bool,
    **opts: Any,
) -> None:
    """Add a RobotHome: a start pose X Y [--heading] or a start region --area.

    \b
    Examples:
      mapkit add-home office.map 0 0 --heading 90
      mapkit add-home office.map --area -500 -500 500 500 --name Start
    """
    _apply(
        map_file,
        opts,
        lambda m: editing.add_home(
            m,
            x,
            y,
            heading=heading,
            area=area or None,
            angle=angle,
            rotate_about=_rotate_about(rotate_about, rotate_about_centre),
            name=name,
            description=description,
            allow_duplicate=allow_duplicate,
        ),
    )


@click.command("forbid", context_settings=_SETTINGS)
@_map_arg
@_area_opts
@click.option(
    "--line", nargs=4, type=float, metavar="X1 Y1 X2 Y2", help="A forbidden line (its ends)."
)
@click.option("--name", default="", help="Name (forbidden areas and lines are usually unnamed).")
@_description
@_allow_dup
@_writes
def forbid_cmd(
    map_file: str,
    area: tuple[float, ...],
    angle: float,
    rotate_about: str,
    rotate_about_centre: bool,
    line: tuple[float, ...],
    name: str,
    description: str,
    allow_duplicate: bool,
    **opts: Any,
) -> None:
    """Add a ForbiddenArea (--area) or a ForbiddenLine (--line).

    --angle turns the box you drew about its own centre, so it stays where you drew it. ARIA
    stores a turned area as corners in a frame turned about the map origin; mapkit computes
    them. Reports give the corners in the world, as `mapkit objects` does. --rotate-about origin
    turns the given corners about (0, 0) instead, the way ARIA reads stored corners.

    \b
    Examples:
      mapkit forbid office.map --area 1000 1000 3000 2000 --angle 30
      mapkit forbid office.map --line -5000 0 5000 0
    """
    if bool(area) == bool(line):
        raise click.UsageError("give --area X1 Y1 X2 Y2 or --line X1 Y1 X2 Y2")
    if line and (angle or rotate_about_centre or rotate_about != "centre"):
        raise click.UsageError("--angle and --rotate-about are for --area")
    _apply(
        map_file,
        opts,
        lambda m: editing.forbid(
            m,
            area=area or None,
            line=line or None,
            angle=angle,
            rotate_about=_rotate_about(rotate_about, rotate_about_centre),
            name=name,
            description=description,
            allow_duplicate=allow_duplicate,
        ),
    )


@click.command("add-object", context_settings=_SETTINGS)
@_map_arg
@click.argument("type_", metavar="TYPE")
@click.option("--at", nargs=2, type=float, metavar="X Y", help="Position of a point object.")
@click.option("--heading", type=float, help="Heading of a point object in degrees.")
@_area_opts
@click.option(
    "--line", nargs=4, type=float, metavar="X1 Y1 X2 Y2", help="Ends of a boundary (line)."
)
@click.option("--name", default="", help="Object name.")
@_description
@_param_opt
@_allow_undeclared
@_allow_dup
@_writes
def add_object_cmd(
    map_file: str,
    type_: str,
    at: tuple[float, ...],
    heading: float | None,
    area: tuple[float, ...],
    angle: float,
    rotate_about: str,
    rotate_about_centre: bool,
    line: tuple[float, ...],
    name: str,
    description: str,
    params: tuple[str, ...],
    allow_undeclared: bool,
    allow_duplicate: bool,
    **opts: Any,
) -> None:
    """Add an object of any TYPE the map declares: sectors, boundaries, goal/dock/location types.

    The type's MapInfo: class decides the shape: SectorType takes --area, BoundaryType --line,
    GoalType/DockType/LocationType --at. Parameters go to a CairnInfo: Params line.

    \b
    Examples:
      mapkit add-object showroom.map MovementParametersSector --area 0 0 4000 2000 \\
          --name Slow --param TransVelMax=300
      mapkit add-object columbia.map Measure --line 0 0 5000 0
    """
    _apply(
        map_file,
        opts,
        lambda m: editing.add_object(
            m,
            type_,
            at=at or None,
            heading=heading,
            area=area or None,
            angle=angle,
            rotate_about=_rotate_about(rotate_about, rotate_about_centre),
            line=line or None,
            name=name,
            description=description,
            params=_params(params),
            allow_undeclared=allow_undeclared,
            allow_duplicate=allow_duplicate,
        ),
    )
