"""The rasteriser: points, lines, polygons, inflation, flood fill, hull, and real maps."""

from __future__ import annotations

import importlib
import math

import numpy as np
import pytest
from hypothesis import given, strategies as st

import mapkit
from mapkit.model import MapData, MapObject, Scan
from mapkit.raster import (
    RasterError,
    burn_points,
    burn_polygons,
    burn_segments,
    flood_fill,
    grid_for,
    grid_for_bounds,
    hull_mask,
    inflate,
    object_polygons,
    rasterize,
    seed_points,
)

from .helpers import covered, dense, off_corners

R = importlib.import_module("mapkit.raster.rasterize")

resolutions = st.sampled_from([0.02, 0.05, 0.1, 0.25])
mm = st.integers(-5_000, 5_000)
points = st.lists(st.tuples(mm, mm), min_size=1, max_size=60)
segments = st.lists(st.tuples(mm, mm, mm, mm), min_size=1, max_size=15)


def _seg_dist(p: np.ndarray, seg: np.ndarray) -> np.ndarray:
    """Distance of each point to the nearest segment."""
    a, b = seg[None, :, 0:2], seg[None, :, 2:4]
    d = b - a
    L = (d**2).sum(-1)
    t = np.clip(((p[:, None] - a) * d).sum(-1) / np.where(L == 0, 1, L), 0, 1)
    return np.sqrt(((a + t[..., None] * d - p[:, None]) ** 2).sum(-1)).min(axis=1)


@given(points, resolutions)
def test_every_point_lands_in_an_occupied_cell(pts, res) -> None:
    m = MapData(scans=(Scan.from_arrays(points=pts),))
    g = rasterize(m, res, free="none", margin_m=0)
    assert (g.values_at(pts) == 100).all()
    # ... and nothing else is occupied: one cell per distinct point cell.
    assert g.counts()["occupied"] == len({tuple(c) for c in g.world_to_cell(pts).tolist()})


@given(segments, resolutions)
def test_every_cell_a_line_crosses_is_occupied(segs, res) -> None:
    seg = np.array(segs, dtype=np.float64)
    g = grid_for_bounds(((-5000, -5000), (5000, 5000)), res, 0.1)
    mask = burn_segments(g, seg)
    assert covered(g, mask, off_corners(g, dense(seg))).all()
    # No stray cells: every marked cell's square touches a segment.
    cells = np.argwhere(mask)
    centres = g.cell_to_world(cells)
    assert (_seg_dist(centres, seg) <= g.resolution_mm * math.sqrt(0.5) + 1e-6).all()


@pytest.mark.parametrize("angle", np.arange(0, 360, 7.5))
def test_lines_have_no_gaps_at_any_angle(angle) -> None:
    g = grid_for_bounds(((-3000, -3000), (3000, 3000)), 0.05, 0)
    a = math.radians(angle)
    seg = np.array([[13.0, -7.0, 13 + 2900 * math.cos(a), -7 + 2900 * math.sin(a)]])
    mask = burn_segments(g, seg)
    rc = g.world_to_cell(dense(seg, 20001))
    assert mask[rc[:, 0], rc[:, 1]].all()
    # The cells form one 4-connected chain.
    from scipy import ndimage

    assert ndimage.label(mask)[1] == 1


def test_segments_on_grid_lines_and_degenerate_ones() -> None:
    g = grid_for_bounds(((0, 0), (1000, 1000)), 0.1, 0)
    # A point-like segment marks its cell; a segment along a grid line marks the cells above it.
    mask = burn_segments(g, [[250, 250, 250, 250], [0, 500, 1000, 500]])
    assert mask[2, 2] and mask[5].all() and mask.sum() == 12
    # Segments off the grid are ignored; parts on it are drawn.
    mask = burn_segments(g, [[-5000, 50, 5000, 50], [5000, 5000, 6000, 6000]])
    assert mask[0].all() and mask.sum() == 11
    assert burn_segments(g, np.zeros((0, 4))).sum() == 0


