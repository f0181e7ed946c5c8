"""The ``mapkit`` command: a click group whose commands are imported only when they run.

Adding a command is one line in :data:`COMMANDS`: its name, where it lives (``module:attribute``)
and the one-line help ``mapkit --help`` shows (a test checks it matches the command's own help).
``mapkit --help`` imports no command module and no numpy; ``mapkit info`` imports only what
``info`` needs.

One rule for errors, for every command, in one place (:meth:`MapkitGroup.invoke`); see
:data:`EXIT_RULE`, which ``mapkit --help`` and ``docs/cli.md`` print.
"""

from __future__ import annotations

import contextlib
import errno
import importlib
import logging
import os
import sys
from typing import Any, NoReturn

import click

import mapkit
from mapkit.errors import MapkitError

#: name -> (``module:attribute``, the one-line help of ``mapkit --help``). One line per command.
COMMANDS: dict[str, tuple[str, str]] = {
    "add-dock": ("mapkit.cli.edit:add_dock_cmd", "Add a dock NAME at X Y (millimetres)."),
    "add-goal": ("mapkit.cli.edit:add_goal_cmd", "Add a goal NAME at X Y (millimetres)."),
    "add-home": (
        "mapkit.cli.edit:add_home_cmd",
        "Add a RobotHome: a start pose X Y [--heading] or a start region --area.",
    ),
    "add-object": (
        "mapkit.cli.edit:add_object_cmd",
        "Add an object of any TYPE the map declares: sectors, boundaries, "
        "goal/dock/location types.",
    ),
    "aria": (
        "mapkit.cli.aria:aria",
        "ARNL/ARAM robots over ArNetworking (port 7272): maps, files, the active map.",
    ),
    "build": ("mapkit.cli.logs:build", "Build a map from a .2d laser log, as Mapper3 did."),
    "codes": (
        "mapkit.cli.validate:codes",
        "List every finding code: number, name, default severity, summary.",
    ),
    "convert": (
        "mapkit.cli.convert:convert",
        "Read SRC and write DST in the format its suffix names.",
    ),
    "crop": (
        "mapkit.cli.edit:crop_cmd",
        "Keep only the data inside a region; objects wholly outside it are removed.",
    ),
    "demo": (
        "mapkit.cli.demo:demo",
        "Run the whole job on a bundled sample into FOLDER (default: mapkit-demo).",
    ),
    "diff": ("mapkit.cli.edit:diff_cmd", "Show what differs from map A to map B."),
    "draw-line": (
        "mapkit.cli.edit:draw_line_cmd",
        "Add a line segment from X1 Y1 to X2 Y2 to the map data (a wall the scan missed).",
    ),
    "edit": (
        "mapkit.cli.edit:edit_cmd",
        "Apply a batch of edits from a YAML or JSON file as one atomic change.",
    ),
    "erase": (
        "mapkit.cli.edit:erase_cmd",
        "Remove the points inside a region and cut away the parts of lines inside it.",
    ),
    "export-mesh": (
        "mapkit.cli.mesh:export_mesh",
        "A 3D wall mesh (STL/OBJ/GLB/DAE) and a Gazebo world.",
    ),
    "fetch": (
        "mapkit.cli.transfer:fetch",
        "Fetch the map NAME from a robot (`mapkit maps` lists them; "
        "`active.map` is the active one).",
    ),
    "forbid": (
        "mapkit.cli.edit:forbid_cmd",
        "Add a ForbiddenArea (--area) or a ForbiddenLine (--line).",
    ),
    "import-ros": (
        "mapkit.cli.rasterize:import_ros",
        "Turn a ROS map_server map (YAML + image) into an ARIA .map.",
    ),
    "info": (
        "mapkit.cli.info:info",
        "Show what MAP_FILE holds: category, counts, bounds, objects, info sections, MD5.",
    ),
    "load": (
        "mapkit.cli.transfer:load",
        "Make the map NAME on the robot its active map (checked: MD5, then parsed).",
    ),
    "log-info": (
        "mapkit.cli.logs:log_info",
        "Show what a .2d laser log holds: version, lasers, scans, events, time, path length.",
    ),
    "maps": (
        "mapkit.cli.transfer:maps",
        "List the maps on a robot: name, size, MD5 and which one is active.",
    ),
    "merge": (
        "mapkit.cli.edit:merge_cmd",
        "Insert map OTHER into BASE (Mapper3's Insert Map); BASE changes unless -o.",
    ),
    "move": (
        "mapkit.cli.edit:move_cmd",
        "Move the object NAME (or #N) to X Y, or --by DX DY; and/or set its --heading.",
    ),
    "objects": (
        "mapkit.cli.edit:objects_cmd",
        "List the objects of MAP, numbered as #N for remove, rename and move.",
    ),
    "open": (
        "mapkit.cli.open:open_cmd",
        "Edit FILE (an ARIA .map, or a ROS map YAML and its keepout zones) in the browser.",
    ),
    "rasterize": (
        "mapkit.cli.rasterize:rasterize",
        "Rasterise MAP_FILE into a ROS map_server / Nav2 map (YAML + image).",
    ),
    "receive": (
        "mapkit.cli.transfer:receive",
        "Receive maps and .2d logs that a robot sends here (`mapkit send` on the robot).",
    ),
    "remove": (
        "mapkit.cli.edit:remove_cmd",
        "Remove objects by NAME (case-insensitive) or #N (see mapkit objects).",
    ),
    "rename": (
        "mapkit.cli.edit:rename_cmd",
        "Rename the object NAME (or #N) to NEW_NAME; its CairnInfo: Params follow.",
    ),
    "render": ("mapkit.cli.render:render", "Draw a map as PNG, SVG or PDF, or in a window."),
    "ros": (
        "mapkit.cli.ros:ros",
        "Maps over ROS 1: transfer between nodes, and a map server for ARIA maps.",
    ),
    "ros2": (
        "mapkit.cli.ros2:ros2",
        "Maps on ROS 2 (Humble, Jazzy) over DDS; needs `pip install 'mapkit[ros2]'`, not ROS 2.",
    ),
    "samples": (
        "mapkit.cli.samples:samples",
        "List the maps and laser logs bundled with mapkit, or copy some into a folder.",
    ),
    "send": (
        "mapkit.cli.transfer:send",
        "Send FILE (a .map or .2d) to a robot or terminal at HOST[:PORT] (default port 7373).",
    ),
    "serve": (
        "mapkit.cli.transfer:serve",
        "Serve the maps in FOLDER to terminals: push, pull, list and load (run on the robot).",
    ),
    "simulate": (
        "mapkit.cli.logs:simulate",
        "Drive a simulated robot through MAP_FILE and write the laser log it would record.",
    ),
    "transform": (
        "mapkit.cli.edit:transform_cmd",
        "Move the whole map: points, lines and every object together; headings follow.",
    ),
    "turn-error": (
        "mapkit.cli.logs:turn_error",
        "Learn how far a robot's odometry errs in its turns from several of its .2d logs.",
    ),
    "validate": (
        "mapkit.cli.validate:validate",
        "Check MAP_FILE and list every finding with a stable code (mapkit codes lists them).",
    ),
}

