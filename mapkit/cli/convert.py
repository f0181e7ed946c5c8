"""``mapkit convert``: rewrite a map (canonical ARIA form now; other formats by output suffix)."""

from __future__ import annotations

import click

from mapkit.cli.options import InputFile, check_outputs, force_option
from mapkit.formats.registry import convert_file


@click.command()
@click.argument("src", type=InputFile())
@click.argument("dst", type=click.Path(dir_okay=False))
@force_option
def convert(src: str, dst: str, force: bool) -> None:
    """Read SRC and write DST in the format its suffix names.

    A .map output is ARIA's canonical form: the bytes ARIA's own writer would emit.

    \b
    Example:
      mapkit convert scanned.map clean.map
    """
    check_outputs([dst], force, same_as=src)
    click.echo(convert_file(src, dst))
