"""Pictures of maps: files of the requested size in each format, objects where ARIA puts them."""

from __future__ import annotations

import math
import struct
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import given, strategies as st

import mapkit
from mapkit.errors import UnsupportedFormatError
from mapkit.formats.registry import convert_file
from mapkit.model import MapData, MapObject, Scan
from mapkit.render import RenderError, make_figure, object_kind, render, type_params


def png_size(data: bytes) -> tuple[int, int]:
    assert data[:8] == b"\x89PNG\r\n\x1a\n", "not a PNG"
    assert data[12:16] == b"IHDR"
    return struct.unpack(">II", data[16:24])


def small_map(**extra: Any) -> MapData:
    pts = [[x, y] for x in range(0, 8000, 400) for y in (0, 5000)]
    lines = [[0, 0, 8000, 0], [8000, 0, 8000, 5000], [0, 5000, 8000, 5000], [0, 0, 0, 5000]]
    objects = (
        MapObject("Goal", 1000, 1000, 45, name="Plain goal"),
        MapObject("GoalWithHeading", 2000, 1000, 90, name="Heading goal"),
        MapObject("Dock", 3000, 1000, 180, name="Dock A"),
        MapObject("RobotHome", 4000, 1000, -90, name="Home"),
        MapObject("ForbiddenArea", 0, 0, 30, name="No go", from_to=(5000, 1000, 6000, 2500)),
        MapObject("ForbiddenLine", 1000, 4000, 0, from_to=(1000, 4000, 3000, 4000)),
        MapObject("Slow", 0, 0, 0, name="Slow zone", from_to=(6500, 3000, 7500, 4500)),
    )
    info = {"MapInfo": [("SectorType", "Name=Slow", "Color0=0x123456")]}
    return MapData(scans=(Scan.from_arrays(pts, lines),), objects=objects, info=info, **extra)


def artists_by_gid(fig: Any) -> dict[str, list[Any]]:
    out: dict[str, list[Any]] = {}
    ax = fig.axes[0]
    for a in [*ax.patches, *ax.collections, *ax.lines, *ax.images, *ax.texts]:
        if a.get_gid():
            out.setdefault(a.get_gid(), []).append(a)
    return out


@pytest.mark.parametrize("width", [200, 640, 1600])
def test_png_has_the_requested_width(tmp_path: Path, width: int) -> None:
    r = render(small_map(), tmp_path / "m.png", width=width)
    assert png_size((tmp_path / "m.png").read_bytes()) == (width, r.height)
    assert r.format == "png" and r.width == width


def test_png_has_the_requested_height(tmp_path: Path) -> None:
    render(small_map(), tmp_path / "m.png", width=900, height=700)
    assert png_size((tmp_path / "m.png").read_bytes()) == (900, 700)


def test_svg_is_xml_of_the_requested_size_with_names_as_text(tmp_path: Path) -> None:
    r = render(small_map(), tmp_path / "m.svg", width=1000, dpi=100)
    root = ET.parse(tmp_path / "m.svg").getroot()
    assert root.tag.endswith("svg")
    assert float(root.get("width", "").removesuffix("pt")) == pytest.approx(1000 * 72 / 100)
    assert float(root.get("height", "").removesuffix("pt")) == pytest.approx(r.height * 72 / 100)
    texts = "".join("".join(t.itertext()) for t in root.iter() if t.tag.endswith("text"))
    for name in ("Plain goal", "Heading goal", "Dock A", "Home", "No go", "Slow zone"):
        assert name in texts


def test_pdf_is_a_pdf_of_the_requested_size(tmp_path: Path) -> None:
    r = render(small_map(), tmp_path / "m.pdf", width=720, dpi=72)
    data = (tmp_path / "m.pdf").read_bytes()
    assert data.startswith(b"%PDF-") and data.rstrip().endswith(b"%%EOF")
    box = data.split(b"/MediaBox")[1].split(b"]")[0].strip(b" [")
    assert [float(v) for v in box.split()] == pytest.approx([0, 0, 720, r.height])


