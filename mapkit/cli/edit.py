"""Map editing commands: objects, geometry, merge, diff and scripted batches.

Each command: options -> one call into :mod:`mapkit.edit` -> a report of what changed (a diff of
the map before and after) -> an atomic write. Edits change MAP in place unless ``-o OUT`` is
given; ``--backup`` keeps the previous file as ``MAP.bak``; ``--dry-run`` writes nothing. A
refused edit exits 1 with one line saying why, and MAP is left byte for byte as it was.

Negative numbers can be given as plain arguments (``mapkit add-goal office.map A -1000 -250``).
"""

from __future__ import annotations

import os
import re
import sys
from collections.abc import Callable, Sequence
from typing import Any

import click

from mapkit import edit as editing
from mapkit.cli.options import (
    InputFile,
    backup_option,
    check_outputs,
    echo_json,
    err,
    force_option,
    json_option,
    plural,
)
from mapkit.errors import EditError, MapkitError
from mapkit.formats.map import load, save
from mapkit.model import MapData

__all__ = ["COMMANDS"]

# Negative numbers as arguments: click would take "-1000" for an option otherwise.
_SETTINGS = {"ignore_unknown_options": True}
_MAX_LINES = 25
_Notes = Callable[[MapData, MapData], list[str]]

F = Callable[..., Any]


def _stack(*decorators: Callable[[F], F]) -> Callable[[F], F]:
    """Several click decorators as one (applied in the order listed, top first)."""

    def apply(f: F) -> F:
        for d in reversed(decorators):
            f = d(f)
        return f

    return apply


_map_arg = click.argument("map_file", metavar="MAP", type=InputFile())
_writes = _stack(
    click.option(
        "-o",
        "--output",
        type=click.Path(dir_okay=False),
        help="Write the result to OUTPUT instead of changing MAP.",
    ),
    backup_option,
    force_option,
    click.option("--dry-run", is_flag=True, help="Show what would change; write nothing."),
)
_type_opt = click.option("--type", "type_", help="Only objects of this type.")
_allow_dup = click.option(
    "--allow-duplicate", is_flag=True, help="Accept a name another object has."
)
_allow_undeclared = click.option(
    "--allow-undeclared", is_flag=True, help="Accept a type the map does not declare."
)
_param_opt = click.option(
    "--param",
    "params",
    multiple=True,
    metavar="NAME=VALUE",
    help="A parameter the type declares (MapInfo: ArgDesc); repeat. Others take their defaults.",
)
_description = click.option("--description", default="", help="Free text stored with the object.")
_area_opts = _stack(
    click.option(
        "--area", nargs=4, type=float, metavar="X1 Y1 X2 Y2", help="Opposite corners of an area."
    ),
    click.option(
        "--angle",
        type=float,
        default=0.0,
        help="Angle of the area in degrees, counter-clockwise.",
    ),
    click.option(
        "--rotate-about",
        type=click.Choice(["centre", "origin"]),
        default="centre",
        show_default=True,
        help="Turn the box drawn about its own centre, or about the map origin (0, 0) as ARIA "
        "stores turned areas (the box then moves).",
    ),
    click.option(
        "--rotate-about-centre",
        is_flag=True,
        hidden=True,  # the default since 0.2; kept so older commands still run
    ),
)
_region_opts = _stack(
    click.option("--box", nargs=4, type=float, metavar="X1 Y1 X2 Y2", help="A box region."),
    click.option(
        "--polygon", metavar="'X1,Y1 X2,Y2 ...'", help="A polygon region (3 or more vertices)."
    ),
)


def _rotate_about(rotate_about: str, rotate_about_centre: bool) -> str:
    if rotate_about_centre and rotate_about == "origin":
        raise click.UsageError("give --rotate-about origin or --rotate-about-centre, not both")
    return rotate_about


def _params(values: Sequence[str]) -> dict[str, str]:
    out = {}
    for v in values:
        k, sep, val = v.partition("=")
        if not sep or not k:
            raise click.BadParameter(f"{v!r}: give parameters as NAME=VALUE", param_hint="--param")
        out[k] = val
    return out


