"""One rule for errors, for every command (``mapkit --help`` and docs/cli.md state it).

Parametrised over the command list read from the CLI itself, so a new command is covered as soon
as it is registered: a missing or unreadable input file, a write that cannot happen, a read-only
map, Ctrl-C, a closed pipe and ``-q`` all give the same answer everywhere.
"""

from __future__ import annotations

import os
import re
import shutil
import signal
import stat
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import click
import pytest
from click.testing import CliRunner

import mapkit
from mapkit.cli.main import EXIT_RULE, cli
from mapkit.cli.options import InputFile
from mapkit.samples import sample_path
from tests.cli.test_help import all_commands

ROOT = Path(__file__).resolve().parent.parent.parent
OFFICE = Path(sample_path("office"))
SERVERS = {("serve",), ("receive",), ("ros", "serve"), ("ros", "receive"), ("ros", "map-server")}


def command_of(path: list[str]) -> click.Command:
    cmd: click.Command = cli
    for name in path:
        assert isinstance(cmd, click.Group)
        sub = cmd.get_command(click.Context(cmd), name)
        assert sub is not None
        cmd = sub
    return cmd


def input_params(cmd: click.Command) -> list[click.Parameter]:
    return [p for p in cmd.params if isinstance(p.type, InputFile)]


def commands_reading_files() -> list[list[str]]:
    return [path for path in all_commands() if input_params(command_of(path))]


def placeholder(p: click.Parameter, tmp_path: Path) -> str:
    """A harmless value for a parameter that is not the file under test."""
    if isinstance(p.type, click.Choice):
        return str(p.type.choices[0])
    if isinstance(
        p.type,
        (click.types.FloatParamType, click.types.IntParamType, click.FloatRange, click.IntRange),
    ):
        return "1"
    if p.name in ("address",):
        return "127.0.0.1:9"
    return str(tmp_path / f"{p.name}.out")


def invocation(path: list[str], bad: str, tmp_path: Path) -> list[str]:
    """``mapkit PATH ...`` with every file it reads set to ``bad`` and placeholders elsewhere."""
    cmd = command_of(path)
    args: list[str] = []
    first = input_params(cmd)[0]
    for p in cmd.params:
        if isinstance(p, click.Argument):
            if isinstance(p.type, InputFile):
                args.append(bad)
            elif p.required:
                args.extend([placeholder(p, tmp_path)] * (p.nargs if p.nargs > 0 else 1))
        elif isinstance(p, click.Option) and (p.required or p is first):
            value = bad if isinstance(p.type, InputFile) else placeholder(p, tmp_path)
            args.extend([p.opts[-1], *([value] * max(p.nargs, 1))])
    return [*path, *args]


def lines(result: click.testing.Result) -> list[str]:
    return (result.stdout + result.stderr).strip().splitlines()


# -- the rule is written down ------------------------------------------------------------------


def test_the_rule_is_in_help_and_in_docs() -> None:
    result = CliRunner().invoke(cli, ["--help"])
    for line in EXIT_RULE.splitlines()[1:]:
        assert line.strip() in result.output
        assert line.strip() in (ROOT / "docs" / "cli.md").read_text(encoding="utf-8")


def test_every_file_a_command_reads_follows_the_rule() -> None:
    """No command checks its input files with click's own ``exists=True`` (three-line usage)."""
    offenders = [
        f"mapkit {' '.join(path)} {p.name}"
        for path in all_commands()
        for p in command_of(path).params
        if isinstance(p.type, click.Path) and p.type.exists and not isinstance(p.type, InputFile)
    ]
    assert not offenders, "use mapkit.cli.options.InputFile for: " + ", ".join(offenders)
    # the commands the issue named are among those checked
    reading = {" ".join(p) for p in commands_reading_files()}
    assert {"info", "validate", "diff", "add-goal", "render", "merge", "build"} <= reading


# -- a missing or unreadable input -------------------------------------------------------------


