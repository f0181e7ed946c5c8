"""3D walls: watertight meshes of the right size in every format, and a Gazebo world for them."""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
import trimesh
from hypothesis import given, strategies as st

import mapkit
from mapkit.errors import UnsupportedFormatError
from mapkit.formats.registry import convert_file
from mapkit.mesh import (
    HomePose,
    MeshError,
    export_mesh,
    extrude,
    footprint,
    home_pose,
    wall_mesh,
    world_sdf,
)
from mapkit.model import MapData, MapObject, Scan

FUSE = 1e-4  # the footprint grows by this much (mesh/walls.py _FUSE) ...
GROW = 5 * FUSE  # ... and up to 5 times that at sharp corners (mitre limit 5)


def lines_map(lines: list[list[int]], objects: tuple[MapObject, ...] = ()) -> MapData:
    return MapData(scans=(Scan.from_arrays(lines=lines),), objects=objects)


def check_closed(mesh: trimesh.Trimesh) -> None:
    assert mesh.is_watertight
    assert mesh.is_winding_consistent
    assert mesh.volume > 0  # outward normals


def check_bounds_around_lines(
    mesh: trimesh.Trimesh, lines_mm: np.ndarray, t: float, h: float
) -> None:
    """Square-ended boxes reach t/2 .. t/sqrt(2) beyond the extreme line ends."""
    ends = lines_mm.reshape(-1, 2) / 1000.0
    lo, hi = ends.min(axis=0), ends.max(axis=0)
    assert np.all(mesh.bounds[0, :2] <= lo - t / 2 + 1e-9)
    assert np.all(mesh.bounds[0, :2] >= lo - t / math.sqrt(2) - GROW - 1e-9)
    assert np.all(mesh.bounds[1, :2] >= hi + t / 2 - 1e-9)
    assert np.all(mesh.bounds[1, :2] <= hi + t / math.sqrt(2) + GROW + 1e-9)
    assert mesh.bounds[0, 2] == 0.0 and mesh.bounds[1, 2] == pytest.approx(h)


def test_one_wall_is_one_box() -> None:
    mesh = wall_mesh(lines_map([[0, 0, 3000, 0]]), height=2.5, thickness=0.2)
    check_closed(mesh)
    g = 0.1 + FUSE
    assert np.allclose(mesh.bounds, [[-g, -g, 0], [3 + g, g, 2.5]])
    assert mesh.volume == pytest.approx((3 + 2 * g) * 2 * g * 2.5)
    assert len(mesh.faces) == 12


def test_crossing_walls_are_merged() -> None:
    m = lines_map([[0, 0, 4000, 0], [2000, -2000, 2000, 2000]])
    mesh = wall_mesh(m, height=2, thickness=0.1)
    check_closed(mesh)
    # Two 4.1 x 0.1 boxes minus their 0.1 x 0.1 overlap, grown by FUSE along the outline.
    assert mesh.volume == pytest.approx((2 * 4.1 * 0.1 - 0.01) * 2, abs=16.4 * FUSE * 2 * 1.01)
    assert mesh.body_count == 1


segment = st.lists(st.integers(-20_000, 20_000), min_size=4, max_size=4)


@given(st.lists(segment, min_size=1, max_size=25), st.floats(0.02, 0.3), st.floats(0.5, 5))
def test_walls_from_any_lines_are_closed_and_fit_the_lines(
    lines: list[list[int]], t: float, h: float
) -> None:
    m = lines_map(lines)
    shape = footprint(m, thickness=t)
    mesh = extrude(shape, h)
    check_closed(mesh)
    check_bounds_around_lines(mesh, m.lines, t, h)
    seg = m.lines.reshape(-1, 2, 2) / 1000.0
    boxes = (np.hypot(*(seg[:, 1] - seg[:, 0]).T) + t) * t
    assert mesh.volume == pytest.approx(shape.area * h, rel=1e-6)
    assert mesh.volume <= (boxes.sum() * h) * (1 + 1e-6) + 2 * FUSE * shape.length * h
    assert mesh.volume >= boxes.max() * h * (1 - 1e-6)


