"""``mapkit demo`` into a temp folder: every artefact checked for real."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np
import pytest
import yaml
from click.testing import CliRunner

import mapkit
from mapkit.cli.main import cli


@pytest.fixture(scope="module")
def demo_run(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict]:
    out = tmp_path_factory.mktemp("demo")
    result = CliRunner().invoke(cli, ["demo", str(out), "--json"])
    assert result.exit_code == 0, result.output
    return out, json.loads(result.stdout)


def test_every_artefact_listed_exists_with_its_checksum(demo_run: tuple[Path, dict]) -> None:
    out, data = demo_run
    names = {Path(a["path"]).name for a in data["artefacts"]}
    assert {
        "built.map",
        "office.map",
        "office.png",
        "office.yaml",
        "office.pgm",
        "walls.stl",
        "walls.sdf",
        "fetched.map",
    } <= names
    for a in data["artefacts"]:
        p = Path(a["path"])
        assert p.parent == out.resolve() or out.resolve() in p.parents
        assert hashlib.sha256(p.read_bytes()).hexdigest() == a["sha256"]
        assert p.stat().st_size == a["size"]


def test_map_parses_validates_and_has_the_edits(demo_run: tuple[Path, dict]) -> None:
    out, data = demo_run
    m = mapkit.load(out / "office.map")
    assert m.scan.num_points > 1000 and m.scan.num_lines > 5
    names = [o.name for o in m.objects]
    assert "Demo goal" in names and "Demo keep-out" in names
    assert any(o.type == "RobotHome" for o in m.objects)
    from mapkit.validate import validate

    assert validate(out / "office.map").errors == ()
    assert data["summary"]["validate"]["errors"] == 0


def test_pgm_matches_yaml(demo_run: tuple[Path, dict]) -> None:
    out, data = demo_run
    meta = yaml.safe_load((out / "office.yaml").read_text())
    assert meta["image"] == "office.pgm" and meta["negate"] == 0 and meta["mode"] == "trinary"
    raw = (out / "office.pgm").read_bytes()
    header = [
        t for line in raw[:200].split(b"\n")[:4] if not line.startswith(b"#") for t in line.split()
    ]  # P5, comments, width height, maxval
    assert header[0] == b"P5"
    width, height, maxval = int(header[1]), int(header[2]), int(header[3])
    assert (width, height, maxval) == (
        data["summary"]["ros"]["width"],
        data["summary"]["ros"]["height"],
        255,
    )
    pixels = np.frombuffer(raw[-width * height :], np.uint8)
    assert set(np.unique(pixels).tolist()) <= {0, 205, 254}
    assert (pixels == 0).sum() > 100 and (pixels == 254).sum() > 1000
    keepout = yaml.safe_load((out / "office_keepout.yaml").read_text())
    assert keepout["resolution"] == meta["resolution"] and keepout["origin"] == meta["origin"]


def test_mesh_is_watertight_and_world_references_it(demo_run: tuple[Path, dict]) -> None:
    import trimesh

    out, _data = demo_run
    mesh = trimesh.load(out / "walls.stl", force="mesh")
    assert mesh.is_watertight and mesh.volume > 0
    assert "walls.stl" in (out / "walls.sdf").read_text()


def test_fetched_file_is_byte_identical(demo_run: tuple[Path, dict]) -> None:
    out, data = demo_run
    assert (out / "fetched.map").read_bytes() == (out / "office.map").read_bytes()
    assert data["summary"]["transfer"]["verified"] is True
    assert data["summary"]["transfer"]["loaded"] is True


def test_png_is_a_picture(demo_run: tuple[Path, dict]) -> None:
    out, _data = demo_run
    assert (out / "office.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_text_output_names_every_step(tmp_path: Path) -> None:
    result = CliRunner().invoke(cli, ["demo", str(tmp_path / "d")])
    assert result.exit_code == 0, result.output
    for word in ("built", "validated", "ROS map", "SHA-256 verified", "office.map", "walls.stl"):
        assert word in result.output
