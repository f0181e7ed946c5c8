"""Options shared by the commands, so every command spells them the same way."""

from __future__ import annotations

import json
import sys
from collections.abc import Callable
from typing import Any, TypeVar

import click

F = TypeVar("F", bound=Callable[..., Any])

json_option = click.option("--json", "as_json", is_flag=True, help="Print one JSON document for machines.")
force_option = click.option("--force", is_flag=True, help="Overwrite an existing output file.")
backup_option = click.option("--backup", is_flag=True, help="Keep the previous file as FILE.bak.")


def output_option(help: str = "Output file.", required: bool = False) -> Callable[[F], F]:
    """``-o/--output PATH``."""
    return click.option("-o", "--output", type=click.Path(dir_okay=False), required=required, help=help)


def echo_json(data: Any) -> None:
    """Print a JSON document on stdout."""
    click.echo(json.dumps(data, indent=2, ensure_ascii=False, default=str))


def err(message: str) -> None:
    """Print a line on stderr."""
    click.echo(message, file=sys.stderr)
