"""Options shared by the commands, so every command spells them the same way."""

from __future__ import annotations

import errno
import json
import os
import sys
from collections.abc import Callable
from typing import Any, TypeVar

import click

from mapkit._text import plural

__all__ = [
    "InputFile",
    "backup_option",
    "check_outputs",
    "echo_json",
    "err",
    "force_option",
    "json_option",
    "output_option",
    "plural",
]

F = TypeVar("F", bound=Callable[..., Any])


class InputFile(click.Path):
    """A file a command reads. Missing or unreadable: one line and exit 2, the same for every
    command (``Error: cannot read office.map: no such file``), not click's usage text.

    ``check=False`` leaves the check to the command (``validate --json`` reports it as JSON).
    """

    def __init__(self, *, check: bool = True) -> None:
        super().__init__(exists=False, dir_okay=False)  # shown as FILE; checked below
        self.check = check

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> Any:
        path = os.fsdecode(value) if isinstance(value, (bytes, os.PathLike)) else value
        if not isinstance(path, str):
            return super().convert(value, param, ctx)
        problem = None
        if not os.path.exists(path):
            problem = errno.ENOENT
        elif os.path.isdir(path):
            problem = errno.EISDIR
        elif not os.access(path, os.R_OK):
            problem = errno.EACCES
        if problem is None:
            return super().convert(value, param, ctx)
        if not self.check:
            return path  # the command reports it (validate --json)
        from mapkit.cli.main import CommandError, error_message

        raise CommandError(*error_message(OSError(problem, os.strerror(problem), path)))


def check_outputs(paths: list[str], force: bool, *, same_as: str | None = None) -> None:
    """Before the work: refuse outputs that exist (unless ``force``) and say now if one cannot be
    written (missing or read-only folder, read-only file) rather than after minutes of work.
    ``same_as``: the input file, which an output may replace without ``--force``."""
    from mapkit._atomic import check_writable

    existing = [
        p
        for p in paths
        if os.path.exists(p) and not (same_as and os.path.abspath(p) == os.path.abspath(same_as))
    ]
    if existing and not force:
        verb = "exists" if len(existing) == 1 else "exist"
        raise click.UsageError(f"{', '.join(existing)} {verb}; add --force to overwrite it")
    for p in paths:
        check_writable(p)


def _allow_read_only(ctx: click.Context, _param: click.Parameter, force: bool) -> bool:
    """``--force`` also lets this one command replace a read-only file (mapkit._atomic)."""
    if force:
        from mapkit._atomic import replace_read_only

        token = replace_read_only.set(True)
        ctx.call_on_close(lambda: replace_read_only.reset(token))
    return force


json_option = click.option(
    "--json", "as_json", is_flag=True, help="Print one JSON document for machines."
)
force_option = click.option(
    "--force",
    is_flag=True,
    callback=_allow_read_only,
    help="Overwrite an existing output file (a read-only one too).",
)
backup_option = click.option("--backup", is_flag=True, help="Keep the previous file as FILE.bak.")


def output_option(help: str = "Output file.", required: bool = False) -> Callable[[F], F]:
    """``-o/--output PATH``."""
    return click.option(
        "-o", "--output", type=click.Path(dir_okay=False), required=required, help=help
    )


def echo_json(data: Any) -> None:
    """Print a JSON document on stdout (also under ``mapkit -q``: it was asked for)."""
    ctx = click.get_current_context(silent=True)
    root = ctx.find_root().obj if ctx else None
    out = root.get("stdout") if isinstance(root, dict) else None
    click.echo(json.dumps(data, indent=2, ensure_ascii=False, default=str), file=out)


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
            self._bar = click.progressbar(
                length=total, label=self.label, file=sys.stderr, show_eta=True
            )
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
