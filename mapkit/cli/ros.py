"""``mapkit ros``: maps over ROS 1 topics, and an ARIA-aware ROS map server.

Every command here starts one rospy node (ROS_MASTER_URI says which master); ROS is imported
only when one of them runs.
"""

from __future__ import annotations

import json
import logging
import time
from typing import Any

import click

from mapkit.cli.aria import robot_options as _aria_robot_options
from mapkit.cli.options import InputFile, RowsBar, echo_json, err, json_option, plural
from mapkit.cli.transfer import _auth_text, _progress, _quiet, _secret_options, _size, print_listing


@click.group()
def ros() -> None:
    """Maps over ROS 1: transfer between nodes, and a map server for ARIA maps.

    Needs ROS 1 (Debian: ros-core python3-rospy python3-nav-msgs ...) and a running master
    (ROS_MASTER_URI). See docs/ros.md.
    """


@ros.command("map-server")
@click.argument("map_file", type=InputFile())
@click.option(
    "--resolution",
    type=float,
    default=0.05,
    show_default=True,
    help="Metres per cell for .map files.",
)
@click.option(
    "--frame-id", default="map", show_default=True, help="Frame of the published messages."
)
@click.option(
    "--free",
    type=click.Choice(["flood", "hull", "all", "none"]),
    default="flood",
    show_default=True,
    help="How free space is decided (see `mapkit rasterize`).",
)
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
            err(
                f"serving {info['file']} on /map: {info['width']} x {info['height']} cells of "
                f"{info['resolution']:g} m, origin ({info['origin'][0]:g}, {info['origin'][1]:g}); "
                f"{plural(len(info['goals']), 'goal')}, {plural(len(info['homes']), 'home')}, "
                f"{plural(len(info['docks']), 'dock')}. "
                "Ctrl-C stops."
            )

    bar = RowsBar("loading map")

    def ready_after_bar(server: Any) -> None:
        bar.__exit__(None, None, None)
        ready(server)

    with bar:
        run_map_server(
            map_file,
            resolution=resolution,
            frame_id=frame_id,
            free=free,
            on_ready=ready_after_bar,
            progress=bar.advance,
        )


@ros.command("aria-bridge")
@click.argument("host")
@click.option("--resolution", type=float, default=0.05, show_default=True, help="Metres per cell.")
@click.option(
    "--frame-id", default="map", show_default=True, help="Frame of the published messages."
)
@click.option(
    "--free",
    type=click.Choice(["flood", "hull", "all", "none"]),
    default="flood",
    show_default=True,
    help="How free space is decided (see `mapkit rasterize`).",
)
@_aria_robot_options
@json_option
def aria_bridge(
    host: str,
    resolution: float,
    frame_id: str,
    free: str,
    user: str,
    password_file: str | None,
    timeout: float,
    as_json: bool,
) -> None:
    """Publish an ARNL/ARAM robot's active map on ROS; republish when the robot changes it.

    The robot is reached over ArNetworking (HOST is host[:port], port 7272; nothing runs on
    the robot). Topics and services as `mapkit ros map-server`: latched /map, /map_metadata,
    /keepout_mask, /map_goals, /map_homes, /map_docks, /map_info, and static_map.

    \b
    Example:
      MAPKIT_ARIA_PASSWORD_FILE=~/.robot-pw mapkit ros aria-bridge robot1 -u admin
    """
    from mapkit.cli.aria import open_robot
    from mapkit.ros.aria_bridge import run_aria_bridge
    from mapkit.ros.map_server import map_info

    def changed(server: Any, change: Any) -> None:
        info = map_info(server.current)
        info["robot_map"] = change.name
        if as_json:
            click.echo(json.dumps(info), nl=True)
        else:
            err(
                f"serving {change.name} from {host} on /map: {info['width']} x {info['height']} "
                f"cells of {info['resolution']:g} m (MD5 {change.md5}); "
                f"{len(info['goals'])} goals. Ctrl-C stops."
            )

    with open_robot(host, user, password_file, timeout) as robot:
        run_aria_bridge(
            robot, resolution=resolution, frame_id=frame_id, free=free, on_change=changed
        )


# -- transfer ---------------------------------------------------------------------------------


def _check_channel(_ctx: Any, _param: Any, value: str) -> str:
    from mapkit.ros.errors import RosError
    from mapkit.ros.transport import check_channel

    try:
        return check_channel(value)
    except RosError as e:
        raise click.BadParameter(str(e)) from e


def _channel_option(f: Any) -> Any:
    return click.option(
        "--channel",
        default="maps",
        show_default=True,
        callback=_check_channel,
        help="Channel: topics mapkit/CHANNEL/{c2r,r2c,announce} in ROS_NAMESPACE.",
    )(f)


