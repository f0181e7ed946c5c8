"""``mapkit aria ...``: ARNL/ARAM robots over ArNetworking (TCP port 7272), as they are.

The password comes from ``--password-file`` or ``$MAPKIT_ARIA_PASSWORD_FILE`` /
``$MAPKIT_ARIA_PASSWORD``, never from the command line. See docs/aria.md.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, TypeVar

import click

from mapkit.cli.options import InputFile, echo_json, err, json_option
from mapkit.cli.transfer import _progress, _quiet, _size

if TYPE_CHECKING:
    from mapkit.arnet import Robot

F = TypeVar("F", bound=Callable[..., Any])


def robot_options(f: F) -> F:
    """``--user``, ``--password-file``, ``--timeout`` (shared with ``mapkit ros aria-bridge``)."""
    f = click.option(
        "--timeout",
        type=float,
        default=15.0,
        show_default=True,
        help="Seconds to wait for the robot before giving up.",
    )(f)
    f = click.option(
        "--password-file",
        type=click.Path(dir_okay=False),
        help="File holding the password (else $MAPKIT_ARIA_PASSWORD_FILE or "
        "$MAPKIT_ARIA_PASSWORD).",
    )(f)
    f = click.option("-u", "--user", default="", help="User name on the robot (ARNL's user file).")(
        f
    )
    return f


def open_robot(host: str, user: str, password_file: str | None, timeout: float) -> Robot:
    """Connect and log in (the password from the file or the environment)."""
    from mapkit.aria import connect, password_from_env

    try:
        return connect(host, user=user, password=password_from_env(password_file), timeout=timeout)
    except ValueError as e:
        raise click.BadParameter(str(e), param_hint="HOST") from e


@click.group()
def aria() -> None:
    """ARNL/ARAM robots over ArNetworking (port 7272): maps, files, the active map.

    Works with the robot's own server (ARNL's arnlServer, ARAM): nothing to install on the
    robot. HOST is host[:port]. See docs/aria.md.
    """


@aria.command()
@click.argument("host")
@robot_options
@json_option
def info(host: str, user: str, password_file: str | None, timeout: float, as_json: bool) -> None:
    """The robot's active map and which map, file and config services this user may use.

    \b
    Example:
      MAPKIT_ARIA_PASSWORD_FILE=~/.robot-pw mapkit aria info robot1 --user admin
    """
    with open_robot(host, user, password_file, timeout) as robot:
        data = robot.info()
    if as_json:
        echo_json(data)
        return
    mid = data["map_id"]
    click.echo(
        f"{data['address']}: ArNetworking server, {data['commands']} commands for "
        f"{'user ' + repr(data['user']) if data['user'] else 'this client'}"
    )
    if data["map"] is not None:
        md5 = f" (MD5 {mid['md5']}, {_size(mid['size'])})" if mid and mid["md5"] else ""
        click.echo(f"active map: {data['map'] or '(none)'}{md5}")
    for svc, cmds in data["services"].items():
        have = [n for n, ok in cmds.items() if ok]
        missing = [n for n, ok in cmds.items() if not ok]
        line = f"{svc}: {', '.join(have) or 'none'}"
        if missing:
            line += f" (not offered to this user: {', '.join(missing)})"
        click.echo(line)
    can = [k.replace("_", " ") for k, ok in data["can"].items() if ok]
    click.echo(f"this user can: {', '.join(can) or 'nothing mapkit uses'}")


@aria.command()
@click.argument("host")
@click.option("--name", help="A map file in the robot's folder (default: the active map).")
@click.option(
    "-o",
    "--output",
    type=click.Path(dir_okay=False),
    help="Local file (default: the map's file name, here).",
)
@click.option(
    "--via",
    type=click.Choice(["auto", "file", "map"]),
    default="auto",
    show_default=True,
    help="file: the robot's exact file; map: rebuilt by the map service; auto: file "
    "when this user may, else map.",
)
@robot_options
@json_option
def fetch(
    host: str,
    name: str | None,
    output: str | None,
    via: str,
    user: str,
    password_file: str | None,
    timeout: float,
    as_json: bool,
) -> None:
    """Fetch the robot's active map (or --name FILE), check it, write it atomically.

    \b
    Example:
      mapkit aria fetch robot1 --user admin -o robot1.map
    """
    t0 = time.monotonic()
    with (
        open_robot(host, user, password_file, timeout) as robot,
        _progress(name or "map", as_json or _quiet(as_json)) as cb,
    ):
        got = robot.fetch(name, via=via, progress=(lambda n, _t: cb(n, n)) if cb else None)
        out = output or os.path.basename(got.name) or "robot.map"
        from mapkit._atomic import atomic_write

        atomic_write(out, got.data)
    result = {
        "file": out,
        "name": got.name,
        "size": len(got.data),
        "md5": got.md5,
        "source": got.source,
        "robot_md5": got.robot_md5,
        "verified": got.verified,
        "points": int(got.map.points.shape[0]),
        "lines": int(got.map.lines.shape[0]),
        "objects": len(got.map.objects),
        "seconds": round(time.monotonic() - t0, 3),
    }
    if as_json:
        echo_json(result)
        return
    check = (
        "matches the robot's map id"
        if got.verified
        else "rebuilt by the robot's map service"
        if got.source != "file"
        else "the robot sent no map id to check it against"
    )
    click.echo(
        f"wrote {out} (MD5 {got.md5}, {_size(len(got.data))}) from {got.name} on "
        f"{robot.address}: {result['points']} points, {result['lines']} lines, "
        f"{result['objects']} objects; {check}"
    )


@aria.command()
@click.argument("map_file", metavar="MAP", type=InputFile())
@click.argument("host")
@click.option("--name", help="File name on the robot (default: MAP's name).")
@click.option(
    "--load",
    "and_load",
    is_flag=True,
    help="Make it the robot's active map (through its config, as MobilePlanner does).",
)
@robot_options
@json_option
def send(
    map_file: str,
    host: str,
    name: str | None,
    and_load: bool,
    user: str,
    password_file: str | None,
    timeout: float,
    as_json: bool,
) -> None:
    """Upload MAP to the robot's map folder; with --load make it the active map.

    Maps with `mapkit validate` errors are refused before anything is sent. With --load the
    robot's map-changed broadcast and its map id confirm the switch; a map the robot cannot
    load is undone (its previous file and active map are put back).

    \b
    Example:
      mapkit aria send office.map robot1 --user admin --load
    """
    with (
        open_robot(host, user, password_file, timeout) as robot,
        _progress(os.path.basename(map_file), as_json or _quiet(as_json)) as cb,
    ):
        result = robot.send_map(map_file, name, load=and_load, progress=cb)
        address = robot.address
    if as_json:
        echo_json(result)
        return
    click.echo(
        f"sent {map_file} to {address} as {result['name']} ({_size(result['size'])}, "
        f"MD5 {result['md5']})"
    )
    if and_load:
        click.echo(
            f"active map on {address} is now {result['name']} (was {result['previous']}; "
            f"robot map id MD5 {result['robot_md5'] or '-'})"
        )


@aria.command("ls")
@click.argument("host")
@click.argument("folder", default="", required=False)
@robot_options
@json_option
def ls(
    host: str, folder: str, user: str, password_file: str | None, timeout: float, as_json: bool
) -> None:
    """List a folder of the robot (default: the top of what it shares).

    \b
    Example:
      mapkit aria ls robot1 logs --user admin
    """
    with open_robot(host, user, password_file, timeout) as robot:
        entries = robot.files(folder)
    rows: list[dict[str, Any]] = [
        {"name": e.name, "type": "dir" if e.is_dir else "file", "size": e.size, "mtime": e.mtime}
        for e in entries
    ]
    if as_json:
        echo_json({"folder": folder, "entries": rows})
        return
    if not rows:
        click.echo(f"{folder or '.'}: empty")
    for r in rows:
        when = time.strftime("%Y-%m-%d %H:%M", time.localtime(r["mtime"]))
        size = "-" if r["type"] == "dir" else _size(r["size"])
        click.echo(f"{r['name'] + ('/' if r['type'] == 'dir' else ''):<40} {size:>9}  {when}")


@aria.command()
@click.argument("host")
@click.argument("remote")
@click.option(
    "-o",
    "--output",
    type=click.Path(dir_okay=False),
    help="Local file (default: REMOTE's file name, here).",
)
@robot_options
def get(
    host: str, remote: str, output: str | None, user: str, password_file: str | None, timeout: float
) -> None:
    """Download a robot file (a map, a .2d laser log ...); written atomically.

    \b
    Example:
      mapkit aria get robot1 logs/run1.2d && mapkit build run1.2d -o run1.map
    """
    out = output or os.path.basename(remote)
    with (
        open_robot(host, user, password_file, timeout) as robot,
        _progress(remote, _quiet(False)) as cb,
    ):
        n = robot.get_file(remote, out, progress=(lambda d, _t: cb(d, d)) if cb else None)
    click.echo(f"wrote {out} ({_size(n)}) from {remote} on {host}")


@aria.command()
@click.argument("local", type=InputFile())
@click.argument("host")
@click.argument("remote")
@robot_options
def put(
    local: str, host: str, remote: str, user: str, password_file: str | None, timeout: float
) -> None:
    """Upload a file to the robot as REMOTE (any file; `send` checks maps first).

    \b
    Example:
      mapkit aria put notes.txt robot1 notes.txt --user admin
    """
    import mmap

    with (
        open(local, "rb") as fh,
        open_robot(host, user, password_file, timeout) as robot,
        _progress(os.path.basename(local), _quiet(False)) as cb,
    ):
        size = os.fstat(fh.fileno()).st_size
        # mapped, not read: a large laser log is sent without holding it all in memory
        data = mmap.mmap(fh.fileno(), 0, access=mmap.ACCESS_READ) if size else b""
        try:
            robot.put_file(data, remote, progress=cb)
        finally:
            if isinstance(data, mmap.mmap):
                data.close()
    click.echo(f"sent {local} to {host} as {remote} ({_size(size)})")


@aria.command()
@click.argument("host")
@click.argument("remote")
@robot_options
def rm(host: str, remote: str, user: str, password_file: str | None, timeout: float) -> None:
    """Delete a robot file.

    \b
    Example:
      mapkit aria rm robot1 old.map --user admin
    """
    with open_robot(host, user, password_file, timeout) as robot:
        robot.delete_file(remote)
    click.echo(f"deleted {remote} on {host}")


@aria.command()
@click.argument("host")
@click.option(
    "--save-dir",
    type=click.Path(file_okay=False),
    help="Keep each version of the map there (NAME-DATE-TIME-MD5.map).",
)
@click.option(
    "--count", type=int, default=0, help="Stop after this many changes (default: run until Ctrl-C)."
)
@robot_options
@json_option
def watch(
    host: str,
    save_dir: str | None,
    count: int,
    user: str,
    password_file: str | None,
    timeout: float,
    as_json: bool,
) -> None:
    """Print the robot's active map, then each change as it happens (Ctrl-C stops).

    \b
    Example:
      mapkit aria watch robot1 --user admin --save-dir robot1-maps
    """
    import json

    seen = 0
    with open_robot(host, user, password_file, timeout) as robot:
        try:
            for ch in robot.watch(save_dir=save_dir):
                row = {
                    "time": time.strftime("%Y-%m-%dT%H:%M:%S", time.localtime(ch.time)),
                    "initial": ch.initial,
                    "name": ch.name,
                    "md5": ch.md5,
                    "size": ch.size,
                    "source": ch.source,
                    "points": int(ch.map.points.shape[0]),
                    "objects": len(ch.map.objects),
                    "saved": ch.saved,
                }
                if as_json:
                    click.echo(json.dumps(row))
                else:
                    what = "active map" if ch.initial else "map changed to"
                    kept = f", kept as {ch.saved}" if ch.saved else ""
                    click.echo(
                        f"{row['time']} {what} {ch.name} (MD5 {ch.md5}, {_size(ch.size)}, "
                        f"{row['points']} points, {row['objects']} objects){kept}"
                    )
                if not ch.initial:
                    seen += 1
                    if count and seen >= count:
                        break
        except KeyboardInterrupt:
            err("stopped")
