"""``mapkit rasterize`` (map → ROS map_server map and Nav2 masks) and ``mapkit import-ros``."""

from __future__ import annotations

import os
from pathlib import Path

import click

from mapkit.cli.options import (
    InputFile,
    RowsBar,
    check_outputs,
    echo_json,
    err,
    force_option,
    json_option,
    output_option,
    plural,
)


def _refuse_existing(paths: list[Path], force: bool) -> None:
    check_outputs([str(p) for p in paths], force)


@click.command()
@click.argument("map_file", type=InputFile())
@output_option(
    "The map YAML to write (NAME.yaml; the image NAME.pgm goes beside it). "
    "Default: MAP's name with .yaml, in the current folder."
)
@click.option(
    "--resolution",
    type=float,
    default=0.05,
    show_default=True,
    metavar="M",
    help="Metres per cell.",
)
@click.option(
    "--mode",
    type=click.Choice(["trinary", "scale", "raw"]),
    default="trinary",
    show_default=True,
    help="How map_server reads the image.",
)
@click.option(
    "--free",
    type=click.Choice(["flood", "hull", "all", "none"]),
    default="flood",
    show_default=True,
    help="Free space: flood from goals/docks/home, the walls' hull, everything, nothing.",
)
@click.option("--png", is_flag=True, help="Write 8-bit grey PNG images instead of PGM.")
@click.option(
    "--keepout",
    is_flag=True,
    help="Also write the Nav2 keepout mask NAME_keepout.* and NAME_filters.yaml.",
)
@click.option(
    "--speed-mask",
    is_flag=True,
    help="Also write the Nav2 speed mask NAME_speed.* (sectors with TransVelMax).",
)
@click.option(
    "--margin",
    type=float,
    default=0.5,
    show_default=True,
    metavar="M",
    help="Unknown border around the map, metres.",
)
@click.option("--inflate", type=float, default=0.0, metavar="MM", help="Grow walls by MM.")
@click.option(
    "--forbidden-as-walls",
    is_flag=True,
    help="Draw forbidden areas and lines into the map as walls.",
)
@click.option(
    "--log",
    "log_path",
    type=InputFile(),
    metavar="LOG.2d",
    help="Free space = the cells this laser log's beams pass through (the log must be in "
    "the map's frame: its robotGlobal: poses, else its odometry).",
)
@force_option
@json_option
def rasterize(
    map_file: str,
    output: str | None,
    resolution: float,
    mode: str,
    free: str,
    png: bool,
    keepout: bool,
    speed_mask: bool,
    margin: float,
    inflate: float,
    forbidden_as_walls: bool,
    log_path: str | None,
    force: bool,
    as_json: bool,
) -> None:
    """Rasterise MAP_FILE into a ROS map_server / Nav2 map (YAML + image).

    The image is north up, free 254 / occupied 0 / unknown 205 as map_saver writes it; the
    YAML gives the origin of the lower-left pixel in metres. With --keepout, forbidden areas
    and lines become a Nav2 keepout mask on the same grid, with a parameters file that runs
    the filter unchanged.

    \b
    Example:
      mapkit rasterize office.map -o office.yaml --keepout
      ros2 run nav2_map_server map_server --ros-args -p yaml_filename:=office.yaml
    """
    from mapkit.formats.map import load
    from mapkit.raster.export import export_ros, planned_outputs

    yaml_path = Path(output) if output else Path(Path(map_file).stem + ".yaml")
    fmt = "png" if png or (mode == "scale") else "pgm"
    _refuse_existing(
        planned_outputs(yaml_path, image_format=fmt, keepout=keepout, speed=speed_mask), force
    )
    m = load(map_file)
    with RowsBar("rasterising") as bar:
        result = export_ros(
            m,
            yaml_path,
            resolution=resolution,
            margin_m=margin,
            free=free,  # type: ignore[arg-type]
            inflate_mm=inflate,
            forbidden_as_walls=forbidden_as_walls,
            mode=mode,  # type: ignore[arg-type]
            image_format="png" if png else None,
            keepout=keepout,
            speed=speed_mask,
            progress=bar.update,
            log=log_path,
            warn=lambda text: err(f"mapkit: warning: {text}"),
        )
    if as_json:
        echo_json(result.to_dict())
        return
    g = result.grid
    c = g.counts()
    click.echo(
        f"wrote {result.map_files.yaml} and {result.map_files.image}: {g.width} x {g.height} "
        f"cells at {g.resolution:g} m, origin ({g.origin[0]:g}, {g.origin[1]:g}) m, "
        f"{c['occupied']} occupied, {c['free']} free, {c['unknown']} unknown"
    )
    f = result.filters
    if f is not None:
        if f.keepout_yaml is not None:
            click.echo(
                f"wrote {f.keepout_yaml} and {f.keepout_image}: "
                f"{plural(f.keepout_zones, 'keepout zone')}"
            )
        if f.speed_yaml is not None:
            click.echo(
                f"wrote {f.speed_yaml} and {f.speed_image}: {plural(f.speed_zones, 'speed zone')}, "
                f"{f.speed_multiplier:g} m/s per unit"
            )
        click.echo(f"wrote {f.params} (Nav2 costmap filter parameters)")


