"""ROS maps back to ARIA maps: points, wall lines, keepout areas, and the round trips."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st
from hypothesis.extra import numpy as hnp

import mapkit
from mapkit.model import MapData, MapObject, Scan
from mapkit.raster import OccupancyGrid, burn_polygons, object_polygons, rasterize
from mapkit.raster.import_ros import cell_runs, grid_to_map, import_ros, keepout_objects
from mapkit.raster.masks import keepout_mask
from mapkit.raster.ros import read_ros_map, write_ros_map

from .helpers import dense, off_corners

occupancy = hnp.arrays(
    np.int8,
    st.tuples(st.integers(1, 25), st.integers(1, 25)),
    elements=st.sampled_from([-1, 0, 0, 100]),
)


@given(
    occupancy,
    st.sampled_from([0.02, 0.05, 0.1]),
    st.tuples(st.integers(-500, 500), st.integers(-500, 500)),
)
@settings(max_examples=60)
def test_rasterise_of_import_reproduces_the_occupied_cells(tmp_path_factory, data, res, o) -> None:
    g = OccupancyGrid(data, res, (o[0] * res, o[1] * res))
    files = write_ros_map(g, tmp_path_factory.mktemp("r") / "m.yaml")
    m = import_ros(files.yaml, min_line_m=2 * res)
    back = rasterize(m, like=g, free="none")
    assert np.array_equal(back.data == 100, g.data == 100)
    # Every extracted line stays on the occupied cells it came from.
    if len(m.lines):
        assert (g.values_at(off_corners(g, dense(m.lines, 201))) == 100).all()


def test_points_are_cell_centres_without_transposition(tmp_path: Path) -> None:
    data = np.full((3, 5), 0, dtype=np.int8)
    data[0, 4] = 100  # south-east corner
    data[2, 0] = 100  # north-west corner
    g = OccupancyGrid(data, 0.1, (-1.0, 2.0))
    files = write_ros_map(g, tmp_path / "m.yaml")
    m = import_ros(files.yaml)
    assert sorted(map(tuple, m.points.tolist())) == [(-950, 2250), (-550, 2050)]
    assert m.scan.resolution == 100 and m.category == "2D-Map"
    # Written as a .map and read again: the same points.
    mapkit.save(m, tmp_path / "m.map")
    assert np.array_equal(mapkit.load(tmp_path / "m.map").points, m.points)


def test_yaw_rotates_about_the_origin(tmp_path: Path) -> None:
    g = OccupancyGrid(np.array([[100]], dtype=np.int8), 1.0, (2.0, 0.0))
    files = write_ros_map(g, tmp_path / "m.yaml")
    text = files.yaml.read_text().replace(
        "origin: [2.0, 0.0, 0.0]", f"origin: [2.0, 0.0, {math.pi / 2!r}]"
    )
    files.yaml.write_text(text)
    m = import_ros(files.yaml)
    assert m.points.tolist() == [[1500, 500]]  # (0.5, 0.5) m turned 90 degrees, then shifted


def test_cell_runs_all_directions() -> None:
    m = np.zeros((6, 6), dtype=bool)
    m[0, :4] = True  # a row
    m[1:5, 5] = True  # a column
    m[[2, 3, 4], [1, 2, 3]] = True  # a diagonal
    m[[5, 4, 3], [0, 1, 2]] |= True  # an anti-diagonal crossing it
    runs = {tuple(r) for r in cell_runs(m, 3).tolist()}
    assert (0, 0, 0, 3) in runs and (1, 5, 4, 5) in runs
    assert (2, 1, 4, 3) in runs and (3, 2, 5, 0) in runs


def test_diagonal_lines_mark_only_diagonal_cells() -> None:
    g = OccupancyGrid(np.zeros((8, 8), dtype=np.int8), 0.1, (0.0, 0.0))
    for seg in ([[50, 50, 650, 650]], [[650, 50, 50, 650]], [[650, 650, 50, 50]]):
        mask = rasterize(MapData(scans=(Scan.from_arrays(lines=seg),)), like=g, free="none")
        assert mask.counts()["occupied"] == 7


def _keepout_map() -> MapData:
    return MapData(
        objects=(
            MapObject("ForbiddenArea", 0, 0, 0, from_to=(1000, 1000, 2500, 1600)),
            MapObject("ForbiddenArea", 0, 0, 30, from_to=(4000, -1000, 6000, 200)),
            MapObject("ForbiddenLine", 0, 4000, 0, from_to=(0, 4000, 3000, 4000)),
            # An L made of two touching rectangles.
            MapObject("ForbiddenArea", 0, 0, 0, from_to=(-4000, -4000, -3000, -1000)),
            MapObject("ForbiddenArea", 0, 0, 0, from_to=(-3000, -4000, -1000, -3000)),
            MapObject("Goal", 5000, 5000),
        )
    )


def test_keepout_mask_imports_as_forbidden_objects(tmp_path: Path) -> None:
    m = _keepout_map()
    g = rasterize(m, 0.05)
    mask = keepout_mask(m, g)
    files = write_ros_map(mask, tmp_path / "k.yaml")
    empty = write_ros_map(g.with_data(np.zeros(g.data.shape)), tmp_path / "map.yaml")
    back = import_ros(empty.yaml, keepout=files.yaml)
    areas = [o for o in back.objects if o.type == "ForbiddenArea"]
    lines = [o for o in back.objects if o.type == "ForbiddenLine"]
    assert len(lines) == 1
    (x1, y1, x2, y2) = lines[0].from_to
    assert sorted([(x1, y1), (x2, y2)]) == [
        (25, 4025),
        (3025, 4025),
    ]  # 3000 lies in the cell [3000, 3050)
    # The axis-aligned area comes back within a cell, theta 0.
    first = [a for a in areas if a.theta == 0 and abs(a.from_to[0] - 1000) <= 50]
    assert len(first) == 1 and np.allclose(first[0].from_to, (1000, 1000, 2550, 1650), atol=50)
    # The rotated one comes back rotated by 30 (or 30 - 90) degrees, corners within two cells.
    rot = [a for a in areas if a.theta != 0]
    assert len(rot) == 1 and (abs(rot[0].theta - 30) < 3 or abs(rot[0].theta + 60) < 3)
    want = np.array(m.objects[1].corners())
    got = np.array(rot[0].corners())
    d = np.sqrt(((want[:, None] - got[None]) ** 2).sum(-1)).min(axis=1)
    assert (d <= 100).all()  # within two cells (the mask marks every cell an edge crosses)
    # Every keepout cell is covered by the imported objects, and the L is covered exactly.
    again = keepout_mask(back, g)
    assert ((again.data == 100) >= (mask.data == 100)).all()
    ell = [a for a in areas if a.from_to[0] <= -3000]
    ell_mask = burn_polygons(g, object_polygons(ell), outline=False)
    region = np.zeros_like(ell_mask)
    region[:, : g.world_to_cell([-900, 0])[1]] = True
    assert np.array_equal(ell_mask, (mask.data == 100) & region)


def test_keepout_objects_of_an_empty_mask() -> None:
    g = OccupancyGrid(np.full((3, 3), -1, dtype=np.int8), 0.1, (0, 0))
    assert keepout_objects(g) == []
    one = g.with_data(np.where(np.eye(3) * 0 == 0, -1, -1).astype(np.int8))
    one = g.with_data(np.array([[-1, -1, -1], [-1, 100, -1], [-1, -1, -1]], dtype=np.int8))
    (obj,) = keepout_objects(one)
    assert obj.type == "ForbiddenArea" and obj.from_to == (100, 100, 200, 200)


def test_grid_to_map_options() -> None:
    g = OccupancyGrid(np.array([[100] * 10], dtype=np.int8), 0.05, (0.0, 0.0))
    assert grid_to_map(g, lines=False).scan.num_lines == 0
    assert grid_to_map(g, min_line_m=1.0).scan.num_lines == 0
    assert grid_to_map(g, min_line_m=0.5).scan.num_lines == 1
    with pytest.raises(mapkit.MapkitError, match="min_line_m"):
        grid_to_map(g, min_line_m=-1)


def test_real_samples_round_trip_keeps_walls_within_a_cell(real_sample, tmp_path: Path) -> None:
    from scipy.spatial import cKDTree

    m = mapkit.load(real_sample)
    g = rasterize(m, 0.05)
    files = write_ros_map(g, tmp_path / "r.yaml")
    back = import_ros(files.yaml)
    assert np.array_equal(rasterize(back, like=g, free="none").data == 100, g.data == 100)
    # Every wall of the original (points and densely sampled lines) is within one cell of the
    # imported points.
    tree = cKDTree(back.points)
    walls = [m.points]
    if len(m.lines):
        walls.append(dense(m.lines, 50))
    dist, _ = tree.query(np.concatenate(walls))
    assert dist.max() <= 50 * math.sqrt(0.5) + 1
    # And reading the ROS map gives the same grid as rasterising.
    assert read_ros_map(files.yaml) == g
