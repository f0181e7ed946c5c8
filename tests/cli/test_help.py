"""Every command has help with an example, and docs/cli.md (generated from it) is current."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import click
import pytest
from click.testing import CliRunner

from mapkit.cli.main import cli

ROOT = Path(__file__).resolve().parent.parent.parent


def all_commands() -> list[list[str]]:
    out: list[list[str]] = []

    def walk(group: click.Group, prefix: list[str]) -> None:
        ctx = click.Context(group)
        for name in group.list_commands(ctx):
            cmd = group.get_command(ctx, name)
            if isinstance(cmd, click.Group):
                walk(cmd, [*prefix, name])
            else:
                out.append([*prefix, name])

    walk(cli, [])
    return out


@pytest.mark.parametrize("path", all_commands(), ids=" ".join)
def test_help_has_an_example(path: list[str]) -> None:
    result = CliRunner().invoke(cli, [*path, "--help"])
    assert result.exit_code == 0, result.output
    assert "Example" in result.output or "example" in result.output
    assert f"mapkit {' '.join(path)}" in result.output


def test_top_level_help_lists_every_command() -> None:
    result = CliRunner().invoke(cli, ["--help"])
    assert result.exit_code == 0
    for path in all_commands():
        assert path[0] in result.output


def test_cli_docs_are_current() -> None:
    result = subprocess.run([sys.executable, str(ROOT / "scripts" / "make_cli_docs.py"), "--check"],
                            capture_output=True, text=True)
    assert result.returncode == 0, result.stdout


def test_errors_are_one_line_and_debug_shows_the_traceback(tmp_path: Path) -> None:
    bad = tmp_path / "bad.map"
    bad.write_bytes(b"not a map\n")
    result = CliRunner().invoke(cli, ["info", str(bad)])
    assert result.exit_code == 1 and len(result.output.strip().splitlines()) == 1
    debug = CliRunner().invoke(cli, ["--debug", "info", str(bad)])
    assert debug.exit_code == 1 and debug.exception is not None