@pytest.mark.parametrize("path", commands_reading_files(), ids=" ".join)
def test_a_missing_input_is_one_line_and_exit_2(
    runner: CliRunner, tmp_path: Path, path: list[str]
) -> None:
    missing = str(tmp_path / "nothere.map")
    result = runner.invoke(cli, invocation(path, missing, tmp_path))
    assert result.exit_code == 2, result.output
    assert lines(result) == [f"Error: cannot read {missing}: no such file"]


@pytest.mark.parametrize("path", commands_reading_files(), ids=" ".join)
def test_a_folder_given_as_input_is_one_line_and_exit_2(
    runner: CliRunner, tmp_path: Path, path: list[str]
) -> None:
    folder = tmp_path / "afolder"
    folder.mkdir()
    result = runner.invoke(cli, invocation(path, str(folder), tmp_path))
    assert result.exit_code == 2, result.output
    assert lines(result) == [f"Error: cannot read {folder}: it is a folder"]


# -- writing -----------------------------------------------------------------------------------


@pytest.fixture
def office(tmp_path: Path) -> Path:
    dst = tmp_path / "office.map"
    shutil.copyfile(OFFICE, dst)
    return dst


def writing_commands(office: Path, out: Path) -> dict[str, list[str]]:
    """Commands that write, each writing ``out``."""
    o = str(office)
    return {
        "add-goal -o": ["add-goal", o, "G", "1000", "1000", "-o", str(out)],
        "forbid -o": ["forbid", o, "--area", "0", "0", "500", "500", "-o", str(out)],
        "merge -o": ["merge", o, o, "--on-clash", "base", "-o", str(out)],
        "convert": ["convert", o, str(out)],
        "rasterize": ["rasterize", o, "-o", str(out.with_suffix(".yaml"))],
        "render": ["render", o, "-o", str(out.with_suffix(".png"))],
        "export-mesh": ["export-mesh", o, "-o", str(out.with_suffix(".stl")), "--no-world"],
        "build": ["build", str(sample_path("office-loop.2d")), "-o", str(out)],
        "simulate": ["simulate", o, "-o", str(out.with_suffix(".2d")), "--no-truth"],
        "info --thumbnail": ["info", o, "--thumbnail", str(out.with_suffix(".png"))],
    }


WRITERS = list(writing_commands(Path("x"), Path("y")))


@pytest.fixture
def no_building(monkeypatch: pytest.MonkeyPatch) -> None:
    """``build`` must find out it cannot write before it builds."""

    def refuse(*_a: object, **_k: object) -> None:
        raise AssertionError("built a map that could not be written")

    monkeypatch.setattr("mapkit.build.build_map", refuse)


@pytest.mark.parametrize("name", WRITERS)
def test_a_missing_output_folder_is_said_so(
    runner: CliRunner, office: Path, tmp_path: Path, name: str, no_building: None
) -> None:
    folder = tmp_path / "no" / "such"
    args = writing_commands(office, folder / "out.map")[name]
    result = runner.invoke(cli, args)
    assert result.exit_code == 1, result.output
    [line] = lines(result)[-1:]
    assert re.fullmatch(
        rf"Error: cannot write {re.escape(str(folder))}/out\.\w+: "
        rf"folder {re.escape(str(folder))} does not exist",
        line,
    ), line
    assert "tmp" not in line.split(":", 2)[1] or str(tmp_path) in line  # never a temp file name


@pytest.mark.parametrize("name", WRITERS)
def test_a_read_only_folder_is_said_so(
    runner: CliRunner, office: Path, name: str, no_building: None
) -> None:
    if os.access("/sys", os.W_OK) and not os.path.ismount("/sys"):
        pytest.skip("no read-only folder here (/sys is not sysfs)")
    args = writing_commands(office, Path("/sys/out.map"))[name]
    result = runner.invoke(cli, args)
    assert result.exit_code == 1, result.output
    assert re.fullmatch(
        r"Error: cannot write /sys/out\.\w+: folder /sys is read-only", lines(result)[-1]
    ), lines(result)


