"""``mapkit render``: a picture of a map (PNG, SVG or PDF), or a window with it."""

from __future__ import annotations

import click

from mapkit.cli.options import (
    InputFile,
    check_outputs,
    echo_json,
    err,
    force_option,
    json_option,
    output_option,
)
from mapkit.formats.registry import read_any
from mapkit.render import render as render_map


@click.command(short_help="Draw a map as PNG, SVG or PDF, or in a window.")
@click.argument("map_file", type=InputFile())
@output_option("Picture to write: .png, .svg or .pdf.")
@click.option("--show", is_flag=True, help="Open a window with the picture (needs a display).")
@click.option(
    "--width",
    type=click.IntRange(32, 20000),
    default=1600,
    show_default=True,
    help="Picture width in pixels.",
)
@click.option(
    "--height",
    type=click.IntRange(32, 20000),
    default=None,
    help="Picture height in pixels [default: from the map's shape].",
)
@click.option(
    "--dpi",
    type=click.FloatRange(10, 1200),
    default=100,
    show_default=True,
    help="Dots per inch: text sizes are in points, so more dpi means larger text.",
)
@click.option("--no-names", is_flag=True, help="Do not write object names.")
@click.option("--no-points", is_flag=True, help="Do not draw the scan points.")
@click.option("--no-lines", is_flag=True, help="Do not draw the LINES.")
@click.option("--no-legend", is_flag=True, help="No legend.")
@click.option("--thumbnail", is_flag=True, help="The map only: no axes, grid, names or legend.")
@click.option(
    "--title", default=None, help='Title above the map [default: file name]; "" for none.'
)
@force_option
@json_option
def render(
    map_file: str,
    output: str | None,
    show: bool,
    width: int,
    height: int | None,
    dpi: float,
    no_names: bool,
    no_points: bool,
    no_lines: bool,
    no_legend: bool,
    thumbnail: bool,
    title: str | None,
    force: bool,
    as_json: bool,
) -> None:
    """Draw MAP_FILE: points, lines, goals with headings and names, home, docks, forbidden
    areas and lines, sectors, a grid and a scale bar in metres, and a legend.

    The format follows the suffix of -o (.png, .svg, .pdf). Names that would overlap others are
    left out (a wider picture has room for more).

    \b
    Examples:
      mapkit render office.map -o office.png
      mapkit render office.map -o office.pdf --width 3000 --no-points
      mapkit render office.map --show
    """
    if output is None and not show:
        raise click.UsageError("give -o OUT.png|svg|pdf or --show")
    if output is not None:
        check_outputs([output], force)
    m = read_any(map_file)
    r = render_map(
        m,
        output,
        show=show,
        width=width,
        height=height,
        dpi=dpi,
        show_names=not no_names,
        show_points=not no_points,
        show_lines=not no_lines,
        legend=not no_legend,
        thumbnail=thumbnail,
        title=title,
    )
    if as_json:
        echo_json(
            {
                "path": r.path,
                "format": r.format,
                "width": r.width,
                "height": r.height,
                "dpi": r.dpi,
                "view": list(r.view),
                "metres_per_pixel": r.metres_per_pixel,
                "names_hidden": r.names_hidden,
            }
        )
        return
    if r.path:
        kind = r.format.upper() if r.format else ""
        click.echo(
            f"wrote {r.path} ({kind}, {r.width}x{r.height} px, "
            f"{r.metres_per_pixel * 1000:.1f} mm per pixel)"
        )
    if r.names_hidden:
        n = r.names_hidden
        err(
            f"mapkit: {n} name{'s' if n > 1 else ''} left out where {'they' if n > 1 else 'it'} "
            f"would overlap others (a larger --width has room for more)"
        )