def _terminal_options(f: Any) -> Any:
    """--channel, --robot, --timeout, the secret and --json: what fetch, maps and load share."""
    f = json_option(f)
    f = _secret_options(f)
    f = click.option(
        "--timeout",
        type=float,
        default=3.0,
        show_default=True,
        help="Seconds to wait for the robots' announcements.",
    )(f)
    f = click.option("--robot", help="The robot (needed when several serve the channel).")(f)
    return _channel_option(f)


def _robot_side(
    robot_name: str | None, secret_file: str | None, insecure: bool
) -> tuple[bytes | None, str]:
    import socket

    from mapkit.transfer import load_secret

    secret = load_secret(path=secret_file)
    if secret is None and not insecure:
        raise click.UsageError(
            "no shared secret: give --secret-file or set MAPKIT_SECRET "
            "(or --insecure to accept anyone)"
        )
    if not logging.getLogger().level > logging.WARNING:
        logging.getLogger("mapkit.ros").setLevel(logging.INFO)
    return secret, robot_name or socket.gethostname()


def _terminal_side(secret_file: str | None, insecure: bool) -> bytes | None:
    from mapkit.transfer import load_secret

    secret = load_secret(path=secret_file)
    if secret is None and not insecure:
        raise click.UsageError(
            "no shared secret: give --secret-file or set MAPKIT_SECRET "
            "(or --insecure if the robots run with --insecure)"
        )
    return secret


def _run_robot(
    folder: str,
    channel: str,
    robot: str,
    secret: bytes | None,
    insecure: bool,
    features: tuple[str, ...],
    map_server: str | None,
    max_size: int,
    count: int = 0,
    on_received: Any = None,
) -> Any:
    from mapkit.ros.node import start_node, stop_on_signals
    from mapkit.ros.transfer import RobotNode
    from mapkit.ros.transport import RosLink
    from mapkit.transfer import MapFolder

    start_node("mapkit_" + ("serve" if "pull" in features else "receive"))
    node = RobotNode(
        MapFolder(folder, max_size=max_size),
        RosLink(channel, robot=True),
        robot=robot,
        secret=secret,
        insecure=insecure,
        features=features,
        map_server=map_server,
        on_received=on_received,
    )
    kind = "serving" if "pull" in features else "receiving into"
    err(
        f"mapkit ros: robot {robot!r} {kind} {node.folder.root} on channel {channel!r} "
        f"(node {node.link.node}, auth {_auth_text(secret)}). Ctrl-C stops."
    )
    stop_on_signals()
    try:
        node.run(until=(lambda: node.received_count >= count) if count else None)
        if count:  # answer repeats of the last VERIFIED for a moment before leaving
            end = time.monotonic() + 1.0
            node.run(until=lambda: time.monotonic() > end)
    except KeyboardInterrupt:
        pass
    return node


@ros.command("receive")
@click.option(
    "-o",
    "--output",
    "folder",
    type=click.Path(file_okay=False),
    default=".",
    show_default=True,
    help="Folder for received files.",
)
@_channel_option
@click.option("--name", "robot", help="This robot's name (default: the host name).")
@_secret_options
@click.option("--count", type=int, default=0, help="Exit after this many files (default: run on).")
@click.option(
    "--map-server",
    default="change_map",
    show_default=True,
    help="LoadMap service to call when a received map is loaded ('' for none).",
)
@click.option(
    "--max-size",
    type=int,
    default=1 << 30,
    show_default=True,
    help="Largest file accepted (bytes).",
)
@json_option
def receive(
    folder: str,
    channel: str,
    robot: str | None,
    secret_file: str | None,
    insecure: bool,
    count: int,
    map_server: str,
    max_size: int,
    as_json: bool,
) -> None:
    """Receive maps pushed with `mapkit ros send` (run on each robot of the fleet).

    Each file is checked (SHA-256, and a .map must parse) before it is renamed into FOLDER; an
    interrupted transfer resumes when the sender tries again. A terminal may also ask to load a
    received map (`send --load`).

    \b
    Example:
      MAPKIT_SECRET_FILE=/etc/mapkit/secret mapkit ros receive -o ~/maps --name robot1
    """
    secret, name = _robot_side(robot, secret_file, insecure)
    got: list[dict[str, Any]] = []

    def received(info: dict[str, Any]) -> None:
        got.append(info)
        if not as_json:
            click.echo(
                f"received {info['name']} ({_size(info['size'])}, SHA-256 {info['sha256'][:16]}…)"
            )

    _run_robot(
        folder,
        channel,
        name,
        secret,
        insecure,
        ("push", "load"),
        map_server or None,
        max_size,
        count,
        received,
    )
    if as_json:
        echo_json(got)


