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


class RowsBar:
    """A progress bar on stderr whose length comes with the first ``update``.

    ``update(done, total)`` takes a running count; ``advance(rows, total)`` an increment.
    Nothing is drawn until the first call (nor when stderr is not a terminal: click's rule).
    """

    def __init__(self, label: str) -> None:
        self.label = label
        self._bar: Any = None
        self._done = 0

    def update(self, done: int, total: int) -> None:
        if self._bar is None:
            self._bar = click.progressbar(length=total, label=self.label, file=sys.stderr,
                                          show_eta=True)
            self._bar.__enter__()
        self._bar.update(done - self._done)
        self._done = done

    def advance(self, rows: int, total: int) -> None:
        self.update(self._done + rows, total)

    def __enter__(self) -> RowsBar:
        return self

    def __exit__(self, *exc: object) -> None:
        if self._bar is not None:
            self._bar.__exit__(*exc)
            self._bar = None