def test_same_map_same_svg_bytes(tmp_path: Path) -> None:
    render(small_map(), tmp_path / "a.svg", width=500)
    render(small_map(), tmp_path / "b.svg", width=500)
    assert (tmp_path / "a.svg").read_bytes() == (tmp_path / "b.svg").read_bytes()


corner = st.integers(-50_000, 50_000)


@given(
    fx=corner, fy=corner, tx=corner, ty=corner, theta=st.floats(-180, 180), extra=st.integers(0, 3)
)
def test_forbidden_area_outline_is_its_corners(
    fx: int, fy: int, tx: int, ty: int, theta: float, extra: int
) -> None:
    """The drawn outline is exactly MapObject.corners() (ARIA's rotation about the origin)."""
    area = MapObject("ForbiddenArea", 0, 0, theta, from_to=(fx, fy, tx, ty))
    anchor = MapObject("FeedbackHandler", 0, 0, 0, from_to=(0, 0, 0, 0))  # not drawn
    objs = [anchor] + [MapObject("Goal", 100 * k, 0, name=f"g{k}") for k in range(extra)] + [area]
    m = MapData(objects=tuple(objs))
    fig, _ = make_figure(m, width=300, legend=False)
    assert "object:0" not in artists_by_gid(fig)
    drawn = artists_by_gid(fig).get(f"object:{extra + 1}", [])  # gid = index in m.objects
    if fx == tx and fy == ty:
        assert drawn == []  # a zero-size rectangle is not drawn
        return
    (patch,) = drawn
    xy = patch.get_xy()
    assert np.allclose(xy[:4], np.asarray(area.corners()) / 1000.0, atol=1e-9)


def test_showroom_forbidden_area_lands_where_formats_md_says(shared_dir: Path) -> None:
    """FORMATS.md A.7.3 / T24: FA3 (theta 180 about the origin) covers x -6001..21124,
    y -7648..-1564."""
    m = mapkit.load(shared_dir / "real" / "omron-ld-showroom-ex4.map")
    index = next(i for i, o in enumerate(m.objects) if o.name == "FA3")
    fig, _ = make_figure(m, width=800)
    (patch,) = artists_by_gid(fig)[f"object:{index}"]
    xy = patch.get_xy()[:4] * 1000
    assert xy[:, 0].min() == pytest.approx(-6001) and xy[:, 0].max() == pytest.approx(21124)
    assert xy[:, 1].min() == pytest.approx(-7648) and xy[:, 1].max() == pytest.approx(-1564)


def test_heading_arrows_for_headed_objects_only() -> None:
    m = small_map()
    fig, r = make_figure(m, width=800)
    gids = artists_by_gid(fig)
    assert "goal-heading" not in gids
    headed = (("goal_heading", m.objects[1]), ("dock", m.objects[2]), ("home", m.objects[3]))
    for kind, obj in headed:
        (q,) = gids[f"{kind}-heading"]
        assert np.allclose(q.X, [obj.x / 1000]) and np.allclose(q.Y, [obj.y / 1000])
        angle = math.degrees(math.atan2(q.V[0], q.U[0]))
        assert angle == pytest.approx(obj.theta, abs=1e-6) or abs(abs(angle) - 180) < 1e-6
        # The arrow has the same length in pixels whatever the map's size.
        assert math.hypot(q.U[0], q.V[0]) / r.metres_per_pixel == pytest.approx(22)


def test_object_kinds() -> None:
    m = small_map()
    assert [object_kind(m, o) for o in m.objects] == [
        "goal",
        "goal_heading",
        "dock",
        "home",
        "forbidden_area",
        "forbidden_line",
        "sector",
    ]


def test_declared_sector_colour_is_used() -> None:
    m = small_map()
    fig, _ = make_figure(m, width=600)
    (patch,) = artists_by_gid(fig)["object:6"]
    assert patch.get_edgecolor()[:3] == pytest.approx((0x12 / 255, 0x34 / 255, 0x56 / 255))
    assert type_params(m)["Slow"] == {"Name": "Slow", "Color0": "0x123456"}


