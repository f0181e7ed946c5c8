"""Commands that change the map data and geometry: erase, draw-line, transform, crop, merge."""

from __future__ import annotations

from typing import Any

import click

from mapkit import edit as editing
from mapkit.cli.edit.common import (
    _SETTINGS,
    _apply,
    _map_arg,
    _Notes,
    _region,
    _region_opts,
    _writes,
)
from mapkit.cli.options import (
    InputFile,
    err,
)
from mapkit.formats.map import load
from mapkit.model import MapData

__all__ = ["crop_cmd", "draw_line_cmd", "erase_cmd", "merge_cmd", "transform_cmd"]


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
