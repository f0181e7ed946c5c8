"""``mapkit info``, ``mapkit convert``, ``--version`` and error handling, through click's runner."""

from __future__ import annotations

import json
from pathlib import Path

from click.testing import CliRunner

import mapkit
from mapkit.cli.main import cli


def test_version(runner: CliRunner) -> None:
    result = runner.invoke(cli, ["--version"])
    assert result.exit_code == 0 and mapkit.__version__ in result.output


def test_info_json_on_real_sample(runner: CliRunner, real_sample: Path, shared_dir: Path) -> None:
    dump = json.loads(
        (shared_dir / "aria-dump" / (real_sample.stem + ".json")).read_bytes().decode()
    )
    result = runner.invoke(cli, ["info", str(real_sample), "--json"])
    assert result.exit_code == 0, result.output
    data = json.loads(result.output)
    assert data["md5"] == dump["md5_read"]
    assert data["scans"][0]["num_points"] == dump["num_points"]
    assert data["scans"][0]["num_lines"] == dump["num_lines"]
    assert sum(data["objects"].values()) == len(dump["objects"])
    assert data["written_category"] == dump["version_header"]


def test_info_text_on_bundled_sample(runner: CliRunner) -> None:
    result = runner.invoke(cli, ["info", "--sample", "office"])
    assert result.exit_code == 0, result.output
    assert "2D-Map" in result.output and "RobotHome" in result.output and "MD5" in result.output


def test_info_needs_exactly_one_input(runner: CliRunner) -> None:
    result = runner.invoke(cli, ["info"])
    assert result.exit_code == 2 and "give a MAP_FILE or --sample" in result.output


def test_info_unknown_sample(runner: CliRunner) -> None:
    result = runner.invoke(cli, ["info", "--sample", "nope"])
    assert result.exit_code == 1 and "no bundled sample 'nope'" in result.output


def test_info_bad_map_is_one_line(runner: CliRunner, tmp_path: Path) -> None:
    bad = tmp_path / "bad.map"
    bad.write_bytes(b"2D-Map\nMinPos: 1 2 3\nDATA\n")
    result = runner.invoke(cli, ["info", str(bad)])
    assert result.exit_code == 1
    assert (
        result.output.strip() == f"Error: {bad}:2: MinPos: expects exactly 2 integers, got 3 "
        "arguments: '1 2 3'"
    )


def test_convert_canonical_rewrite(
    runner: CliRunner, real_sample: Path, shared_dir: Path, tmp_path: Path
) -> None:
    out = tmp_path / "out.map"
    result = runner.invoke(cli, ["convert", str(real_sample), str(out)])
    assert result.exit_code == 0, result.output
    assert out.read_bytes() == (shared_dir / "aria-written" / real_sample.name).read_bytes()


def test_convert_refuses_to_overwrite_without_force(runner: CliRunner, tmp_path: Path) -> None:
    src = tmp_path / "a.map"
    src.write_bytes(b"2D-Map\nDATA\n1 1\n")
    dst = tmp_path / "b.map"
    dst.write_bytes(b"keep")
    result = runner.invoke(cli, ["convert", str(src), str(dst)])
    assert result.exit_code == 2 and dst.read_bytes() == b"keep"
    assert runner.invoke(cli, ["convert", str(src), str(dst), "--force"]).exit_code == 0
    assert dst.read_bytes().startswith(b"2D-Map\n")


def test_convert_unknown_suffix(runner: CliRunner, tmp_path: Path) -> None:
    src = tmp_path / "a.map"
    src.write_bytes(b"2D-Map\nDATA\n")
    result = runner.invoke(cli, ["convert", str(src), str(tmp_path / "a.xyz")])
    assert result.exit_code == 1 and "no format for suffix '.xyz'" in result.output


def test_python_dash_m(tmp_path: Path) -> None:
    import subprocess
    import sys

    out = subprocess.run(
        [sys.executable, "-m", "mapkit", "--version"], capture_output=True, text=True, check=True
    )
    assert mapkit.__version__ in out.stdout
