"""Commands that list and change objects: objects, remove, rename, move."""

from __future__ import annotations

from typing import Any

import click

from mapkit import edit as editing
from mapkit.cli.edit.common import (
    _SETTINGS,
    _allow_dup,
    _apply,
    _map_arg,
    _reference_notes,
    _type_opt,
    _writes,
)
from mapkit.cli.options import (
    echo_json,
    json_option,
)
from mapkit.formats.map import load

__all__ = ["move_cmd", "objects_cmd", "remove_cmd", "rename_cmd"]


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
