"""diff, and edit: a batch of edits from a YAML or JSON file as one atomic change."""

from __future__ import annotations

import os
import sys
from typing import Any

import click

from mapkit import edit as editing
from mapkit.cli.edit.common import _apply, _map_arg, _writes
from mapkit.cli.options import (
    InputFile,
    echo_json,
    err,
    json_option,
    plural,
)
from mapkit.errors import MapkitError
from mapkit.formats.map import load

__all__ = ["diff_cmd", "edit_cmd"]


# -- diff and scripts --------------------------------------------------------------------------


@click.command("diff")
@click.argument("a", type=InputFile())
@click.argument("b", type=InputFile())
@json_option
def diff_cmd(a: str, b: str, as_json: bool) -> None:
    """Show what differs from map A to map B. Exit 0 when equal, 1 when different, 2 on error.

    \b
    Example:
      mapkit diff office.map office-edited.map
    """
    try:
        ma, mb = load(a), load(b)
    except (MapkitError, OSError) as e:  # 1 means "different" here, so errors are 2
        from mapkit.cli.main import EXIT_USAGE, CommandError, error_message

        raise CommandError(error_message(e)[0], EXIT_USAGE) from e
    d = editing.diff(ma, mb)
    if as_json:
        echo_json(d.to_json())
    elif d.equal:
        click.echo(f"{a} and {b} hold the same map")
    else:
        c = d.counts()
        click.echo(
            f"objects: {c['added']} added, {c['removed']} removed, {c['moved']} moved, "
            f"{c['changed']} changed"
        )
        for line in d.summary():
            click.echo("  " + line)
    sys.exit(0 if d.equal else 1)


@click.command("edit")
@_map_arg
@click.option(
    "--script",
    "script",
    required=True,
    type=InputFile(),
    help="A YAML or JSON file of edits (see docs/edit.md).",
)
@_writes
def edit_cmd(map_file: str, script: str, **opts: Any) -> None:
    """Apply a batch of edits from a YAML or JSON file as one atomic change.

    If any edit is refused, nothing is written.

    \b
    Example:
      mapkit edit office.map --script edits.yaml --backup
    """
    edits = editing.load_script(script)
    base_dir = os.path.dirname(os.path.abspath(script))
    err(f"{plural(len(edits), 'edit')} from {script}")
    _apply(map_file, opts, lambda m: editing.apply_script(m, edits, base_dir=base_dir))