def test_burn_into_existing_mask_and_bad_mask() -> None:
    g = grid_for_bounds(((0, 0), (1000, 1000)), 0.1, 0)
    out = np.zeros(g.data.shape, dtype=bool)
    assert burn_points(g, [[0, 0]], out=out) is out
    burn_segments(g, [[0, 1000, 1000, 1000]], out=out)
    assert out[0, 0] and out[10].all()
    with pytest.raises(ValueError, match="bool array of shape"):
        burn_points(g, [[0, 0]], out=np.zeros((2, 2), dtype=bool))


@given(
    st.tuples(mm, mm, mm, mm),
    st.floats(-180, 180),
    resolutions,
)
def test_rotated_rectangles_cover_their_cells(ft, theta, res) -> None:
    fx, fy, tx, ty = ft
    obj = MapObject("ForbiddenArea", 0, 0, theta, from_to=ft)
    (poly,) = object_polygons([obj])
    g = grid_for_bounds(((-8000, -8000), (8000, 8000)), res, 0)
    mask = burn_polygons(g, [poly])
    from shapely import contains_xy
    from shapely.geometry import Polygon

    shape = Polygon(poly) if abs(fx - tx) > 0 and abs(fy - ty) > 0 else None
    # Every cell whose centre is inside is marked (all cells of the bounding box checked) ...
    if shape is not None:
        (r0, c0), (r1, c1) = g.world_to_cell(poly.min(axis=0)), g.world_to_cell(poly.max(axis=0))
        rr, cc = np.mgrid[
            max(r0, 0) : min(r1, g.height - 1) + 1, max(c0, 0) : min(c1, g.width - 1) + 1
        ]
        cells = np.stack([rr.ravel(), cc.ravel()], axis=1)
        xy = g.cell_to_world(cells)
        inside = contains_xy(shape, xy[:, 0], xy[:, 1])
        assert mask[cells[inside, 0], cells[inside, 1]].all()
    # ... and the outline marks the cells its edges cross.
    edges = np.concatenate([poly, np.roll(poly, -1, axis=0)], axis=1)
    assert covered(g, mask, off_corners(g, dense(edges, 2001))).all()
    # Nothing farther than a cell's half-diagonal from the rectangle is marked.
    marked = g.cell_to_world(np.argwhere(mask))
    if shape is not None and len(marked):
        from shapely import distance, points as spoints

        assert (distance(shape, spoints(marked)) <= g.resolution_mm * math.sqrt(0.5) + 1e-6).all()


def test_polygon_fill_without_outline_uses_cell_centres() -> None:
    g = grid_for_bounds(((0, 0), (1000, 1000)), 0.1, 0)
    # A tiny square between centres marks nothing without its outline, one cell with it.
    tiny = [[[110, 110], [140, 110], [140, 140], [110, 140]]]
    assert burn_polygons(g, tiny, outline=False).sum() == 0
    assert burn_polygons(g, tiny).sum() == 1
    # A triangle: centres on its hypotenuse count as inside.
    tri = [[[50, 50], [550, 50], [50, 550]]]
    got = burn_polygons(g, tri, outline=False)
    rows, cols = np.nonzero(got)
    assert ((rows + cols) <= 5).all() and got.sum() == 21


def test_inflate_matches_brute_force() -> None:
    rng = np.random.default_rng(3)
    mask = rng.random((40, 50)) < 0.02
    got = inflate(mask, 230, 0.05)
    cells = np.argwhere(mask)
    allc = np.argwhere(np.ones_like(mask))
    d = np.sqrt(((allc[:, None, :] - cells[None]) ** 2).sum(-1)).min(axis=1) * 50
    want = (d <= 230).reshape(mask.shape)
    assert np.array_equal(got, want)
    assert np.array_equal(inflate(mask, 0, 0.05), mask)
    assert not inflate(np.zeros((3, 3), dtype=bool), 100, 0.05).any()


