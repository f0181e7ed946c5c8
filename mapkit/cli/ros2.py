"""``mapkit ros2``: maps on ROS 2 topics over DDS, with no ROS 2 install (see docs/ros2.md)."""

from __future__ import annotations

import json
import signal
import threading
from typing import Any

import click

from mapkit.cli.aria import robot_options as _aria_robot_options
from mapkit.cli.options import err, json_option


@click.group()
def ros2() -> None:
    """Maps on ROS 2 (Humble, Jazzy) over DDS; needs `pip install 'mapkit[ros2]'`, not ROS 2.

    Joins the DDS domain ROS_DOMAIN_ID (--domain) on the local network, as a ROS 2 node would.
    See docs/ros2.md.
    """


def _common(f: Any) -> Any:
    f = json_option(f)
    f = click.option(
        "--distro",
        type=click.Choice(["jazzy", "humble"]),
        default="jazzy",
        show_default=True,
        help="Whose discovery layout to announce (type hashes, "
        "Gid size); the map topics are the same for both.",
    )(f)
    f = click.option(
        "--free",
        type=click.Choice(["flood", "hull", "all", "none"]),
        default="flood",
        show_default=True,
        help="How free space is decided (see `mapkit rasterize`).",
    )(f)
    f = click.option(
        "--resolution",
        type=float,
        default=0.05,
        show_default=True,
        help="Metres per cell for .map files.",
    )(f)
    f = click.option(
        "--frame",
        "frame_id",
        default="map",
        show_default=True,
        help="Frame of the published messages.",
    )(f)
    f = click.option(
        "--topic", default="map", show_default=True, help="The grid's topic (nav2: map)."
    )(f)
    return click.option(
        "--domain",
        type=click.IntRange(0, 232),
        envvar="ROS_DOMAIN_ID",
        default=0,
        show_default=True,
        help="ROS 2 domain (ROS_DOMAIN_ID).",
    )(f)


def _stop_event() -> threading.Event:
    stop = threading.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_a: stop.set())
    return stop


def _report(server: Any, as_json: bool, extra: dict[str, Any] | None = None) -> None:
    from mapkit.ros.map_server import map_info

    info = map_info(server.current)
    info["topic"] = server.topics.map
    info.update(extra or {})
    if as_json:
        click.echo(json.dumps(info))
    else:
        err(
            f"serving {info['name']} on ROS 2 /{info['topic'].lstrip('/')}: {info['width']} x "
            f"{info['height']} cells of {info['resolution']:g} m; {len(info['goals'])} goals"
            f"{'; keepout mask' if info['keepout'] else ''}. Ctrl-C stops."
        )


@ros2.command("map-server")
@click.argument("map_file", type=click.Path(dir_okay=False))
@_common
def map_server(
    map_file: str,
    domain: int,
    topic: str,
    frame_id: str,
    resolution: float,
    free: str,
    distro: str,
    as_json: bool,
) -> None:
    """Serve MAP_FILE (.map, or a map_server YAML) on ROS 2 as nav2's map_server does.

    /map (reliable, transient-local, depth 1), /keepout_filter_mask + /costmap_filter_info for
    Nav2's KeepoutFilter, /map_goals, /map_homes, /map_docks (geometry_msgs/PoseArray).
    Republishes when MAP_FILE changes on disk; a broken change keeps the old map.

    \b
    Example:
      mapkit ros2 map-server office.map --domain 3
      ros2 topic echo --qos-durability transient_local --once /map --field info
    """
    from mapkit.ros2.graph import resolve_topic
    from mapkit.ros2.map_server import Topics, run_map_server

    stop = _stop_event()
    run_map_server(
        map_file,
        domain=domain,
        topics=Topics(map=resolve_topic(topic)),
        frame_id=frame_id,
        distro=distro,
        stop=stop,
        resolution=resolution,
        free=free,
        on_publish=lambda s: _report(s, as_json),
        on_error=lambda e: err(f"warning: {e}; still serving the previous map"),
    )


@ros2.command("aria-bridge")
@click.argument("host")
@_common
@_aria_robot_options
def aria_bridge(
    host: str,
    domain: int,
    topic: str,
    frame_id: str,
    resolution: float,
    free: str,
    distro: str,
    as_json: bool,
    user: str,
    password_file: str | None,
    timeout: float,
) -> None:
    """Publish an ARNL/ARAM robot's active map on ROS 2; republish when the robot changes it.

    The robot is reached over ArNetworking (HOST is host[:port], port 7272). Topics as
    `mapkit ros2 map-server`.

    \b
    Example:
      MAPKIT_ARIA_PASSWORD_FILE=~/.robot-pw mapkit ros2 aria-bridge robot1 -u admin --domain 3
    """
    from mapkit.cli.aria import open_robot
    from mapkit.ros2.graph import resolve_topic
    from mapkit.ros2.map_server import Topics, run_aria_bridge

    stop = _stop_event()
    with open_robot(host, user, password_file, timeout) as robot:
        run_aria_bridge(
            robot,
            domain=domain,
            topics=Topics(map=resolve_topic(topic)),
            frame_id=frame_id,
            distro=distro,
            stop=stop,
            resolution=resolution,
            free=free,
            on_publish=lambda s, c: _report(s, as_json, {"robot_map": c.name}),
        )
