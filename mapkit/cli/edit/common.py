"""What the editing commands share: options, argument parsing, and the load -> edit -> report ->
write step."""

from __future__ import annotations

import re
from collections.abc import Callable, Sequence
from typing import Any

import click

from mapkit import edit as editing
from mapkit.cli.options import (
    InputFile,
    backup_option,
    check_outputs,
    err,
    force_option,
    plural,
)
from mapkit.errors import EditError
from mapkit.formats.map import load, save
from mapkit.model import MapData

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