@given(
    st.lists(
        st.tuples(st.integers(-5000, 5000), st.integers(-5000, 5000)), min_size=1, max_size=200
    ),
    st.sampled_from([0.02, 0.05, 0.1]),
)
def test_walls_from_points_cover_every_point(pts: list[tuple[int, int]], res: float) -> None:
    m = MapData(scans=(Scan.from_arrays(pts),))
    shape = footprint(m, source="auto", resolution=res)
    import shapely

    assert shapely.covers(shape, shapely.points(np.asarray(pts) / 1000.0)).all()
    # Cell (i, j) covers [i * res, (i + 1) * res) x [j * res, (j + 1) * res).
    cells = {(math.floor(x / (res * 1000)), math.floor(y / (res * 1000))) for x, y in pts}
    assert shape.area <= len(cells) * res * res + 2 * FUSE * shape.length + 1e-9
    check_closed(extrude(shape, 1.0))


def test_cells_touching_at_a_corner_still_give_a_closed_mesh() -> None:
    # Cells (0,0) and (1,1) at 0.05 m share only a corner: without fusing, an edge of 4 faces.
    m = MapData(scans=(Scan.from_arrays([[10, 10], [60, 60], [110, 10]]),))
    check_closed(wall_mesh(m, source="points", resolution=0.05))


def test_real_samples_give_closed_meshes(real_sample: Path) -> None:
    m = mapkit.load(real_sample)
    mesh = wall_mesh(m, height=2.0, thickness=0.1)
    check_closed(mesh)
    if m.lines.size:
        check_bounds_around_lines(mesh, m.lines, 0.1, 2.0)
        # Volume below the sum of the separate boxes (they overlap at corners), but most of it.
        seg = m.lines.reshape(-1, 2, 2) / 1000.0
        boxes = ((np.hypot(*(seg[:, 1] - seg[:, 0]).T) + 0.1) * 0.1).sum() * 2.0
        assert 0.5 * boxes < mesh.volume <= boxes * 1.001


@pytest.mark.parametrize("suffix", [".stl", ".obj", ".glb", ".dae"])
def test_every_format_reloads_as_the_same_solid(tmp_path: Path, suffix: str) -> None:
    m = lines_map([[0, 0, 5000, 0], [5000, 0, 5000, 4000], [0, 0, 0, 4000]])
    mesh = wall_mesh(m, height=2.0)
    out = tmp_path / ("walls" + suffix)
    r = export_mesh(m, out, height=2.0)
    back = trimesh.load(out, force="mesh")
    back.merge_vertices()  # DAE has its own vertices per triangle (flat shading)
    check_closed(back)
    assert np.allclose(back.bounds, mesh.bounds, atol=1e-6)
    assert back.volume == pytest.approx(mesh.volume, rel=1e-6)
    assert r.faces == len(mesh.faces) and r.watertight and r.source == "lines"


def test_collada_says_metres_and_z_up(tmp_path: Path) -> None:
    export_mesh(lines_map([[0, 0, 1000, 0]]), tmp_path / "w.dae")
    root = ET.parse(tmp_path / "w.dae").getroot()
    ns = {"c": "http://www.collada.org/2005/11/COLLADASchema"}
    assert root.find("c:asset/c:up_axis", ns).text == "Z_UP"
    assert root.find("c:asset/c:unit", ns).get("meter") == "1"


