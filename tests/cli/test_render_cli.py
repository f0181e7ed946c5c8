"""``mapkit render`` and ``mapkit info --thumbnail``."""

from __future__ import annotations

import json
import struct
from pathlib import Path

import pytest
from click.testing import CliRunner

import mapkit
from mapkit.cli.main import cli
from mapkit.model import MapData, MapObject, Scan


@pytest.fixture
def office(tmp_path: Path) -> Path:
    scan = Scan.from_arrays([[0, 0], [6000, 4000]], [[0, 0, 6000, 0], [0, 0, 0, 4000]])
    m = MapData(
        scans=(scan,),
        objects=(
            MapObject("GoalWithHeading", 3000, 2000, 90, name="Desk"),
            MapObject("ForbiddenArea", 0, 0, 0, from_to=(1000, 1000, 2000, 2000)),
        ),
    )
    path = tmp_path / "office.map"
    mapkit.save(m, path)
    return path


def png_size(path: Path) -> tuple[int, int]:
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    return struct.unpack(">II", data[16:24])


def test_render_png(runner: CliRunner, office: Path, tmp_path: Path) -> None:
    out = tmp_path / "office.png"
    res = runner.invoke(cli, ["render", str(office), "-o", str(out), "--width", "800"])
    assert res.exit_code == 0, res.output
    w, h = png_size(out)
    assert w == 800
    assert res.output.startswith(f"wrote {out} (PNG, 800x{h} px, ")


@pytest.mark.parametrize("suffix", [".svg", ".pdf"])
def test_render_vector_formats_json(
    runner: CliRunner, office: Path, tmp_path: Path, suffix: str
) -> None:
    out = tmp_path / ("office" + suffix)
    res = runner.invoke(
        cli,
        [
            "render",
            str(office),
            "-o",
            str(out),
            "--json",
            "--no-names",
            "--no-points",
            "--no-legend",
            "--title",
            "",
        ],
    )
    assert res.exit_code == 0, res.output
    data = json.loads(res.output)
    assert data["path"] == str(out) and data["format"] == suffix[1:] and data["width"] == 1600
    assert out.read_bytes()[:5] in (b"<?xml", b"%PDF-")


def test_render_refuses_to_overwrite(runner: CliRunner, office: Path, tmp_path: Path) -> None:
    out = tmp_path / "office.png"
    out.write_bytes(b"keep")
    res = runner.invoke(cli, ["render", str(office), "-o", str(out)])
    assert res.exit_code == 2 and "exists; add --force" in res.output
    assert out.read_bytes() == b"keep"
    assert runner.invoke(cli, ["render", str(office), "-o", str(out), "--force"]).exit_code == 0
    assert png_size(out)[0] == 1600


def test_render_needs_an_output(runner: CliRunner, office: Path) -> None:
    res = runner.invoke(cli, ["render", str(office)])
    assert res.exit_code == 2 and "give -o OUT.png|svg|pdf or --show" in res.output


def test_render_bad_suffix(runner: CliRunner, office: Path, tmp_path: Path) -> None:
    res = runner.invoke(cli, ["render", str(office), "-o", str(tmp_path / "x.gif")])
    assert res.exit_code == 1 and "pictures are .png, .svg or .pdf, not '.gif'" in res.output


def test_render_show_without_display(
    runner: CliRunner, office: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    res = runner.invoke(cli, ["render", str(office), "--show"])
    assert res.exit_code == 1
    assert "cannot open a window: no display (DISPLAY is not set)" in res.output


def test_render_reports_hidden_names(runner: CliRunner, tmp_path: Path) -> None:
    goals = tuple(MapObject("Goal", 10 * k, 0, name=f"Goal {k}") for k in range(30))
    src = tmp_path / "crowded.map"
    mapkit.save(MapData(objects=goals), src)
    res = runner.invoke(cli, ["render", str(src), "-o", str(tmp_path / "c.png"), "--width", "400"])
    assert res.exit_code == 0
    assert "names left out where they would overlap others (a larger --width" in res.stderr


def test_info_thumbnail(runner: CliRunner, office: Path, tmp_path: Path) -> None:
    out = tmp_path / "thumb.png"
    res = runner.invoke(cli, ["info", str(office), "--thumbnail", str(out)])
    assert res.exit_code == 0, res.output
    w, h = png_size(out)
    assert w == 320
    assert f"thumbnail: {out} (320x{h} px)" in res.output
    res = runner.invoke(cli, ["info", str(office), "--thumbnail", str(out), "--json"])
    assert json.loads(res.output)["thumbnail"] == {"path": str(out), "width": 320, "height": h}


def test_convert_to_png(runner: CliRunner, office: Path, tmp_path: Path) -> None:
    out = tmp_path / "o.png"
    res = runner.invoke(cli, ["convert", str(office), str(out)])
    assert res.exit_code == 0, res.output
    assert png_size(out)[0] == 1600 and res.output.startswith(f"wrote {out} (1600x")