#: Exit status and error output, the same for every command.
EXIT_RULE = """\b
Exit status, every command:
  0    done (diff: the maps are equal; validate: no errors)
  1    the work failed: a map that is not valid, a refused edit, a write or
       transfer that failed (diff: the maps differ; validate: errors found)
  2    bad usage, or an input file that is missing or cannot be read
       (diff, validate: also any input that cannot be read as a map)
  130  interrupted (Ctrl-C); servers (serve, receive, ros serve, ros receive,
       ros map-server) run until Ctrl-C, which stops them with 0
Errors are one line on stderr (--debug shows the traceback). Output cut
short by a closed pipe (mapkit ... | head) ends quietly with 141. A file
is never half-written: a failed or interrupted write leaves it as it was."""

#: Exit statuses (see :data:`EXIT_RULE`).
EXIT_FAILED, EXIT_USAGE, EXIT_INTERRUPTED, EXIT_BROKEN_PIPE = 1, 2, 130, 141


class CommandError(click.ClickException):
    """One line on stderr (``Error: ...``) and an exit status."""

    def __init__(self, message: str, exit_code: int = EXIT_FAILED) -> None:
        super().__init__(message)
        setattr(self, "exit_code", exit_code)  # noqa: B010 (a ClassVar in click's typing)


def error_message(err: BaseException) -> tuple[str, int]:
    """The one line and the exit status for an error a command raised."""
    from mapkit._atomic import ReadOnlyFileError, WriteError

    if isinstance(err, ReadOnlyFileError):
        return (
            f"cannot write {err.filename}: {err.strerror}; add --force to replace it",
            EXIT_FAILED,
        )
    if isinstance(err, WriteError):
        return f"cannot write {err.filename}: {err.strerror}", EXIT_FAILED
    if (
        isinstance(err, OSError)
        and err.errno in (errno.EACCES, errno.EPERM, errno.EROFS)
        and isinstance(err.filename, str)
        and not os.path.exists(err.filename)
    ):  # not there and not allowed: making it (a folder, a file) was refused
        from mapkit._atomic import write_error

        return error_message(write_error(err.filename, err))
    if isinstance(err, OSError) and err.filename is not None:
        reason = {
            errno.ENOENT: "no such file",
            errno.EISDIR: "it is a folder",
            errno.EACCES: "permission denied",
            errno.ENOTDIR: "a part of the path is not a folder",
        }.get(err.errno or 0, err.strerror or str(err))
        return f"cannot read {err.filename}: {reason}", EXIT_USAGE
    return str(err), EXIT_FAILED