def test_hull_matches_brute_force() -> None:
    rng = np.random.default_rng(5)
    mask = np.zeros((30, 40), dtype=bool)
    mask[tuple(rng.integers(5, 25, (2, 12)))] = True
    got = hull_mask(mask)
    from shapely.geometry import MultiPoint, Point

    hull = MultiPoint([(c + 0.5, r + 0.5) for r, c in np.argwhere(mask)]).convex_hull
    want = np.array(
        [
            [hull.buffer(1e-9).contains(Point(c + 0.5, r + 0.5)) for c in range(40)]
            for r in range(30)
        ]
    )
    assert np.array_equal(got, want)
    # Collinear and single cells.
    line = np.zeros((5, 5), dtype=bool)
    line[1, 1] = line[3, 3] = True
    assert np.array_equal(np.argwhere(hull_mask(line)), [[1, 1], [2, 2], [3, 3]])
    assert not hull_mask(np.zeros((3, 3), dtype=bool)).any()


def test_flood_fill_stops_at_diagonal_walls() -> None:
    # A diagonal (8-connected) wall splits the square in two.
    walls = np.eye(6, dtype=bool)
    filled = flood_fill(~walls, [[5, 0]])
    assert filled[5, 0] and not filled[0, 5]
    assert filled.sum() == 15
    # Seeds on walls or off the grid are ignored.
    assert not flood_fill(~walls, [[0, 0], [9, 9], [-1, 0]]).any()


def _room(objects=()) -> MapData:
    walls = [[0, 0, 4000, 0], [4000, 0, 4000, 3000], [4000, 3000, 0, 3000], [0, 3000, 0, 0]]
    return MapData(scans=(Scan.from_arrays(lines=walls),), objects=tuple(objects))


def test_flood_fills_the_room_from_home_only() -> None:
    m = _room([MapObject("RobotHome", 2000, 1500)])
    g = rasterize(m, 0.1, margin_m=0.5)
    assert g.values_at([[2000, 1500], [100, 100], [3900, 2900]]).tolist() == [0, 0, 0]
    assert g.values_at([[-200, 1500], [4200, 1500], [2000, -300]]).tolist() == [-1, -1, -1]
    assert g.values_at([[0, 0], [4000, 3000], [2000, 3000]]).tolist() == [100, 100, 100]
    # The interior is exactly the free space.
    assert g.counts()["free"] == 39 * 29
    # Without a seed: the walls' hull; hull/all/none modes.
    assert rasterize(_room(), 0.1).counts()["free"] == 39 * 29
    assert rasterize(m, 0.1, free="hull").counts()["free"] == 39 * 29
    assert rasterize(m, 0.1, free="none").counts()["free"] == 0
    all_ = rasterize(m, 0.1, free="all", margin_m=0.5)
    assert all_.counts()["unknown"] == 0


def test_flood_through_a_gap_stays_inside_the_hull() -> None:
    walls = [[0, 0, 4000, 0], [4000, 0, 4000, 3000], [4000, 3000, 0, 3000], [0, 3000, 0, 1000]]
    m = MapData(scans=(Scan.from_arrays(lines=walls),), objects=(MapObject("Goal", 2000, 1500),))
    g = rasterize(m, 0.1, margin_m=1.0)
    assert g.values_at([[2000, 1500], [-500, 1500]]).tolist() == [0, -1]


def test_seeds_include_declared_goal_types_and_home_rectangles() -> None:
    m = MapData(
        objects=(
            MapObject("GoalWithHeading", 1, 2, 90),
            MapObject("Dock", 3, 4),
            MapObject("StandbyGoal", 5, 6),
            MapObject("RobotHome", 0, 0, 0, from_to=(0, 0, 100, 200)),
            MapObject("ForbiddenArea", 0, 0, 0, from_to=(0, 0, 100, 200)),
            MapObject("Sim.BoxObstacle", 9, 9),
        ),
        info={"MapInfo": [("GoalType", "Name=StandbyGoal")]},
    )
    assert seed_points(m).tolist() == [[1, 2], [3, 4], [5, 6], [50, 100]]


