"""``mapkit rasterize``, ``mapkit import-ros`` and ``mapkit convert`` to and from ROS maps."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from click.testing import CliRunner

import mapkit
from mapkit.cli.main import cli
from mapkit.raster import rasterize
from mapkit.raster.ros import read_ros_map
from mapkit.samples import sample_path

from ..raster.rosloader import cells


def test_rasterize_writes_map_and_masks(runner: CliRunner, tmp_path: Path) -> None:
    out = tmp_path / "office.yaml"
    result = runner.invoke(
        cli,
        [
            "rasterize",
            str(sample_path("office")),
            "-o",
            str(out),
            "--keepout",
            "--speed-mask",
            "--resolution",
            "0.1",
        ],
    )
    assert result.exit_code == 0, result.output
    names = sorted(p.name for p in tmp_path.iterdir())
    assert names == [
        "office.pgm",
        "office.yaml",
        "office_filters.yaml",
        "office_keepout.pgm",
        "office_keepout.yaml",
        "office_speed.pgm",
        "office_speed.yaml",
    ]
    assert "wrote " + str(out) in result.output and ": 2 keepout zones\n" in result.output
    data, doc = cells(out)
    m = mapkit.load(sample_path("office"))
    assert np.array_equal(data, rasterize(m, 0.1).data) and doc["resolution"] == 0.1
    # Refuses to overwrite without --force, and names the files.
    again = runner.invoke(cli, ["rasterize", str(sample_path("office")), "-o", str(out)])
    assert again.exit_code == 2 and "office.pgm, " in again.output and "--force" in again.output
    forced = runner.invoke(
        cli,
        [
            "rasterize",
            str(sample_path("office")),
            "-o",
            str(out),
            "--force",
            "--png",
            "--mode",
            "raw",
            "--free",
            "all",
            "--json",
        ],
    )
    assert forced.exit_code == 0, forced.output
    info = json.loads(forced.stdout)
    assert info["image"].endswith("office.png") and info["mode"] == "raw"
    assert info["grid"]["unknown"] == 0
    assert read_ros_map(out).counts()["unknown"] == 0


def test_rasterize_options(runner: CliRunner, tmp_path: Path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)
    result = runner.invoke(
        cli,
        [
            "rasterize",
            str(sample_path("office")),
            "--mode",
            "scale",
            "--inflate",
            "200",
            "--forbidden-as-walls",
            "--margin",
            "1",
        ],
    )
    assert result.exit_code == 0, result.output
    assert (tmp_path / "office.yaml").exists() and (tmp_path / "office.png").exists()
    bad = runner.invoke(
        cli, ["rasterize", str(sample_path("office")), "-o", "x.yaml", "--resolution", "-1"]
    )
    assert bad.exit_code == 1 and "resolution must be a positive number" in bad.output
    bad = runner.invoke(cli, ["rasterize", str(sample_path("office")), "--mode", "binary"])
    assert bad.exit_code == 2


def test_import_ros_round_trip(runner: CliRunner, tmp_path: Path, real_sample: Path) -> None:
    y = tmp_path / "r.yaml"
    assert (
        runner.invoke(cli, ["rasterize", str(real_sample), "-o", str(y), "--keepout"]).exit_code
        == 0
    )
    out = tmp_path / "back.map"
    result = runner.invoke(
        cli,
        [
            "import-ros",
            str(y),
            "-o",
            str(out),
            "--keepout",
            str(tmp_path / "r_keepout.yaml"),
            "--json",
        ],
    )
    assert result.exit_code == 0, result.output
    info = json.loads(result.output)
    back = mapkit.load(out)
    assert info["points"] == back.scan.num_points and info["md5"] == back.md5
    g = read_ros_map(y)
    assert np.array_equal(rasterize(back, like=g, free="none").data == 100, g.data == 100)
    m = mapkit.load(real_sample)
    if any(o.type == "ForbiddenArea" for o in m.objects):
        assert info["forbidden_areas"] >= 1


def test_import_ros_errors_and_text(runner: CliRunner, tmp_path: Path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)
    (tmp_path / "bad.yaml").write_text(
        "image: x.pgm\nresolution: 0.05\norigin: [0, 0]\n"
        "negate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n"
    )
    result = runner.invoke(cli, ["import-ros", "bad.yaml"])
    assert result.exit_code == 1
    assert result.output.strip() == (
        "Error: bad.yaml:3: origin needs at least 3 numbers (x, y, yaw), got 2"
    )
    assert runner.invoke(cli, ["rasterize", str(sample_path("office"))]).exit_code == 0
    result = runner.invoke(cli, ["import-ros", "office.yaml", "--no-lines"])
    assert result.exit_code == 0 and "0 lines" in result.output
    assert (tmp_path / "office.map").exists()
    result = runner.invoke(cli, ["import-ros", "office.yaml"])
    assert result.exit_code == 2 and "office.map exists" in result.output


def test_convert_by_suffix(runner: CliRunner, tmp_path: Path) -> None:
    src = str(sample_path("office"))
    r = runner.invoke(cli, ["convert", src, str(tmp_path / "o.yaml")])
    assert r.exit_code == 0 and (tmp_path / "o.pgm").exists(), r.output
    r = runner.invoke(cli, ["convert", src, str(tmp_path / "p.pgm")])
    assert r.exit_code == 0 and (tmp_path / "p.yaml").exists(), r.output
    assert read_ros_map(tmp_path / "p.yaml") == read_ros_map(tmp_path / "o.yaml")
    r = runner.invoke(cli, ["convert", str(tmp_path / "o.yaml"), str(tmp_path / "o.map")])
    assert r.exit_code == 0, r.output
    assert mapkit.load(tmp_path / "o.map").scan.num_points > 0


def test_help_has_examples(runner: CliRunner) -> None:
    for cmd in ("rasterize", "import-ros"):
        r = runner.invoke(cli, [cmd, "--help"])
        assert r.exit_code == 0 and "Example:" in r.output