def _stop_on_broken_pipe() -> NoReturn:
    """The reader went away (``| head``): end quietly, without Python's complaint at exit."""
    with contextlib.suppress(OSError, ValueError):
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    sys.exit(EXIT_BROKEN_PIPE)


class MapkitGroup(click.Group):
    """A click group with commands imported on first use and one error rule for all of them."""

    def __init__(
        self, *args: Any, lazy: dict[str, tuple[str, str]] | None = None, **kwargs: Any
    ) -> None:
        super().__init__(*args, **kwargs)
        self.lazy = dict(lazy or {})

    def list_commands(self, ctx: click.Context) -> list[str]:
        return sorted({*self.commands, *self.lazy})

    def get_command(self, ctx: click.Context, cmd_name: str) -> click.Command | None:
        if cmd_name not in self.commands and cmd_name in self.lazy:
            module, _, attr = self.lazy[cmd_name][0].partition(":")
            command = getattr(importlib.import_module(module), attr)
            self.add_command(command, cmd_name)
        return self.commands.get(cmd_name)

    def format_commands(self, ctx: click.Context, formatter: click.HelpFormatter) -> None:
        """The command list from the table, so ``mapkit --help`` imports no command module."""
        names = self.list_commands(ctx)
        limit = formatter.width - 6 - max((len(n) for n in names), default=0)
        rows = [
            (
                name,
                click.Command(name, help=self.lazy[name][1]).get_short_help_str(limit)
                if name in self.lazy and name not in self.commands
                else self.commands[name].get_short_help_str(limit),
            )
            for name in names
        ]
        if rows:
            with formatter.section("Commands"):
                formatter.write_dl(rows)

    def invoke(self, ctx: click.Context) -> Any:
        try:
            return super().invoke(ctx)
        except KeyboardInterrupt:
            raise CommandError("interrupted", EXIT_INTERRUPTED) from None
        except BrokenPipeError:
            _stop_on_broken_pipe()
        except (MapkitError, OSError) as err:
            if ctx.obj and ctx.obj.get("debug"):
                raise
            message, code = error_message(err)
            raise CommandError(message, code) from err

    def main(self, *args: Any, **kwargs: Any) -> Any:
        try:
            return super().main(*args, **kwargs)
        except BrokenPipeError:  # while click itself printed (help, an error)
            _stop_on_broken_pipe()


def quiet_requested() -> bool:
    """True when ``mapkit -q`` asked for errors only."""
    ctx = click.get_current_context(silent=True)
    return bool(ctx and isinstance(ctx.find_root().obj, dict) and ctx.find_root().obj.get("quiet"))


@click.group(
    cls=MapkitGroup,
    lazy=COMMANDS,
    epilog=EXIT_RULE,
    context_settings={"help_option_names": ["-h", "--help"]},
)
@click.version_option(mapkit.__version__, "--version", prog_name="mapkit")
@click.option("-v", "--verbose", count=True, help="More log output (repeat for debug).")
@click.option(
    "-q",
    "--quiet",
    is_flag=True,
    help="Print only errors (and what --json asks for); the exit status tells the rest.",
)
@click.option("--debug", is_flag=True, help="Show tracebacks instead of one-line errors.")
@click.pass_context
def cli(ctx: click.Context, verbose: int, quiet: bool, debug: bool) -> None:
    """mapkit: ARIA/ARNL maps and laser logs, from the command line.

    Read, write, build, edit, validate, rasterise and transfer ARIA .map files and .2d laser
    logs, and bridge them to ROS. Run `mapkit COMMAND --help` for each command.
    """
    ctx.ensure_object(dict)
    ctx.obj["debug"] = debug
    ctx.obj["quiet"] = quiet
    level = (
        logging.ERROR if quiet else (logging.WARNING, logging.INFO, logging.DEBUG)[min(verbose, 2)]
    )
    logging.basicConfig(level=level, format="mapkit: %(message)s", stream=sys.stderr)
    if quiet:  # reports, notes and progress go nowhere; errors are printed after this closes
        ctx.obj["stdout"] = sys.stdout
        sink = ctx.with_resource(open(os.devnull, "w", encoding="utf-8"))  # noqa: SIM115
        ctx.with_resource(contextlib.redirect_stdout(sink))
        ctx.with_resource(contextlib.redirect_stderr(sink))


def main() -> None:
    """Entry point for ``python -m mapkit``."""
    cli(prog_name="mapkit")