@ros.command("serve")
@click.argument("folder", type=click.Path(file_okay=False))
@_channel_option
@click.option("--name", "robot", help="This robot's name (default: the host name).")
@_secret_options
@click.option(
    "--map-server",
    default="change_map",
    show_default=True,
    help="LoadMap service to call after a load, so /map follows ('' for none).",
)
@click.option(
    "--max-size",
    type=int,
    default=1 << 30,
    show_default=True,
    help="Largest file accepted (bytes).",
)
def serve(
    folder: str,
    channel: str,
    robot: str | None,
    secret_file: str | None,
    insecure: bool,
    map_server: str,
    max_size: int,
) -> None:
    """Serve the maps in FOLDER over ROS: push, pull, list and load (run on the robot).

    Requests and replies are MKT/1 frames on the channel's topics (std_srvs has no service that
    carries bytes); the latched mapkit/CHANNEL/announce topic lists the maps. A load makes the
    map FOLDER/active.map and calls the map server's change_map, so /map is republished.

    \b
    Example:
      mapkit ros serve ~/maps --name robot1 --secret-file /etc/mapkit/secret
      mapkit ros map-server ~/maps/active.map     # in another terminal: /map for navigation
    """
    secret, name = _robot_side(robot, secret_file, insecure)
    _run_robot(
        folder,
        channel,
        name,
        secret,
        insecure,
        ("push", "pull", "list", "load"),
        map_server or None,
        max_size,
    )


def _fleet_rows(results: list[Any]) -> list[dict[str, Any]]:
    return [
        {
            "robot": r.robot,
            "node": r.node,
            "received": r.received,
            "verified": r.verified,
            "loaded": r.loaded,
            "skipped": r.skipped,
            "resumed_chunks": r.resumed_chunks,
            "chunks_sent": r.chunks_sent,
            "chunks_resent": r.chunks_resent,
            "error": r.error,
            "ok": r.ok,
        }
        for r in results
    ]


@ros.command("send")
@click.argument("file", type=InputFile())
@_channel_option
@click.option("--name", help="Name on the robots (default: the file's name).")
@click.option("--robot", "robots", multiple=True, help="Only this robot (repeat for several).")
@click.option("--expect", type=int, default=0, help="Wait for at least this many robots.")
@click.option(
    "--wait",
    type=float,
    default=3.0,
    show_default=True,
    help="Seconds to wait for robots to announce themselves.",
)
@click.option("--load", "and_load", is_flag=True, help="Then make it each robot's active map.")
@click.option(
    "--chunk-size", type=int, default=256 * 1024, show_default=True, help="Bytes per frame."
)
@click.option(
    "--timeout",
    type=float,
    default=30.0,
    show_default=True,
    help="Give a robot up after this many seconds without an answer.",
)
@_secret_options
@json_option
def send(
    file: str,
    channel: str,
    name: str | None,
    robots: tuple[str, ...],
    expect: int,
    wait: float,
    and_load: bool,
    chunk_size: int,
    timeout: float,
    secret_file: str | None,
    insecure: bool,
    as_json: bool,
) -> None:
    """Send FILE to every robot on the channel at once (`mapkit ros receive` or `serve` there).

    Each robot checks the file (SHA-256; a .map must parse) and reports back; the table shows
    per robot whether it received, verified (and loaded) the file. Exits 1 if any robot failed.

    \b
    Example:
      mapkit ros send office.map --expect 3 --load --secret-file secret
    """
    from mapkit.ros.node import start_node
    from mapkit.ros.transfer import push

    secret = _terminal_side(secret_file, insecure)
    start_node("mapkit_send")
    with _progress(name or file, as_json or _quiet(as_json)) as cb:
        results = push(
            file,
            channel=channel,
            secret=secret,
            name=name,
            robots=robots,
            expect=expect,
            wait=wait,
            load=and_load,
            chunk_size=chunk_size,
            idle_timeout=timeout,
            progress=cb,
        )
    rows = _fleet_rows(results)
    if as_json:
        echo_json(rows)
    else:

        def yn(v: Any) -> str:
            return "-" if v is None else ("yes" if v else "NO")

        width = max(5, *(len(r["robot"]) for r in rows))
        click.echo(f"{'robot':<{width}}  received  verified  loaded  note")
        for r in rows:
            resumed = (
                f"{plural(r['resumed_chunks'], 'chunk')} resumed" if r["resumed_chunks"] else ""
            )
            note = r["error"] or ("already had it" if r["skipped"] else resumed)
            click.echo(
                f"{r['robot']:<{width}}  {yn(r['received']):<8}  {yn(r['verified']):<8}  "
                f"{yn(r['loaded']):<6}  {note}".rstrip()
            )
    failed = [r for r in rows if not r["ok"]]
    if failed:
        raise click.exceptions.Exit(1)


