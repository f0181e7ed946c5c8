"""``mapkit ros``: maps over ROS 1 topics, and an ARIA-aware ROS map server.

Every command here starts one rospy node (ROS_MASTER_URI says which master); ROS is imported
only when one of them runs.
"""

from __future__ import annotations

from typing import Any

import click

from mapkit.cli.options import echo_json, err, json_option


@click.group()
def ros() -> None:
    """Maps over ROS 1: transfer between nodes, and a map server for ARIA maps.

    Needs ROS 1 (Debian: ros-core python3-rospy python3-nav-msgs ...) and a running master
    (ROS_MASTER_URI). See docs/ros.md.
    """


@ros.command("map-server")
@click.argument("map_file", type=click.Path(dir_okay=False))
@click.option("--resolution", type=float, default=0.05, show_default=True,
              help="Metres per cell for .map files.")
@click.option("--frame-id", default="map", show_default=True, help="Frame of the published messages.")
@click.option("--free", type=click.Choice(["flood", "hull", "all", "none"]), default="flood",
              show_default=True, help="How free space is decided (see `mapkit rasterize`).")
@json_option
def map_server(map_file: str, resolution: float, frame_id: str, free: str, as_json: bool) -> None:
    """Serve MAP_FILE (.map, or a map_server YAML) to ROS until Ctrl-C.

    Publishes latched /map (nav_msgs/OccupancyGrid) and /map_metadata, serves static_map
    (nav_msgs/GetMap) and change_map (nav_msgs/LoadMap: a .map path or a YAML), and publishes
    the keepout mask (keepout_mask) and goals, homes and docks (map_goals, map_homes, map_docks
    as geometry_msgs/PoseArray) on latched topics. Names are relative: set ROS_NAMESPACE to
    move them.

    \b
    Example:
      mapkit ros map-server office.map --resolution 0.05
      rostopic echo -n1 /map_metadata
    """
    from mapkit.ros.map_server import map_info, run_map_server

    def ready(server: Any) -> None:
        info = map_info(server.current)
        if as_json:
            echo_json(info)
        else:
            err(f"serving {info['file']} on /map: {info['width']} x {info['height']} cells of "
                f"{info['resolution']:g} m, origin ({info['origin'][0]:g}, {info['origin'][1]:g}); "
                f"{len(info['goals'])} goals, {len(info['homes'])} homes, {len(info['docks'])} docks. "
                "Ctrl-C stops.")

    run_map_server(map_file, resolution=resolution, frame_id=frame_id, free=free, on_ready=ready)