def test_a_read_only_map_is_kept_unless_force(runner: CliRunner, office: Path) -> None:
    before = office.read_bytes()
    office.chmod(0o444)
    result = runner.invoke(cli, ["add-goal", str(office), "G", "1000", "1000"])
    assert result.exit_code == 1
    assert lines(result) == [
        f"Error: cannot write {office}: the file is read-only; add --force to replace it"
    ]
    assert office.read_bytes() == before
    result = runner.invoke(cli, ["convert", str(OFFICE), str(office), "--force"])
    assert result.exit_code == 0, result.output
    result = runner.invoke(cli, ["add-goal", str(office), "G", "1000", "1000", "--force"])
    assert result.exit_code == 0, result.output
    assert mapkit.load(office).find("G") and stat.S_IMODE(office.stat().st_mode) == 0o444
    # --force is for that one command only
    result = runner.invoke(cli, ["add-goal", str(office), "H", "1000", "1200"])
    assert result.exit_code == 1 and "read-only" in result.output


@pytest.mark.parametrize("mode", [0o600, 0o640, 0o664, 0o755])
def test_a_rewrite_keeps_permissions(runner: CliRunner, office: Path, mode: int) -> None:
    office.chmod(mode)
    assert runner.invoke(cli, ["add-goal", str(office), "G", "1000", "1000"]).exit_code == 0
    assert stat.S_IMODE(office.stat().st_mode) == mode


def test_a_rewrite_through_a_symlink_keeps_the_link(
    runner: CliRunner, office: Path, tmp_path: Path
) -> None:
    link = tmp_path / "current.map"
    link.symlink_to(office)
    assert runner.invoke(cli, ["add-goal", str(link), "G", "1000", "1000"]).exit_code == 0
    assert link.is_symlink() and mapkit.load(office).find("G")


# -- a truncated map ---------------------------------------------------------------------------


@pytest.fixture
def cut(tmp_path: Path) -> Path:
    """office.map cut short in its DATA rows (a copy that stopped)."""
    data = OFFICE.read_bytes()
    path = tmp_path / "cut.map"
    path.write_bytes(data[: data.index(b"\nDATA\n") + 2000])
    return path


def test_info_warns_about_a_truncated_map(runner: CliRunner, cut: Path) -> None:
    result = runner.invoke(cli, ["info", str(cut)])
    assert result.exit_code == 0
    assert re.search(
        r"warning: .*cut\.map: NumPoints: 7116 but the file has \d+ DATA rows: "
        r"\d+ missing",
        result.stderr,
    )
    data = mapkit.load(cut)
    assert runner.invoke(cli, ["info", str(OFFICE)]).stderr == ""
    assert len(data.points) < 7116


@pytest.mark.parametrize(
    "edit",
    [
        ["add-goal", "G", "1000", "1000"],
        ["forbid", "--line", "0", "0", "1000", "0"],
        ["remove", "Kitchen"],
        ["erase", "--box", "0", "0", "100", "100"],
        ["transform", "--translate", "10", "0"],
    ],
)
def test_edits_refuse_a_truncated_map_unless_force(
    runner: CliRunner, cut: Path, edit: list[str]
) -> None:
    before = cut.read_bytes()
    result = runner.invoke(cli, [edit[0], str(cut), *edit[1:]])
    assert result.exit_code == 1 and "cut short" in result.stderr and "--force" in result.stderr
    assert cut.read_bytes() == before
    result = runner.invoke(cli, [edit[0], str(cut), *edit[1:], "--force"])
    assert result.exit_code == 0, result.output
    assert "warning" in result.stderr and cut.read_bytes() != before


# -- Ctrl-C, a closed pipe, -q -----------------------------------------------------------------


def _mapkit(*args: str, **kw: object) -> subprocess.Popen[bytes]:
    return subprocess.Popen(
        [sys.executable, "-m", "mapkit", *args],
        cwd=kw.pop("cwd", None),
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        **kw,
    )  # type: ignore[call-overload]


def _wait_for(proc: subprocess.Popen[bytes], marker: bytes, timeout: float = 60.0) -> bytes:
    """Read the process's stderr until ``marker`` shows (or it ends); what was read."""
    import select

    assert proc.stderr is not None
    fd, seen, end = proc.stderr.fileno(), b"", time.monotonic() + timeout
    while marker not in seen and time.monotonic() < end:
        ready, _, _ = select.select([fd], [], [], 0.5)
        if ready:
            chunk = os.read(fd, 4096)
            if not chunk:
                break
            seen += chunk
    return seen


