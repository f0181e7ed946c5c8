"""``mapkit export-mesh``."""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest
import trimesh
from click.testing import CliRunner

import mapkit
from mapkit.cli.main import cli
from mapkit.model import MapData, MapObject, Scan


@pytest.fixture
def office(tmp_path: Path) -> Path:
    m = MapData(
        scans=(Scan.from_arrays(lines=[[0, 0, 6000, 0], [6000, 0, 6000, 4000]]),),
        objects=(MapObject("RobotHome", 1000, 1000, 0, name="Home"),),
    )
    path = tmp_path / "office.map"
    mapkit.save(m, path)
    return path


def test_mesh_and_world(runner: CliRunner, office: Path, tmp_path: Path) -> None:
    out = tmp_path / "walls.stl"
    res = runner.invoke(cli, ["export-mesh", str(office), "-o", str(out), "--height", "2.5"])
    assert res.exit_code == 0, res.output
    mesh = trimesh.load(out)
    assert mesh.is_watertight and mesh.bounds[1][2] == pytest.approx(2.5)
    lines = res.output.splitlines()
    assert lines[0].startswith(
        f"wrote {out} (STL, walls from lines: {len(mesh.faces)} triangles, watertight"
    )
    assert lines[1] == (
        f"wrote {tmp_path / 'walls.sdf'} (Gazebo SDF world; robot home RobotHome "
        f"'Home' at 1.000, 1.000 m, yaw 0.000 rad)"
    )
    root = ET.parse(tmp_path / "walls.sdf").getroot()
    assert {u.text for u in root.iter("uri")} == {"walls.stl"}


def test_world_path_and_json(runner: CliRunner, office: Path, tmp_path: Path) -> None:
    out, world = tmp_path / "walls.glb", tmp_path / "office.world"
    res = runner.invoke(
        cli,
        [
            "export-mesh",
            str(office),
            "-o",
            str(out),
            "--world",
            str(world),
            "--thickness",
            "0.2",
            "--json",
        ],
    )
    assert res.exit_code == 0, res.output
    data = json.loads(res.output)
    assert data["world"] == str(world) and data["watertight"] and data["source"] == "lines"
    assert data["home"] == {"type": "RobotHome", "name": "Home", "x": 1.0, "y": 1.0, "yaw": 0.0}
    assert data["bounds"][0][0] == pytest.approx(-0.1, abs=1e-3)
    assert world.exists()


def test_no_world(runner: CliRunner, office: Path, tmp_path: Path) -> None:
    out = str(tmp_path / "w.obj")
    res = runner.invoke(cli, ["export-mesh", str(office), "-o", out, "--no-world"])
    assert res.exit_code == 0, res.output
    assert sorted(p.name for p in tmp_path.iterdir()) == ["office.map", "w.obj"]
    res = runner.invoke(
        cli, ["export-mesh", str(office), "-o", out, "--no-world", "--world", "x.sdf", "--force"]
    )
    assert res.exit_code == 2 and "--world and --no-world exclude each other" in res.output


def test_refuses_to_overwrite_the_world(runner: CliRunner, office: Path, tmp_path: Path) -> None:
    (tmp_path / "walls.sdf").write_text("mine")
    res = runner.invoke(cli, ["export-mesh", str(office), "-o", str(tmp_path / "walls.stl")])
    assert res.exit_code == 2 and "walls.sdf exists; add --force" in res.output
    assert not (tmp_path / "walls.stl").exists()


def test_points_only_map(runner: CliRunner, tmp_path: Path) -> None:
    src = tmp_path / "scan.map"
    mapkit.save(MapData(scans=(Scan.from_arrays([[x, 0] for x in range(0, 3000, 20)]),)), src)
    res = runner.invoke(
        cli,
        [
            "export-mesh",
            str(src),
            "-o",
            str(tmp_path / "w.stl"),
            "--no-world",
            "--resolution",
            "0.1",
        ],
    )
    assert res.exit_code == 0, res.output
    assert "walls from points" in res.output
    res = runner.invoke(
        cli, ["export-mesh", str(src), "-o", str(tmp_path / "w.stl"), "--force", "--from", "lines"]
    )
    assert res.exit_code == 1
    assert "has no LINES to make walls from (150 points, 0 lines)" in res.output


def test_bad_height(runner: CliRunner, office: Path, tmp_path: Path) -> None:
    out = str(tmp_path / "w.stl")
    res = runner.invoke(cli, ["export-mesh", str(office), "-o", out, "--height", "0"])
    assert res.exit_code == 2 and "--height" in res.output


def test_convert_to_stl(runner: CliRunner, office: Path, tmp_path: Path) -> None:
    res = runner.invoke(cli, ["convert", str(office), str(tmp_path / "w.stl")])
    assert res.exit_code == 0, res.output
    assert res.output.startswith(f"wrote {tmp_path / 'w.stl'} (STL, ")
    assert trimesh.load(tmp_path / "w.stl").is_watertight