@click.command("import-ros")
@click.argument("yaml_file", type=InputFile())
@output_option("The .map to write. Default: YAML's name with .map, in the current folder.")
@click.option(
    "--keepout",
    type=InputFile(),
    metavar="MASK.yaml",
    help="A keepout mask (map_server YAML) to import as forbidden areas.",
)
@click.option(
    "--flavor",
    type=click.Choice(["ros1", "nav2"]),
    default="ros1",
    show_default=True,
    help="Read the image as ROS 1 map_server or Nav2 does.",
)
@click.option(
    "--min-line",
    type=float,
    default=0.3,
    show_default=True,
    metavar="M",
    help="Shortest wall line to extract, metres.",
)
@click.option("--no-lines", is_flag=True, help="Points only; no wall lines.")
@force_option
@json_option
def import_ros(
    yaml_file: str,
    output: str | None,
    keepout: str | None,
    flavor: str,
    min_line: float,
    no_lines: bool,
    force: bool,
    as_json: bool,
) -> None:
    """Turn a ROS map_server map (YAML + image) into an ARIA .map.

    Occupied cells become points at their centres, wall faces become lines, the origin is kept
    (no x/y swap); a keepout mask becomes forbidden areas.

    \b
    Example:
      mapkit import-ros office.yaml -o office.map --keepout office_keepout.yaml
    """
    from mapkit.formats.map import save
    from mapkit.raster.import_ros import import_ros as do_import

    out = Path(output) if output else Path(Path(yaml_file).stem + ".map")
    _refuse_existing([out], force)
    from mapkit.cli.logs import _Bar

    bar = _Bar("importing rows", enabled=not as_json)
    try:
        m = do_import(
            yaml_file,
            keepout=keepout,
            flavor=flavor,  # type: ignore[arg-type]
            lines=not no_lines,
            min_line_m=min_line,
            progress=bar,
        )
    finally:
        bar.close()
    md5 = save(m, out)
    areas = sum(1 for o in m.objects if o.type == "ForbiddenArea")
    lines = sum(1 for o in m.objects if o.type == "ForbiddenLine")
    if as_json:
        echo_json(
            {
                "map": os.fspath(out),
                "md5": md5,
                "points": m.scan.num_points,
                "lines": m.scan.num_lines,
                "forbidden_areas": areas,
                "forbidden_lines": lines,
            }
        )
        return
    click.echo(
        f"wrote {out} (MD5 {md5}): {plural(m.scan.num_points, 'point')}, "
        f"{plural(m.scan.num_lines, 'line')}, {plural(areas, 'forbidden area')}, "
        f"{plural(lines, 'forbidden line')}"
    )