def test_ctrl_c_exits_130_with_one_line(tmp_path: Path) -> None:
    proc = _mapkit("build", str(sample_path("building-labs.2d")), "-o", str(tmp_path / "b.map"))
    seen = _wait_for(proc, b"registering")  # started and working: scans are being matched
    assert proc.poll() is None, (seen, proc.communicate())
    proc.send_signal(signal.SIGINT)
    _out, err = proc.communicate(timeout=60)
    err = seen + err
    assert proc.returncode == 130, err.decode()
    assert err.decode().strip().splitlines()[-1] == "Error: interrupted"
    assert b"Traceback" not in err and not (tmp_path / "b.map").exists()


def test_ctrl_c_in_any_command_is_130(runner: CliRunner, monkeypatch: pytest.MonkeyPatch) -> None:
    def interrupted(*_a: object, **_k: object) -> None:
        raise KeyboardInterrupt

    monkeypatch.setattr("mapkit.cli.info.load", interrupted)
    result = runner.invoke(cli, ["info", str(OFFICE)])
    assert result.exit_code == 130 and lines(result) == ["Error: interrupted"]


@pytest.fixture
def many_objects(tmp_path: Path) -> Path:
    m = mapkit.loads(b"2D-Map\nDATA\n0 0\n")
    objs = tuple(mapkit.MapObject("Goal", i, i, 0, name=f"G{i}") for i in range(20000))
    path = tmp_path / "many.map"
    mapkit.save(m.replace(objects=objs), path)
    return path


@pytest.mark.parametrize(
    "args", [["objects", "{map}"], ["objects", "{map}", "--json"], ["codes", "--markdown"]]
)
def test_a_closed_pipe_ends_quietly(many_objects: Path, args: list[str]) -> None:
    proc = _mapkit(*[a.format(map=many_objects) for a in args])
    assert proc.stdout is not None and proc.stderr is not None
    proc.stdout.readline()
    proc.stdout.close()  # `| head -1`
    err = proc.stderr.read()
    proc.wait(timeout=60)
    assert err == b"" and proc.returncode in (0, 141)


@pytest.mark.parametrize(
    "args",
    [
        ["add-goal", "{map}", "G", "1000", "1000"],
        ["forbid", "{map}", "--area", "0", "0", "500", "500", "--angle", "10"],
        ["info", "{map}"],
        ["objects", "{map}"],
        ["validate", "{map}", "--no-navigation"],
        ["convert", "{map}", "{tmp}/c.map"],
        ["rasterize", "{map}", "-o", "{tmp}/r.yaml", "--keepout"],
        ["samples", "office.map", "-o", "{tmp}/s"],
    ],
)
def test_quiet_silences_reports(
    runner: CliRunner, office: Path, tmp_path: Path, args: list[str]
) -> None:
    (tmp_path / "loud").mkdir()
    loud_copy = tmp_path / "loud" / office.name
    shutil.copyfile(office, loud_copy)
    loud = runner.invoke(cli, [a.format(map=loud_copy, tmp=tmp_path / "loud") for a in args])
    assert loud.exit_code in (0, 1) and loud.stdout  # there is a report to silence
    argv = [a.format(map=office, tmp=tmp_path) for a in args]
    result = runner.invoke(cli, ["-q", *argv])
    assert result.exit_code in (0, 1) and result.stdout == "" and result.stderr == ""


def test_quiet_keeps_errors_and_json(runner: CliRunner, office: Path, tmp_path: Path) -> None:
    result = runner.invoke(cli, ["-q", "info", str(office), "--json"])
    assert result.exit_code == 0 and '"category": "2D-Map"' in result.stdout
    missing = tmp_path / "gone.map"
    result = runner.invoke(cli, ["-q", "info", str(missing)])
    assert result.exit_code == 2 and lines(result) == [
        f"Error: cannot read {missing}: no such file"
    ]
    office.chmod(0o444)
    result = runner.invoke(cli, ["-q", "add-goal", str(office), "G", "1", "1"])
    assert result.exit_code == 1 and "read-only" in result.stderr


