"""The ``mapkit`` command: a click group; each command lives in its own module.

Every :class:`~mapkit.errors.MapkitError` (and file-system error) becomes one line on stderr and
a non-zero exit here, in one place; ``--debug`` shows the traceback instead.
"""

from __future__ import annotations

import logging
import sys
from typing import Any

import click

import mapkit
from mapkit.errors import MapkitError


class MapkitGroup(click.Group):
    """A click group that turns mapkit's errors into one clear line and exit code 1."""

    def invoke(self, ctx: click.Context) -> Any:
        try:
            return super().invoke(ctx)
        except (MapkitError, OSError) as err:
            if ctx.obj and ctx.obj.get("debug"):
                raise
            if isinstance(err, OSError) and err.filename and err.strerror:
                message = f"{err.filename}: {err.strerror}"
            else:
                message = str(err)
            raise click.ClickException(message) from err


@click.group(cls=MapkitGroup, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(mapkit.__version__, "--version", prog_name="mapkit")
@click.option("-v", "--verbose", count=True, help="More log output (repeat for debug).")
@click.option("-q", "--quiet", is_flag=True, help="Only errors.")
@click.option("--debug", is_flag=True, help="Show tracebacks instead of one-line errors.")
@click.pass_context
def cli(ctx: click.Context, verbose: int, quiet: bool, debug: bool) -> None:
    """mapkit: ARIA/ARNL maps and laser logs, from the command line.

    Read, write, build, edit, validate, rasterise and transfer ARIA .map files and .2d laser
    logs, and bridge them to ROS. Run `mapkit COMMAND --help` for each command.
    """
    ctx.ensure_object(dict)
    ctx.obj["debug"] = debug
    level = logging.ERROR if quiet else (logging.WARNING, logging.INFO, logging.DEBUG)[min(verbose, 2)]
    logging.basicConfig(level=level, format="mapkit: %(message)s", stream=sys.stderr)


# Commands are registered explicitly, one module per command or command group.
from mapkit.cli import convert as _convert  # noqa: E402
from mapkit.cli import demo as _demo  # noqa: E402
from mapkit.cli import edit as _edit  # noqa: E402
from mapkit.cli import info as _info  # noqa: E402
from mapkit.cli import logs as _logs  # noqa: E402
from mapkit.cli import mesh as _mesh  # noqa: E402
from mapkit.cli import rasterize as _rasterize  # noqa: E402
from mapkit.cli import render as _render  # noqa: E402
from mapkit.cli import ros as _ros  # noqa: E402
from mapkit.cli import samples as _samples  # noqa: E402
from mapkit.cli import transfer as _transfer  # noqa: E402
from mapkit.cli import validate as _validate  # noqa: E402

cli.add_command(_demo.demo)
cli.add_command(_info.info)
cli.add_command(_samples.samples)
cli.add_command(_convert.convert)
cli.add_command(_rasterize.rasterize)
cli.add_command(_rasterize.import_ros)
cli.add_command(_validate.validate)
cli.add_command(_validate.codes)
cli.add_command(_render.render)
cli.add_command(_mesh.export_mesh)
for _command in (*_transfer.COMMANDS, *_edit.COMMANDS):
    cli.add_command(_command)
cli.add_command(_ros.ros)
cli.add_command(_logs.simulate)
cli.add_command(_logs.build)
cli.add_command(_logs.log_info)
from mapkit.cli.aria import aria as _aria  # noqa: E402
cli.add_command(_aria)
from mapkit.cli.ros2 import ros2 as _ros2  # noqa: E402
cli.add_command(_ros2)


def main() -> None:
    """Entry point for ``python -m mapkit``."""
    cli(prog_name="mapkit")