def test_world_loads_the_mesh_and_notes_home(tmp_path: Path) -> None:
    home = MapObject("RobotHome", 1500, -2500, 90, name="Home -- base")
    m = lines_map([[0, 0, 5000, 0]], (MapObject("Dock", 0, 0, 0, name="D"), home))
    (tmp_path / "worlds").mkdir()
    r = export_mesh(m, tmp_path / "walls.stl", world=tmp_path / "worlds" / "office.world")
    root = ET.parse(tmp_path / "worlds" / "office.world").getroot()
    assert root.tag == "sdf" and root.get("version") == "1.7"
    walls = root.find("world/model[@name='walls']")
    assert walls.find("static").text == "true"
    uris = {u.text for u in walls.iter("uri")}
    assert uris == {"../walls.stl"}
    assert (tmp_path / "worlds" / "../walls.stl").exists()
    text = (tmp_path / "worlds" / "office.world").read_text(encoding="utf-8")
    assert "<pose>1.500 -2.500 0 0 0 1.5708</pose>" in text
    assert r.home == HomePose("RobotHome", "Home -- base", 1.5, -2.5, math.pi / 2)


def test_world_without_home_says_so() -> None:
    doc = world_sdf("walls.stl")
    assert "no RobotHome or Dock" in doc
    ET.fromstring(doc)


def test_home_pose_rules() -> None:
    dock = MapObject("Dock", 1000, 2000, 180, name="D")
    area = MapObject("RobotHome", 0, 0, 90, name="Area", from_to=(0, 0, 2000, 1000))
    assert home_pose(MapData(objects=(dock,))) == HomePose("Dock", "D", 1.0, 2.0, math.pi)
    h = home_pose(MapData(objects=(dock, area)))
    assert (h.type, h.name) == ("RobotHome", "Area")
    # Centre of the rectangle rotated by 90 degrees about the origin: (-0.5, 1.0).
    assert (h.x, h.y) == pytest.approx((-0.5, 1.0))
    assert home_pose(MapData()) is None


def test_convert_writes_meshes(tmp_path: Path) -> None:
    src = tmp_path / "m.map"
    mapkit.save(lines_map([[0, 0, 2000, 0]]), src)
    for suffix in (".stl", ".obj", ".glb", ".dae"):
        out = tmp_path / ("w" + suffix)
        assert convert_file(src, out).startswith(f"wrote {out}")
        assert trimesh.load(tmp_path / ("w" + suffix), force="mesh").volume > 0


def test_no_walls_to_make() -> None:
    with pytest.raises(MeshError, match=r"has no LINES to make walls from \(0 points, 0 lines\)"):
        wall_mesh(MapData(), source="lines")
    with pytest.raises(MeshError, match=r"has no points to make walls from \(0 points, 1 line\)"):
        wall_mesh(lines_map([[0, 0, 1, 1]]), source="points")


@pytest.mark.parametrize(
    ("kw", "message"),
    [
        ({"height": 0}, "height must be a positive number of metres, got 0"),
        ({"thickness": -1}, "thickness must be a positive number of metres, got -1"),
        ({"resolution": float("nan")}, "resolution must be a positive number"),
        ({"source": "walls"}, "source must be 'auto', 'lines' or 'points', got 'walls'"),
    ],
)
def test_bad_parameters(kw: dict, message: str) -> None:
    with pytest.raises(MeshError, match=message):
        wall_mesh(lines_map([[0, 0, 1000, 0]]), **kw)


def test_bad_suffix(tmp_path: Path) -> None:
    with pytest.raises(
        UnsupportedFormatError, match=r"meshes are \.stl, \.obj, \.glb, \.dae, not '\.ply'"
    ):
        export_mesh(lines_map([[0, 0, 1000, 0]]), tmp_path / "w.ply")
    assert not list(tmp_path.iterdir())


def test_zero_length_segments_become_square_posts() -> None:
    mesh = wall_mesh(lines_map([[0, 0, 0, 0], [500, 500, 500, 500]]), height=2.0, thickness=0.1)
    check_closed(mesh)
    assert mesh.body_count == 2
    g = 0.05 + FUSE
    assert mesh.volume == pytest.approx(2 * (2 * g) ** 2 * 2.0)