@given(
    st.lists(
        st.tuples(st.integers(-20_000, 20_000), st.integers(-20_000, 20_000)),
        min_size=1,
        max_size=300,
    )
)
def test_every_point_is_drawn(pts: list[tuple[int, int]]) -> None:
    m = MapData(scans=(Scan.from_arrays(pts, resolution=0),))
    fig, r = make_figure(m, width=400, height=300)
    (img,) = artists_by_gid(fig)["points"]
    a = img.get_array()
    x0, y0, _, _ = r.view
    p = np.asarray(pts) / 1000.0
    ix = np.floor((p[:, 0] - x0) / r.metres_per_pixel).astype(int)
    iy = np.floor((p[:, 1] - y0) / r.metres_per_pixel).astype(int)
    lit = a[..., 3] == 255
    # Within one pixel: a point on a pixel edge may fall either side by rounding.
    near = np.zeros_like(lit)
    for dx in (-1, 0, 1):
        for dy in (-1, 0, 1):
            rows = np.clip(iy + dy, 0, lit.shape[0] - 1)
            near[rows, np.clip(ix + dx, 0, lit.shape[1] - 1)] = True
    assert all(
        lit[max(y - 1, 0) : y + 2, max(x - 1, 0) : x + 2].any() for x, y in zip(ix, iy, strict=True)
    )
    assert not (lit & ~near).any()  # nothing drawn where there is no point