def _polygon(text: str) -> list[tuple[float, float]]:
    nums = [t for t in re.split(r"[\s,;]+", text.strip()) if t]
    try:
        vals = [float(t) for t in nums]
    except ValueError:
        raise click.BadParameter(
            f"{text!r}: give vertices as 'X1,Y1 X2,Y2 X3,Y3 ...'", param_hint="--polygon"
        ) from None
    if len(vals) % 2:
        raise click.BadParameter(
            f"{text!r}: an odd count of numbers; give X,Y pairs", param_hint="--polygon"
        )
    return list(zip(vals[0::2], vals[1::2], strict=True))


def _region(
    box: Sequence[float] | None, polygon: str | None, *, required: bool, box_name: str = "--box"
) -> editing.Region | None:
    if box and polygon is not None:
        raise click.UsageError(f"give {box_name} or --polygon, not both")
    if required and not box and polygon is None:
        raise click.UsageError(
            f"give a region: {box_name} X1 Y1 X2 Y2 or --polygon 'X1,Y1 X2,Y2 X3,Y3 ...'"
        )
    return editing.Region.from_spec(box or None, None if polygon is None else _polygon(polygon))


def _apply(
    map_file: str,
    opts: dict[str, Any],
    edit: Callable[[MapData], MapData],
    notes: _Notes | None = None,
) -> None:
    """Load, edit, report the changes, write atomically (unless nothing changed or a dry run)."""
    output, backup, force, dry_run = opts["output"], opts["backup"], opts["force"], opts["dry_run"]
    if not dry_run:
        check_outputs([output or map_file], force, same_as=map_file)
    m = load(map_file)
    for lost in editing.missing_rows(m):
        if not force:
            raise EditError(
                f"{map_file}: {lost}; an edit would write the smaller count and lose those rows "
                "for good (restore the file, or add --force to edit what is left)"
            )
        err(f"warning: {map_file}: {lost}; --force: writing what is left")
    new = edit(m)
    d = editing.diff(m, new)
    lines = d.summary()
    for line in lines[:_MAX_LINES]:
        click.echo(line)
    if len(lines) > _MAX_LINES:
        more = plural(len(lines) - _MAX_LINES, "more change")
        click.echo(f"... and {more} (mapkit diff shows them all)")
    for n in notes(m, new) if notes else []:
        err(f"note: {n}")
    if dry_run:
        click.echo("dry run: nothing written")
        return
    if d.equal and output is None:
        click.echo(f"nothing changed; {map_file} left as it was")
        return
    target = output or map_file
    md5 = save(new, target, backup=backup)
    click.echo(
        f"wrote {target} (MD5 {md5})" + (f", previous file kept as {target}.bak" if backup else "")
    )


def _reference_notes(names: Callable[[MapData], list[str]]) -> _Notes:
    def notes(before: MapData, after: MapData) -> list[str]:
        return [
            f"{section}: {' '.join(line)} still names {n!r}"
            for n in names(before)
            for section, _, line in editing.name_references(after, n)
        ]

    return notes


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


def _where(r: dict[str, Any]) -> str:
    if r["shape"] == "rect":
        where = "area " + " ".join(f"({x:.0f}, {y:.0f})" for x, y in r["corners"])
    elif r["shape"] == "line":
        (ax, ay), (bx, by) = r["corners"]
        where = f"line ({ax:.0f}, {ay:.0f}) -> ({bx:.0f}, {by:.0f})"
    else:
        where = "point"
    return where + (
        "  " + " ".join(f"{k}={v}" for k, v in r["params"].items()) if r["params"] else ""
    )


@click.command("objects")
@_map_arg
@click.option("--type", "type_", help="Only this type (Goal includes GoalWithHeading).")
@click.option(
    "--all", "all_", is_flag=True, help="Also inactive (_Cairn:) and template child objects."
)
@json_option
def objects_cmd(map_file: str, type_: str | None, all_: bool, as_json: bool) -> None:
    """List the objects of MAP, numbered as #N for remove, rename and move.

    \b
    Example:
      mapkit objects columbia.map --type Goal
    """
    rows = editing.list_objects(load(map_file), type=type_, inactive=all_)
    if as_json:
        echo_json(rows)
        return
    if not rows:
        click.echo("no objects" + (f" of type {type_}" if type_ else ""))
        return
    wt = max(4, *(len(r["type"]) for r in rows))
    wn = max(4, *(len(r["name"]) + 2 for r in rows))
    click.echo(f"{'#':>4}  {'type':<{wt}}  {'name':<{wn}}  {'x':>8} {'y':>8} {'theta':>8}  where")
    for r in rows:
        idx = (
            str(r["index"])
            if r["index"]
            else {"inactive_objects": "_", "child_objects": "c"}[r["list"]]
        )
        click.echo(
            f"{idx:>4}  {r['type']:<{wt}}  {r['name']!r:<{wn}}  {r['x']:>8.0f} {r['y']:>8.0f} "
            f"{r['theta']:>8.2f}  {_where(r)}"
        )