def test_inflation_and_forbidden_as_walls() -> None:
    fa = MapObject("ForbiddenArea", 0, 0, 0, from_to=(1000, 1000, 1500, 1500))
    fl = MapObject("ForbiddenLine", 2500, 500, 0, from_to=(2500, 500, 2500, 2500))
    m = _room([MapObject("RobotHome", 500, 500), fa, fl])
    g = rasterize(m, 0.1)
    assert g.values_at([[1250, 1250], [2500, 1500]]).tolist() == [0, 0]
    gw = rasterize(m, 0.1, forbidden_as_walls=True)
    assert gw.values_at([[1250, 1250], [2500, 1500]]).tolist() == [100, 100]
    gi = rasterize(m, 0.1, inflate_mm=300)
    assert gi.values_at([[290, 1500], [420, 1500], [3750, 1500]]).tolist() == [100, 0, 100]


def test_bad_options() -> None:
    m = _room()
    with pytest.raises(RasterError, match="free must be one of"):
        rasterize(m, free="everything")  # type: ignore[arg-type]
    with pytest.raises(RasterError, match="inflation"):
        rasterize(m, inflate_mm=-1)
    with pytest.raises(RasterError, match="positive number"):
        rasterize(m, 0)
    with pytest.raises(FileNotFoundError):
        rasterize(m, log="no-such-log.2d")


def test_empty_map_gives_a_small_unknown_grid() -> None:
    g = rasterize(MapData(), 0.1, margin_m=0.2)
    assert g.counts()["unknown"] == g.width * g.height == 25


def test_real_samples(real_sample) -> None:
    m = mapkit.load(real_sample)
    g = rasterize(m, 0.05)
    if len(m.points):
        assert (g.values_at(m.points) == 100).all()
    if len(m.lines):
        assert (g.values_at(m.lines[:, 0:2]) == 100).all()
        assert (g.values_at(m.lines[:, 2:4]) == 100).all()
    base = grid_for(m, 0.05)
    assert g.same_geometry(base)
    seeds = seed_points(m)
    c = g.counts()
    assert c["occupied"] > 0 and c["free"] > 0
    # Every seed that is not on a wall is free.
    vals = g.values_at(seeds)
    assert set(vals.tolist()) <= {0, 100}


def test_free_from_rays_marks_beams_but_not_hits() -> None:
    m = _room()
    rng = np.random.default_rng(7)
    angles = rng.uniform(0, 2 * np.pi, 500)
    # A sensor at (2000, 1500) in the 4 x 3 m room: each beam ends on the wall it meets.
    d = np.stack([np.cos(angles), np.sin(angles)], axis=1)
    with np.errstate(divide="ignore"):
        tx = np.where(d[:, 0] > 0, (4000 - 2000) / d[:, 0], (0 - 2000) / d[:, 0])
        ty = np.where(d[:, 1] > 0, (3000 - 1500) / d[:, 1], (0 - 1500) / d[:, 1])
    t = np.minimum(np.abs(tx), np.abs(ty))
    ends = np.rint(np.array([2000, 1500]) + d * t[:, None])  # integer mm, as logs hold them
    rays = np.concatenate([np.tile([2000, 1500], (500, 1)), ends], axis=1)
    g = rasterize(m, 0.1, free="rays", rays_mm=rays)
    assert g.values_at([[2000, 1500], [3500, 1500], [-300, 1500]]).tolist() == [0, 0, -1]
    assert (g.values_at(ends) == 100).all()
    free = g.data == 0
    assert free.sum() > 0.8 * 39 * 29 and free.sum() <= 39 * 29
    # Max-range readings (no hit) free their end cell too; chunking does not change the result.
    base = grid_for(m, 0.1)
    a = R.free_from_rays(base, [[500, 500, 1000, 500]], hits=[False])
    b = R.free_from_rays(base, [[500, 500, 1000, 500]])
    assert a.sum() == b.sum() + 1
    assert np.array_equal(R.free_from_rays(base, rays, chunk=7), R.free_from_rays(base, rays))
    with pytest.raises(RasterError, match="one flag per ray"):
        R.free_from_rays(base, rays, hits=[True])
    with pytest.raises(RasterError, match="go together"):
        rasterize(m, free="rays")
    with pytest.raises(RasterError, match="go together"):
        rasterize(m, rays_mm=rays)