def test_names_never_overlap_and_crowded_ones_are_counted() -> None:
    goals = tuple(
        MapObject("Goal", 100 * (k % 10), 100 * (k // 10), name=f"Goal number {k}")
        for k in range(100)
    )
    m = MapData(scans=(Scan.from_arrays(lines=[[0, 0, 20000, 20000]]),), objects=goals)
    fig, r = make_figure(m, width=600)
    names = artists_by_gid(fig).get("name", [])
    assert len(names) + r.names_hidden == 100 and r.names_hidden > 0
    renderer = fig.canvas.get_renderer()
    boxes = [t.get_window_extent(renderer) for t in names]
    for i, a in enumerate(boxes):
        for b in boxes[i + 1 :]:
            assert not a.overlaps(b)


def test_odd_names_are_drawn(tmp_path: Path) -> None:
    m = MapData(
        objects=(
            MapObject("Goal", 0, 0, name="cost $5 and $6"),
            MapObject("Goal", 2000, 0, name="bad \udcff byte"),
            MapObject("_Odd", 0, 2000, name="under"),
        )
    )
    render(m, tmp_path / "odd.svg", width=500)
    text = (tmp_path / "odd.svg").read_text(encoding="utf-8")
    assert "cost $5 and $6" in text and "bad \ufffd byte" in text


def test_empty_map_renders(tmp_path: Path) -> None:
    r = render(MapData(), tmp_path / "empty.png", width=300)
    assert png_size((tmp_path / "empty.png").read_bytes()) == (300, r.height)


def test_thumbnail_has_no_decorations(tmp_path: Path) -> None:
    fig, _ = make_figure(small_map(), width=200, thumbnail=True)
    assert not fig.axes[0].axison and not fig.legends and "name" not in artists_by_gid(fig)


@pytest.mark.parametrize("suffix", [".png", ".svg", ".pdf"])
def test_every_real_sample_renders(real_sample: Path, tmp_path: Path, suffix: str) -> None:
    m = mapkit.load(real_sample)
    out = tmp_path / ("pic" + suffix)
    r = render(m, out, width=700)
    assert out.stat().st_size > 1000 and r.names_hidden >= 0
    if suffix == ".png":
        assert png_size(out.read_bytes()) == (700, r.height)


def test_convert_writes_pictures(tmp_path: Path) -> None:
    src = tmp_path / "m.map"
    mapkit.save(small_map(), src)
    for suffix in (".png", ".svg", ".pdf"):
        summary = convert_file(src, tmp_path / ("out" + suffix))
        assert summary.startswith("wrote") and (tmp_path / ("out" + suffix)).stat().st_size > 0
    assert png_size((tmp_path / "out.png").read_bytes())[0] == 1600


def test_bad_suffix(tmp_path: Path) -> None:
    with pytest.raises(
        UnsupportedFormatError, match=r"pictures are \.png, \.svg or \.pdf, not '\.jpg'"
    ):
        render(small_map(), tmp_path / "m.jpg")
    assert not (tmp_path / "m.jpg").exists()


def test_nowhere_to_draw() -> None:
    with pytest.raises(RenderError, match="give an output file or show=True"):
        render(small_map())


@pytest.mark.parametrize(
    ("kw", "message"),
    [
        ({"width": 10}, "width must be between 32 and 20000 px, got 10"),
        ({"height": 99999}, "height must be between"),
        ({"dpi": 5}, "dpi must be between 10 and 1200"),
        ({"width": 60}, "a width of 60 px leaves no room for the map"),
    ],
)
def test_bad_sizes(tmp_path: Path, kw: dict[str, Any], message: str) -> None:
    with pytest.raises(RenderError, match=message):
        render(small_map(), tmp_path / "m.png", **kw)


def test_show_without_a_display(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    with pytest.raises(RenderError, match="cannot open a window: no display"):
        render(small_map(), show=True)


SHOW_SCRIPT = """
import sys
import matplotlib.pyplot as plt
import mapkit
from mapkit.render import render

shown = []
real_show = plt.show

def show(*args, **kwargs):
    fig = plt.gcf()
    shown.append(plt.get_backend())
    timer = fig.canvas.new_timer(interval=800)
    timer.add_callback(lambda: plt.close(fig))
    timer.start()
    real_show(*args, **kwargs)

plt.show = show
m = mapkit.MapData(objects=(mapkit.MapObject("Goal", 0, 0, name="G"),))
r = render(m, show=True, width=500)
print(shown[0], r.width, r.path)
"""


@pytest.fixture
def x_display() -> Any:
    """A real X server (Xvfb) on a free display number; skips where Xvfb or Tk is missing."""
    import os
    import shutil
    import subprocess
    import sys
    import time

    xvfb = shutil.which("Xvfb")
    probe = subprocess.run(
        [sys.executable, "-c", "import tkinter; from PIL import ImageTk"], capture_output=True
    )
    if xvfb is None or probe.returncode != 0:
        message = (
            "needs Xvfb and Tk for matplotlib "
            "(apt install xvfb python3-tk python3-pil.imagetk; scripts/setup does)"
        )
        if os.environ.get("CI", "").lower() in ("1", "true", "yes"):
            pytest.fail(message)
        pytest.skip(message)
    for number in range(90, 120):
        if not (
            os.path.exists(f"/tmp/.X11-unix/X{number}") or os.path.exists(f"/tmp/.X{number}-lock")
        ):
            break
    proc = subprocess.Popen(
        [xvfb, f":{number}", "-screen", "0", "1280x1024x24", "-nolisten", "tcp"],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    try:
        for _ in range(100):
            if os.path.exists(f"/tmp/.X11-unix/X{number}"):
                break
            time.sleep(0.05)
        yield f":{number}"
    finally:
        proc.terminate()
        proc.wait(timeout=10)


def test_show_opens_a_window(x_display: str) -> None:
    import os
    import subprocess
    import sys

    env = {**os.environ, "DISPLAY": x_display}
    env.pop("MPLBACKEND", None)
    res = subprocess.run(
        [sys.executable, "-c", SHOW_SCRIPT], env=env, capture_output=True, text=True, timeout=120
    )
    assert res.returncode == 0, res.stderr
    backend, width, path = res.stdout.split()
    assert backend.lower() not in ("agg", "pdf", "svg") and width == "500" and path == "None"