@click.command("remove", context_settings=_SETTINGS)
@_map_arg
@click.argument("names", nargs=-1, required=True)
@_type_opt
@click.option("--all", "all_", is_flag=True, help="Remove every object a shared name picks.")
@_writes
def remove_cmd(
    map_file: str, names: tuple[str, ...], type_: str | None, all_: bool, **opts: Any
) -> None:
    """Remove objects by NAME (case-insensitive) or #N (see mapkit objects).

    \b
    Examples:
      mapkit remove office.map Kitchen "Old desk"
      mapkit remove columbia.map '#3' '#4'
    """
    _apply(
        map_file,
        opts,
        lambda m: editing.remove(m, *names, type=type_, all_matches=all_),
        _reference_notes(lambda m: [n for n in names if not n.startswith("#")]),
    )


@click.command("rename", context_settings=_SETTINGS)
@_map_arg
@click.argument("name")
@click.argument("new_name")
@_type_opt
@_allow_dup
@_writes
def rename_cmd(
    map_file: str, name: str, new_name: str, type_: str | None, allow_duplicate: bool, **opts: Any
) -> None:
    """Rename the object NAME (or #N) to NEW_NAME; its CairnInfo: Params follow.

    Routes and tasks that mention the old name are reported, not changed.

    \b
    Example:
      mapkit rename office.map "Goal 1" Reception
    """
    _apply(
        map_file,
        opts,
        lambda m: editing.rename(m, name, new_name, type=type_, allow_duplicate=allow_duplicate),
        _reference_notes(
            lambda m: [m.objects[i].name for i in editing.select(m, name, type=type_)]
        ),
    )


@click.command("move", context_settings=_SETTINGS)
@_map_arg
@click.argument("name")
@click.argument("x", type=float, required=False)
@click.argument("y", type=float, required=False)
@click.option("--by", nargs=2, type=float, metavar="DX DY", help="Move by an offset instead.")
@click.option(
    "--heading", type=float, help="New heading in degrees (areas turn about their centre)."
)
@_type_opt
@_writes
def move_cmd(
    map_file: str,
    name: str,
    x: float | None,
    y: float | None,
    by: tuple[float, ...],
    heading: float | None,
    type_: str | None,
    **opts: Any,
) -> None:
    """Move the object NAME (or #N) to X Y, or --by DX DY; and/or set its --heading.

    Lines and areas are moved so their centre lands on X Y.

    \b
    Examples:
      mapkit move office.map Kitchen 12500 -3500 --heading 180
      mapkit move office.map '#2' --by 0 250
    """
    _apply(
        map_file,
        opts,
        lambda m: editing.move(m, name, x, y, by=by or None, heading=heading, type=type_),
    )


# -- data and geometry -------------------------------------------------------------------------


@click.command("erase", context_settings=_SETTINGS)
@_map_arg
@_region_opts
@click.option(
    "--source", "sources", multiple=True, help="Only this scan source (repeat; default all)."
)
@_writes
def erase_cmd(
    map_file: str,
    box: tuple[float, ...],
    polygon: str | None,
    sources: tuple[str, ...],
    **opts: Any,
) -> None:
    """Remove the points inside a region and cut away the parts of lines inside it.

    The eraser for people, carts and doors the scan caught. Objects are not touched; the border
    counts as inside.

    \b
    Examples:
      mapkit erase office.map --box 1000 -2000 2500 -500
      mapkit erase office.map --polygon '0,0 4000,0 4000,3000 1000,3500'
    """
    region = _region(box, polygon, required=True)
    assert region is not None
    _apply(map_file, opts, lambda m: editing.erase(m, region, sources=sources or None))


