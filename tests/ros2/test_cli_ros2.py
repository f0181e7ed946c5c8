"""``mapkit ros2`` on bad input: one clear line naming the file, nothing published."""

from __future__ import annotations

from pathlib import Path

from click.testing import CliRunner

from mapkit.cli.main import cli


def test_missing_map_is_one_clear_error(runner: CliRunner, tmp_path: Path) -> None:
    res = runner.invoke(cli, ["ros2", "map-server", str(tmp_path / "nope.map")])
    assert res.exit_code != 0
    assert "nope.map: no such map file" in res.output
    assert "Traceback" not in res.output


def test_broken_map_names_the_file_and_line(runner: CliRunner, tmp_path: Path) -> None:
    bad = tmp_path / "bad.map"
    bad.write_text("2D-Map\nLineMinPos: 0 zero\nDATA\n", encoding="latin-1")
    res = runner.invoke(cli, ["ros2", "map-server", str(bad)])
    assert res.exit_code != 0
    assert "bad.map" in res.output and ":2" in res.output, res.output


def test_bad_topic_and_domain_are_refused(runner: CliRunner, tmp_path: Path) -> None:
    res = runner.invoke(cli, ["ros2", "map-server", str(tmp_path / "x.map"), "--topic", "1map"])
    assert res.exit_code != 0 and "invalid ROS 2 topic name" in res.output
    res = runner.invoke(cli, ["ros2", "map-server", str(tmp_path / "x.map"), "--domain", "300"])
    assert res.exit_code == 2 and "300" in res.output


def test_help_names_the_commands(runner: CliRunner) -> None:
    res = runner.invoke(cli, ["ros2", "--help"])
    assert res.exit_code == 0
    assert "map-server" in res.output and "aria-bridge" in res.output
