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
    result = subprocess.run(
        [sys.executable, str(ROOT / "scripts" / "make_cli_docs.py"), "--check"],
        capture_output=True,
        text=True,
    )
    assert result.returncode == 0, result.stdout


def test_errors_are_one_line_and_debug_shows_the_traceback(tmp_path: Path) -> None:
    bad = tmp_path / "bad.map"
    bad.write_bytes(b"not a map\n")
    result = CliRunner().invoke(cli, ["info", str(bad)])
    assert result.exit_code == 1 and len(result.output.strip().splitlines()) == 1
    debug = CliRunner().invoke(cli, ["--debug", "info", str(bad)])
    assert debug.exit_code == 1 and debug.exception is not None


# -- the lazy command table --------------------------------------------------------------------


def test_the_table_help_is_each_commands_own() -> None:
    """``mapkit --help`` shows the table's line without importing the command: it must match."""
    from mapkit.cli.main import COMMANDS

    ctx = click.Context(cli)
    for name, (_where, short) in COMMANDS.items():
        cmd = cli.get_command(ctx, name)
        assert cmd is not None, name
        assert cmd.get_short_help_str(10**6) == short, f"{name}: update COMMANDS in cli/main.py"


def test_every_command_defined_is_in_the_table() -> None:
    """A command written in a mapkit/cli module but missing from the table would be unreachable."""
    import importlib
    import pkgutil

    import mapkit.cli

    reachable: set[int] = set()

    def walk(group: click.Group) -> None:
        ctx = click.Context(group)
        for name in group.list_commands(ctx):
            cmd = group.get_command(ctx, name)
            assert cmd is not None
            reachable.add(id(cmd))
            if isinstance(cmd, click.Group):
                walk(cmd)

    walk(cli)
    missing = []
    for info in pkgutil.iter_modules(mapkit.cli.__path__):
        module = importlib.import_module(f"mapkit.cli.{info.name}")
        for attr, value in vars(module).items():
            if isinstance(value, click.Command) and value is not cli and id(value) not in reachable:
                missing.append(f"mapkit.cli.{info.name}:{attr}")
    assert not missing, f"not registered in COMMANDS (mapkit/cli/main.py): {missing}"


def _modules_after(code: str) -> set[str]:
    probe = f"import sys\n{code}\nprint('\\n'.join(sorted(sys.modules)))"
    result = subprocess.run(
        [sys.executable, "-c", probe], capture_output=True, text=True, cwd=ROOT, timeout=120
    )
    assert result.returncode == 0, result.stderr
    return set(result.stdout.split())


HEAVY = {"numpy", "scipy", "matplotlib", "shapely", "trimesh", "yaml", "PIL", "rospy"}


def test_help_imports_no_command_and_no_numpy() -> None:
    mods = _modules_after(
        "from mapkit.cli.main import cli\n"
        "try:\n    cli(['--help'], prog_name='mapkit')\n"
        "except SystemExit:\n    pass"
    )
    assert not {m for m in mods if m.startswith("mapkit.cli.")} - {"mapkit.cli.main"}
    assert not HEAVY & mods


def test_info_imports_only_what_it_needs() -> None:
    mods = _modules_after(
        "from mapkit.cli.main import cli\n"
        "try:\n    cli(['info', 'mapkit/sample_maps/office.map'], "
        "prog_name='mapkit')\nexcept SystemExit:\n    pass"
    )
    assert "numpy" in mods and "mapkit.cli.info" in mods
    assert not (HEAVY - {"numpy"}) & mods
    assert not {"mapkit.edit", "mapkit.validate", "mapkit.raster", "mapkit.cli.edit"} & mods


def test_import_mapkit_is_light_and_whole() -> None:
    mods = _modules_after("import mapkit")
    assert not HEAVY & mods
    import mapkit

    assert all(hasattr(mapkit, name) for name in mapkit.__all__)
    star: dict[str, object] = {}
    exec("from mapkit import *", star)
    assert set(mapkit.__all__) <= set(star)
    for name in ("edit", "raster", "build", "validate", "formats", "model"):
        assert getattr(mapkit, name).__name__ == f"mapkit.{name}"
    assert callable(mapkit.validate) and callable(mapkit.build_map)
