"""``mapkit info``: what a map holds."""

from __future__ import annotations

from collections import Counter
from typing import Any

import click

from mapkit.cli.options import InputFile, echo_json, json_option, plural
from mapkit.formats.map import load, written_category
from mapkit.model import MapData
from mapkit.model.map import missing_rows

#: Width in pixels of ``--thumbnail`` pictures.
THUMBNAIL_WIDTH = 320


def summary(m: MapData) -> dict[str, Any]:
    """The facts ``mapkit info`` prints, as JSON-ready data."""
    scans = []
    for s in m.scans:
        scans.append(
            {
                "name": s.name,
                "num_points": s.num_points,
                "num_lines": s.num_lines,
                "min_pos": list(s.min_pos) if s.min_pos else None,
                "max_pos": list(s.max_pos) if s.max_pos else None,
                "line_min_pos": list(s.line_min_pos) if s.line_min_pos else None,
                "line_max_pos": list(s.line_max_pos) if s.line_max_pos else None,
                "resolution": s.resolution,
                "points_sorted": s.points_sorted,
                "lines_sorted": s.lines_sorted,
            }
        )
    return {
        "file": m.provenance.source if m.provenance else None,
        "category": m.category,
        "written_category": written_category(m),
        "md5": m.md5,
        "size": m.provenance.size if m.provenance else None,
        "scans": scans,
        "objects": dict(Counter(o.type for o in m.objects)),
        "inactive_objects": len(m.inactive_objects),
        "child_objects": len(m.child_objects),
        "info": {k: len(v) for k, v in m.info.items()},
        "inactive_info": {k: len(v) for k, v in m.inactive_info.items()},
        "origin_lla": list(m.origin_lla) if m.origin_lla else None,
        "unknown_lines": len(m.remainder),
        "missing_rows": missing_rows(m),
    }


@click.command()
@click.argument("map_file", required=False, type=InputFile())
@click.option("--sample", help="Use a bundled sample map by name (e.g. office).")
@click.option(
    "--thumbnail",
    type=click.Path(dir_okay=False),
    help="Also write a small picture of the map (PNG; .svg/.pdf by suffix).",
)
@json_option
def info(map_file: str | None, sample: str | None, thumbnail: str | None, as_json: bool) -> None:
    """Show what MAP_FILE holds: category, counts, bounds, objects, info sections, MD5.

    \b
    Example:
      mapkit info office.map
      mapkit info --sample office --json
      mapkit info office.map --thumbnail office-small.png
    """
    if (map_file is None) == (sample is None):
        raise click.UsageError("give a MAP_FILE or --sample NAME")
    path = map_file
    if sample:
        from mapkit.samples import sample_path  # importlib.resources: only when asked for

        path = str(sample_path(sample))
    assert path is not None
    m = load(path)
    data = summary(m)
    if thumbnail:
        from mapkit.render import render

        pic = render(m, thumbnail, width=THUMBNAIL_WIDTH, thumbnail=True)
        data["thumbnail"] = {"path": pic.path, "width": pic.width, "height": pic.height}
    for lost in data["missing_rows"]:
        click.echo(f"warning: {path}: {lost}; editing it would lose them for good", err=True)
    if as_json:
        echo_json(data)
        return
    click.echo(f"{data['file']}: {data['category']}, {data['size']} bytes, MD5 {data['md5']}")
    for s in data["scans"]:
        label = f"source {s['name']!r}" if s["name"] else "scan"
        box = f"{s['min_pos']} .. {s['max_pos']}" if s["num_points"] else "-"
        lbox = f"{s['line_min_pos']} .. {s['line_max_pos']}" if s["num_lines"] else "-"
        click.echo(
            f"  {label}: {plural(s['num_points'], 'point')} (box {box}, resolution "
            f"{s['resolution']} mm, sorted {str(s['points_sorted']).lower()}), "
            f"{plural(s['num_lines'], 'line')} (box {lbox})"
        )
    if data["objects"]:
        objs = ", ".join(f"{n} {t}" for t, n in sorted(data["objects"].items()))
        click.echo(f"  objects: {objs}")
    else:
        click.echo("  objects: none")
    if data["info"]:
        click.echo("  info: " + ", ".join(f"{k} {n}" for k, n in data["info"].items()))
    extra = []
    if data["inactive_objects"]:
        extra.append(plural(data["inactive_objects"], "inactive object"))
    if data["child_objects"]:
        extra.append(plural(data["child_objects"], "child object"))
    if data["unknown_lines"]:
        extra.append(plural(data["unknown_lines"], "unknown line") + " kept")
    if data["origin_lla"]:
        extra.append("origin lat/long/alt {:.6f} {:.6f} {:.1f}".format(*data["origin_lla"]))
    if extra:
        click.echo("  " + "; ".join(extra))
    if thumbnail:
        t = data["thumbnail"]
        click.echo(f"  thumbnail: {t['path']} ({t['width']}x{t['height']} px)")