@click.command("draw-line", context_settings=_SETTINGS)
@_map_arg
@click.argument("x1", type=float)
@click.argument("y1", type=float)
@click.argument("x2", type=float)
@click.argument("y2", type=float)
@click.option("--source", help="Scan source to draw into (default the first).")
@click.option(
    "--as-points",
    is_flag=True,
    help="Draw a row of points on the resolution grid instead of a LINES segment.",
)
@_writes
def draw_line_cmd(
    map_file: str,
    x1: float,
    y1: float,
    x2: float,
    y2: float,
    source: str | None,
    as_points: bool,
    **opts: Any,
) -> None:
    """Add a line segment from X1 Y1 to X2 Y2 to the map data (a wall the scan missed).

    \b
    Example:
      mapkit draw-line office.map 0 0 5000 0 --as-points
    """
    _apply(
        map_file,
        opts,
        lambda m: editing.draw_line(m, x1, y1, x2, y2, source=source, as_points=as_points),
    )


def _transform_notes(rotate: float) -> _Notes:
    def notes(before: MapData, after: MapData) -> list[str]:
        out = []
        if before.origin_lla is not None:
            out.append(
                "OriginLatLongAlt: is kept as it was, but it gives the latitude and longitude of "
                "the map origin, which moved: update it if the map is geo-referenced"
            )
        if rotate % 90 and any(s.resolution > 0 and s.num_points for s in before.scans):
            out.append(
                f"a turn of {rotate:g} degrees takes the points off their "
                f"{before.scan.resolution} mm grid (rounded to whole mm)"
            )
        if before.child_objects:
            out.append(
                "template children (ChildCairn:) are relative to their group and were not moved"
            )
        return out

    return notes


@click.command("transform", context_settings=_SETTINGS)
@_map_arg
@click.option(
    "--translate", nargs=2, type=float, metavar="DX DY", help="Shift by DX DY millimetres."
)
@click.option("--rotate", type=float, default=0.0, help="Turn by DEG degrees counter-clockwise.")
@click.option(
    "--about",
    nargs=2,
    type=float,
    metavar="X Y",
    help="Turn about this point (default the origin).",
)
@click.option("--recenter", is_flag=True, help="First move the centre of the data to the origin.")
@_writes
def transform_cmd(
    map_file: str,
    translate: tuple[float, ...],
    rotate: float,
    about: tuple[float, ...],
    recenter: bool,
    **opts: Any,
) -> None:
    """Move the whole map: points, lines and every object together; headings follow.

    Order: --recenter, then --rotate about --about, then --translate. Turned areas keep their
    exact shape (new corners and angle, as ARIA stores them).

    \b
    Examples:
      mapkit transform office.map --rotate 90
      mapkit transform office.map --recenter -o centred.map
      mapkit transform office.map --rotate -12.5 --about 1000 2000 --translate 0 -500
    """
    if not translate and not rotate and not recenter:
        raise click.UsageError("give --translate, --rotate or --recenter")

    def edit(m: MapData) -> MapData:
        motion = editing.transform_motion(
            m,
            rotate=rotate,
            translate=translate or (0.0, 0.0),
            about=about or (0.0, 0.0),
            recenter=recenter,
        )
        err(
            f"motion: turn {motion.angle:g} degrees, "
            f"then shift ({motion.tx:.1f}, {motion.ty:.1f}) mm"
        )
        return editing.apply_motion(m, motion)

    _apply(map_file, opts, edit, _transform_notes(rotate))


@click.command("crop", context_settings=_SETTINGS)
@_map_arg
@_region_opts
@click.option("--keep-objects", is_flag=True, help="Keep objects outside the region too.")
@_writes
def crop_cmd(
    map_file: str, box: tuple[float, ...], polygon: str | None, keep_objects: bool, **opts: Any
) -> None:
    """Keep only the data inside a region; objects wholly outside it are removed.

    \b
    Example:
      mapkit crop columbia.map --box -6000 -28000 21000 0 -o south.map
    """
    region = _region(box, polygon, required=True)
    assert region is not None
    _apply(map_file, opts, lambda m: editing.crop(m, region, keep_objects=keep_objects))