# -- plurals -----------------------------------------------------------------------------------

ONE_PLURAL = re.compile(r"(?<![\d.])1 (?!s\b|ms\b|mm\b|px\b|m\b|m/s\b|bytes\b)[a-z][a-z ]*?s\b")


@pytest.fixture
def one_of_each(tmp_path: Path) -> Iterator[Path]:
    path = tmp_path / "one.map"
    path.write_bytes(
        b"2D-Map\nMinPos: 0 0\nMaxPos: 4000 3000\nNumPoints: 1\nLineMinPos: 0 0\n"
        b"LineMaxPos: 4000 0\nNumLines: 1\n"
        b'Cairn: RobotHome 500 500 0.000000 "" ICON "Home"\n'
        b'Cairn: Goal 1000 300 0.000000 "" ICON "Desk"\n'
        b'Cairn: ForbiddenArea 0 0 0.000000 "" ICON "" 2000 1000 3000 2000\n'
        b"LINES\n0 0 4000 0\nDATA\n4000 3000\n"
    )
    yield path


def test_one_thing_is_not_plural(runner: CliRunner, one_of_each: Path, tmp_path: Path) -> None:
    out = tmp_path / "r.yaml"
    runs = [
        ["info", str(one_of_each)],
        ["validate", str(one_of_each), "--no-navigation"],
        ["rasterize", str(one_of_each), "-o", str(out), "--keepout", "--speed-mask"],
        [
            "import-ros",
            str(out),
            "-o",
            str(tmp_path / "back.map"),
            "--keepout",
            str(tmp_path / "r_keepout.yaml"),
        ],
        ["add-goal", str(one_of_each), "Other", "3000", "300"],
    ]
    text = ""
    for argv in runs:
        result = runner.invoke(cli, argv)
        assert result.exit_code in (0, 1), result.output
        text += result.stdout + result.stderr
    assert "1 point" in text and "1 keepout zone" in text and "1 forbidden area" in text
    assert not ONE_PLURAL.findall(text), text


@pytest.mark.parametrize("command", ["serve", "receive"])
def test_ctrl_c_stops_a_server_normally(tmp_path: Path, command: str) -> None:
    folder = tmp_path / "maps"
    proc = (
        _mapkit(command, str(folder), "--insecure", "--listen", "127.0.0.1:0")
        if command == "serve"
        else _mapkit(command, "--insecure", "--listen", "127.0.0.1:0", "-o", str(folder))
    )
    time.sleep(2)
    assert proc.poll() is None, proc.communicate()
    proc.send_signal(signal.SIGINT)
    _out, err = proc.communicate(timeout=30)
    assert proc.returncode == 0 and b"Traceback" not in err, err.decode()


@pytest.mark.parametrize("path", all_commands(), ids=" ".join)
def test_bad_usage_is_exit_2_for_every_command(runner: CliRunner, path: list[str]) -> None:
    result = runner.invoke(cli, [*path, "--no-such-option"])
    # (editing commands take unknown options as arguments, for negative numbers: -1000)
    assert result.exit_code == 2 and result.stdout == "", result.output
    assert "No such option" in result.stderr or "--no-such-option" in result.stderr


@pytest.mark.parametrize(
    "args",
    [
        ["samples", "office.map", "-o", "/sys/mapkit-samples"],
        ["samples", "office.map", "-o", "/sys"],
        ["serve", "/sys/mapkit-maps", "--insecure", "--listen", "127.0.0.1:0"],
    ],
)
def test_a_folder_that_cannot_be_made_is_a_write_error(runner: CliRunner, args: list[str]) -> None:
    if os.access("/sys", os.W_OK) and not os.path.ismount("/sys"):
        pytest.skip("no read-only folder here (/sys is not sysfs)")
    result = runner.invoke(cli, args)
    assert result.exit_code == 1, result.output
    assert re.fullmatch(
        r"Error: cannot write /sys(/[\w.-]+)?: folder /sys is read-only", lines(result)[-1]
    ), lines(result)