@ros.command("fetch")
@click.argument("name")
@click.option("-o", "--output", type=click.Path(dir_okay=False), help="Local file (default: NAME).")
@click.option("--if-changed", is_flag=True, help="Skip when the local file already matches.")
@_terminal_options
def fetch(
    name: str,
    output: str | None,
    channel: str,
    robot: str | None,
    if_changed: bool,
    timeout: float,
    secret_file: str | None,
    insecure: bool,
    as_json: bool,
) -> None:
    """Fetch the map NAME from a robot running `mapkit ros serve` (`active.map`: its active map).

    \b
    Example:
      mapkit ros fetch office.map -o office.map --robot robot1 --if-changed
    """
    from mapkit.ros.node import start_node
    from mapkit.ros.transfer import fetch as do_fetch

    secret = _terminal_side(secret_file, insecure)
    start_node("mapkit_fetch")
    with _progress(name, as_json or _quiet(as_json)) as cb:
        result = do_fetch(
            name,
            output or name,
            channel=channel,
            secret=secret,
            robot=robot,
            if_changed=if_changed,
            timeout=timeout,
            progress=cb,
        )
    if as_json:
        echo_json(result)
    elif not result["changed"]:
        click.echo(
            f"{result['path']} is up to date (SHA-256 {result['sha256'][:16]}…), nothing fetched"
        )
    else:
        resumed = f", {plural(result['resumed'], 'chunk')} resumed" if result["resumed"] else ""
        click.echo(
            f"fetched {name} from {result['robot']} into {result['path']}: "
            f"{_size(result['size'])}, SHA-256 verified{resumed}"
        )


@ros.command("maps")
@click.option(
    "--all",
    "all_robots",
    is_flag=True,
    help="Every robot's announced maps (the latched topic; no authentication).",
)
@_terminal_options
def maps(
    channel: str,
    robot: str | None,
    all_robots: bool,
    timeout: float,
    secret_file: str | None,
    insecure: bool,
    as_json: bool,
) -> None:
    """List the maps on a robot: name, size, MD5, and which one is active.

    \b
    Example:
      mapkit ros maps --robot robot1
      mapkit ros maps --all
    """
    from mapkit.ros.node import start_node
    from mapkit.ros.transfer import discover, list_maps

    if all_robots:
        start_node("mapkit_maps")
        docs = discover(channel, timeout=timeout)
        if as_json:
            echo_json(docs)
            return
        if not docs:
            click.echo(f"no robot announces itself on channel {channel!r}")
        for d in docs:
            feats = ", ".join(d.get("features", []))
            click.echo(f"{d.get('robot')} ({d.get('node')}): serves {feats}")
            for m in d.get("maps", []):
                mark = "*" if m["name"] == d.get("active") else " "
                click.echo(f"  {mark} {m['name']}  {_size(m['size'])}  {m['md5']}")
        return
    secret = _terminal_side(secret_file, insecure)
    start_node("mapkit_maps")
    listing = list_maps(channel, secret=secret, robot=robot, timeout=timeout)
    if as_json:
        echo_json(listing)
        return
    print_listing(listing, listing["robot"])


@ros.command("load")
@click.argument("name", required=False)
@click.option("--md5", help="Only load if the robot's file has this MD5.")
@click.option("--rollback", is_flag=True, help="Re-activate the previous map.")
@_terminal_options
def load(
    name: str | None,
    channel: str,
    robot: str | None,
    md5: str | None,
    rollback: bool,
    timeout: float,
    secret_file: str | None,
    insecure: bool,
    as_json: bool,
) -> None:
    """Make the map NAME on the robot its active map; its map server republishes /map.

    \b
    Example:
      mapkit ros load office.map --robot robot1
    """
    from mapkit.ros.node import start_node
    from mapkit.ros.transfer import load_map

    if not rollback and not name:
        raise click.UsageError("give a map NAME or --rollback")
    secret = _terminal_side(secret_file, insecure)
    start_node("mapkit_load")
    state = load_map(
        name or "",
        channel=channel,
        secret=secret,
        robot=robot,
        md5=md5,
        rollback=rollback,
        timeout=timeout,
    )
    if as_json:
        echo_json(state)
        return
    ms = state.get("map_server")
    note = {None: "no map server answered", 0: "map server republished /map"}.get(
        ms, f"map server refused it (LoadMap result {ms})"
    )
    click.echo(
        f"active map on {state['robot']} is now {state['name']} (MD5 {state['md5']}); {note}"
    )