def _merge_notes(other: MapData, on_clash: str) -> _Notes:
    what = {
        "keep": "both kept",
        "rename": "OTHER's renamed",
        "base": "BASE's kept",
        "other": "OTHER's kept",
        "error": "",
    }[on_clash]

    def notes(before: MapData, after: MapData) -> list[str]:
        out = [
            f"name clash: {b.type} {b.name!r} in BASE and {o.type} {o.name!r} in OTHER ({what})"
            for b, o in editing.merge_clashes(before, other)
        ]
        if other.scan.resolution != before.scan.resolution:
            out.append(
                f"resolutions differ: BASE {before.scan.resolution} mm, "
                f"OTHER {other.scan.resolution} mm"
            )
        out.extend(
            f"OTHER's {key}: lines were not merged (BASE's kept)"
            for key, lines in other.info.items()
            if key not in ("MapInfo", "CairnInfo") and lines != before.info.get(key, ())
        )
        return out

    return notes


@click.command("merge", context_settings=_SETTINGS)
@click.argument("base", type=InputFile())
@click.argument("other", type=InputFile())
@click.option(
    "--region",
    nargs=4,
    type=float,
    metavar="X1 Y1 X2 Y2",
    help="Take OTHER's data only inside this box (BASE's data there is replaced).",
)
@click.option("--polygon", metavar="'X1,Y1 X2,Y2 ...'", help="The same with a polygon.")
@click.option(
    "--on-clash",
    type=click.Choice(editing.CLASH_POLICIES),
    default="keep",
    show_default=True,
    help="Same name in both maps: keep both, rename OTHER's, keep BASE's or OTHER's, or refuse.",
)
@_writes
def merge_cmd(
    base: str,
    other: str,
    region: tuple[float, ...],
    polygon: str | None,
    on_clash: str,
    **opts: Any,
) -> None:
    """Insert map OTHER into BASE (Mapper3's Insert Map); BASE changes unless -o.

    Without a region OTHER's points and lines are added; with one, the data inside it comes
    from OTHER. Objects of both are kept; name clashes are reported.

    \b
    Example:
      mapkit merge building.map rescan.map --region 0 0 8000 6000 -o updated.map
    """
    reg = _region(region, polygon, required=False, box_name="--region")
    other_map = load(other)
    _apply(
        base,
        opts,
        lambda m: editing.merge(m, other_map, region=reg, on_clash=on_clash),
        _merge_notes(other_map, on_clash),
    )


# -- diff and scripts --------------------------------------------------------------------------


@click.command("diff")
@click.argument("a", type=InputFile())
@click.argument("b", type=InputFile())
@json_option
def diff_cmd(a: str, b: str, as_json: bool) -> None:
    """Show what differs from map A to map B. Exit 0 when equal, 1 when different, 2 on error.

    \b
    Example:
      mapkit diff office.map office-edited.map
    """
    try:
        ma, mb = load(a), load(b)
    except (MapkitError, OSError) as e:  # 1 means "different" here, so errors are 2
        from mapkit.cli.main import EXIT_USAGE, CommandError, error_message

        raise CommandError(error_message(e)[0], EXIT_USAGE) from e
    d = editing.diff(ma, mb)
    if as_json:
        echo_json(d.to_json())
    elif d.equal:
        click.echo(f"{a} and {b} hold the same map")
    else:
        c = d.counts()
        click.echo(
            f"objects: {c['added']} added, {c['removed']} removed, {c['moved']} moved, "
            f"{c['changed']} changed"
        )
        for line in d.summary():
            click.echo("  " + line)
    sys.exit(0 if d.equal else 1)


@click.command("edit")
@_map_arg
@click.option(
    "--script",
    "script",
    required=True,
    type=InputFile(),
    help="A YAML or JSON file of edits (see docs/edit.md).",
)
@_writes
def edit_cmd(map_file: str, script: str, **opts: Any) -> None:
    """Apply a batch of edits from a YAML or JSON file as one atomic change.

    If any edit is refused, nothing is written.

    \b
    Example:
      mapkit edit office.map --script edits.yaml --backup
    """
    edits = editing.load_script(script)
    base_dir = os.path.dirname(os.path.abspath(script))
    err(f"{plural(len(edits), 'edit')} from {script}")
    _apply(map_file, opts, lambda m: editing.apply_script(m, edits, base_dir=base_dir))


#: Every command of this module, for ``mapkit/cli/main.py`` to register.
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
