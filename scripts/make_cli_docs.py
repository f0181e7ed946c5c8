#!/usr/bin/env python3
"""Write docs/cli.md: every command's --help, generated from the code so it stays true.

python scripts/make_cli_docs.py           # rewrite docs/cli.md
python scripts/make_cli_docs.py --check   # exit 1 if docs/cli.md is stale
"""

from __future__ import annotations

import sys
from collections.abc import Iterator
from pathlib import Path

import click

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from mapkit.cli.main import cli  # noqa: E402

OUT = ROOT / "docs" / "cli.md"


def commands(group: click.Group, prefix: list[str]) -> Iterator[tuple[list[str], click.Command]]:
    yield prefix, group
    ctx = click.Context(group)
    for name in group.list_commands(ctx):  # a lazy group imports each command here
        cmd = group.get_command(ctx, name)
        assert cmd is not None, name
        if isinstance(cmd, click.Group):
            yield from commands(cmd, [*prefix, name])
        else:
            yield [*prefix, name], cmd


def render() -> str:
    parts = [
        "# Command reference\n",
        "Generated from the code by `scripts/make_cli_docs.py`; a test fails when it is stale.",
        'Shell completion: `eval "$(_MAPKIT_COMPLETE=bash_source mapkit)"` (bash; `zsh_source`,',
        "`fish_source` for the others). Every command takes `-h/--help`; errors are one line",
        "(`mapkit --debug COMMAND` shows the traceback), and exit statuses follow one rule,",
        "printed at the end of `mapkit --help` below.\n",
    ]
    for path, cmd in commands(cli, ["mapkit"]):
        ctx = click.Context(
            cmd, info_name=" ".join(path), terminal_width=100, max_content_width=100
        )
        parts.append(f"## `{' '.join(path)}`\n")
        parts.append("```text\n" + cmd.get_help(ctx) + "\n```\n")
    return "\n".join(parts)


def main() -> int:
    text = render()
    if "--check" in sys.argv:
        if not OUT.exists() or OUT.read_text(encoding="utf-8") != text:
            print("docs/cli.md is stale: run scripts/make_cli_docs.py")
            return 1
        return 0
    OUT.write_text(text, encoding="utf-8")
    print(f"wrote {OUT.relative_to(ROOT)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
