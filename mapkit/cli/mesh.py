"""``mapkit export-mesh``: the map's walls as a 3D mesh for simulators, plus a Gazebo world."""

from __future__ import annotations

import os

import click

from mapkit.cli.options import (
    InputFile,
    check_outputs,
    echo_json,
    force_option,
    json_option,
    output_option,
)
from mapkit.formats.registry import read_any
from mapkit.mesh import export_mesh as export

_POSITIVE = click.FloatRange(0, min_open=True)


@click.command("export-mesh", short_help="A 3D wall mesh (STL/OBJ/GLB/DAE) and a Gazebo world.")
@click.argument("map_file", type=InputFile())
@output_option("Mesh to write: .stl, .obj, .glb or .dae.", required=True)
@click.option("--height", type=_POSITIVE, default=2.0, show_default=True, help="Wall height (m).")
@click.option(
    "--thickness",
    type=_POSITIVE,
    default=0.1,
    show_default=True,
    help="Wall thickness (m) for walls made from LINES.",
)
@click.option(
    "--from",
    "source",
    type=click.Choice(["auto", "lines", "points"]),
    default="auto",
    show_default=True,
    help="Make walls from the LINES or from the points' occupied "
    "cells (auto: LINES when the map has any).",
)
@click.option(
    "--resolution",
    type=_POSITIVE,
    default=0.05,
    show_default=True,
    help="Cell size (m) for walls made from points.",
)
@click.option(
    "--world",
    type=click.Path(dir_okay=False),
    default=None,
    help="Gazebo SDF world to write [default: the mesh's name with .sdf].",
)
@click.option("--no-world", is_flag=True, help="Write the mesh only.")
@force_option
@json_option
def export_mesh(
    map_file: str,
    output: str,
    height: float,
    thickness: float,
    source: str,
    resolution: float,
    world: str | None,
    no_world: bool,
    force: bool,
    as_json: bool,
) -> None:
    """Extrude the walls of MAP_FILE into a watertight mesh (metres, z up) and write a Gazebo
    world that loads it as a static model, with the robot's home pose noted.

    \b
    Examples:
      mapkit export-mesh office.map -o walls.stl                # + walls.sdf
      mapkit export-mesh office.map -o walls.dae --height 2.5 --world office.world
      mapkit export-mesh scan.map -o walls.glb --from points --resolution 0.1 --no-world
    """
    if world is not None and no_world:
        raise click.UsageError("--world and --no-world exclude each other")
    if not no_world and world is None:
        world = os.path.splitext(output)[0] + ".sdf"
    check_outputs([p for p in (output, world) if p is not None], force)
    m = read_any(map_file)
    r = export(
        m,
        output,
        height=height,
        thickness=thickness,
        source=source,
        resolution=resolution,
        world=None if no_world else world,
    )
    (x0, y0, z0), (x1, y1, z1) = r.bounds
    if as_json:
        echo_json(
            {
                "path": r.path,
                "format": r.format,
                "world": r.world,
                "source": r.source,
                "vertices": r.vertices,
                "faces": r.faces,
                "watertight": r.watertight,
                "volume": r.volume,
                "bounds": [list(r.bounds[0]), list(r.bounds[1])],
                "home": None
                if r.home is None
                else {
                    "type": r.home.type,
                    "name": r.home.name,
                    "x": r.home.x,
                    "y": r.home.y,
                    "yaw": r.home.yaw,
                },
            }
        )
        return
    click.echo(
        f"wrote {r.path} ({r.format.upper()}, walls from {r.source}: {r.faces} triangles, "
        f"{'watertight' if r.watertight else 'NOT watertight'}, "
        f"{x1 - x0:.2f} x {y1 - y0:.2f} x {z1 - z0:.2f} m, {r.volume:.2f} m3)"
    )
    if r.world:
        where = (
            "no RobotHome or Dock"
            if r.home is None
            else f"robot home {r.home.type} {r.home.name!r} at {r.home.x:.3f}, {r.home.y:.3f} m, "
            f"yaw {r.home.yaw:.3f} rad"
        )
        click.echo(f"wrote {r.world} (Gazebo SDF world; {where})")
