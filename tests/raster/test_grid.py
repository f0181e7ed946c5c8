"""OccupancyGrid geometry: shape from bounds, world <-> cell conversions, validation."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, strategies as st

from mapkit.raster import OccupancyGrid, RasterError, grid_for_bounds

resolutions = st.sampled_from([0.01, 0.02, 0.025, 0.05, 0.1, 0.15, 0.2, 0.5, 1.0])
coords = st.integers(-200_000, 200_000)


@st.composite
def boxes(draw: st.DrawFn) -> tuple[tuple[int, int], tuple[int, int]]:
    x0, y0 = draw(coords), draw(coords)
    return (x0, y0), (x0 + draw(st.integers(0, 30_000)), y0 + draw(st.integers(0, 30_000)))


@given(boxes(), resolutions, st.sampled_from([0.0, 0.05, 0.5, 1.3]))
def test_grid_shape_matches_bounds_and_resolution(box, res, margin) -> None:
    g = grid_for_bounds(box, res, margin)
    (x0, y0), (x1, y1) = box
    r, mm = res * 1000, margin * 1000
    (gx0, gy0), (gx1, gy1) = g.bounds_mm()
    # The grid starts at most one cell before the margin and ends in the cell holding the maximum.
    assert gx0 <= x0 - mm + 1e-6 < gx0 + r
    assert gy0 <= y0 - mm + 1e-6 < gy0 + r
    assert gx1 - r <= x1 + mm + 1e-6 and x1 + mm < gx1 - 1e-6
    assert gy1 - r <= y1 + mm + 1e-6 and y1 + mm < gy1 - 1e-6
    assert g.width == round((gx1 - gx0) / r) and g.height == round((gy1 - gy0) / r)
    assert g.data.shape == (g.height, g.width) and (g.data == -1).all()
    # The origin is a multiple of the resolution, and both corners of the box are on the grid.
    assert abs(g.origin[0] / res - round(g.origin[0] / res)) < 1e-6
    rc = g.world_to_cell([[x0, y0], [x1, y1], [x0, y1], [x1, y0]])
    assert g.inside(rc).all()


@given(boxes(), resolutions, st.data())
def test_cell_world_round_trip(box, res, data) -> None:
    g = grid_for_bounds(box, res, 0.2)
    rows = data.draw(st.lists(st.integers(0, g.height - 1), min_size=1, max_size=20))
    cols = data.draw(st.lists(st.integers(0, g.width - 1), min_size=len(rows), max_size=len(rows)))
    rc = np.stack([rows, cols[: len(rows)]], axis=1)
    assert np.array_equal(g.world_to_cell(g.cell_to_world(rc)), rc)
    # A world point maps to the cell whose square contains it.
    (bx0, by0), (bx1, by1) = g.bounds_mm()
    xs = data.draw(st.lists(st.floats(bx0, bx1 - 1e-3), min_size=1, max_size=20))
    ys = data.draw(st.lists(st.floats(by0, by1 - 1e-3), min_size=len(xs), max_size=len(xs)))
    xy = np.stack([xs, ys[: len(xs)]], axis=1)
    cells = g.world_to_cell(xy)
    assert g.inside(cells).all()
    centres = g.cell_to_world(cells)
    assert (np.abs(centres - xy) <= g.resolution_mm / 2 + 1e-6).all()


def test_single_point_conversions_keep_shape() -> None:
    g = OccupancyGrid(np.zeros((2, 3), dtype=np.int8), 0.5, (1.0, -1.0))
    assert g.world_to_cell([1000, -1000]).tolist() == [0, 0]
    assert g.world_to_cell([2499.9, -0.1]).tolist() == [1, 2]
    assert g.world_to_cell([999.9, 0]).tolist() == [2, -1]
    assert not g.inside(g.world_to_cell([999.9, 0]))
    assert g.cell_to_world([1, 2]).tolist() == [2250.0, -250.0]


def test_grid_is_immutable_and_compares_by_value() -> None:
    a = np.zeros((2, 2), dtype=np.int8)
    g = OccupancyGrid(a, 0.05, (0, 0))
    a[0, 0] = 100  # the grid took a copy
    assert g.data[0, 0] == 0
    with pytest.raises(ValueError, match="read-only"):
        g.data[0, 0] = 1
    assert g == OccupancyGrid(np.zeros((2, 2)), 0.05, (0.0, 0.0))
    assert g != g.with_data(np.full((2, 2), 100))
    assert g != OccupancyGrid(np.zeros((2, 2)), 0.05, (0.05, 0.0))
    assert g.counts() == {"occupied": 0, "free": 4, "unknown": 0, "other": 0}
    assert "2x2 cells at 0.05 m" in repr(g)


def test_values_at_and_masks() -> None:
    g = OccupancyGrid(np.array([[0, 100, -1], [50, 0, 0]], dtype=np.int8), 1.0, (0, 0))
    assert g.values_at([[500, 500], [1500, 500], [2500, 500], [500, 1500], [-1, 0]]).tolist() == [
        0,
        100,
        -1,
        50,
        -1,
    ]
    assert g.occupied.sum() == 1 and g.free.sum() == 3 and g.unknown.sum() == 1
    d = g.to_dict()
    assert d["origin"] == [0.0, 0.0, 0.0] and d["bounds_mm"] == [[0.0, 0.0], [3000.0, 2000.0]]


@pytest.mark.parametrize(
    ("data", "res", "origin", "message"),
    [
        (np.zeros(3), 0.05, (0, 0), "2-D"),
        (np.zeros((2, 2)), 0.0, (0, 0), "positive"),
        (np.zeros((2, 2)), math.nan, (0, 0), "positive"),
        (np.zeros((2, 2)), 0.05, (math.inf, 0), "finite"),
        (np.full((2, 2), 300), 0.05, (0, 0), "int8"),
    ],
)
def test_bad_grids_are_refused(data, res, origin, message) -> None:
    with pytest.raises(ValueError, match=message):
        OccupancyGrid(data, res, origin)


def test_grid_for_bounds_refuses_bad_options() -> None:
    with pytest.raises(RasterError, match="positive number of metres"):
        grid_for_bounds(((0, 0), (1, 1)), -0.05)
    with pytest.raises(RasterError, match="margin"):
        grid_for_bounds(((0, 0), (1, 1)), 0.05, -1)
    with pytest.raises(RasterError, match="too large"):
        grid_for_bounds(((0, 0), (3_000_000_000, 1)), 0.001)  # a side over 2**31 - 1 cells
    # A 400 M-cell grid's geometry takes no memory: its cells are one shared byte.
    big = grid_for_bounds(((0, 0), (1_000_000, 1_000_000)), 0.05)
    assert (big.width, big.height) == (20_021, 20_021)  # with the 0.5 m margins
    assert big.data.strides == (0, 0) and int(big.data[123, 4567]) == -1
    g = grid_for_bounds(None, 0.1, 0)
    assert (g.width, g.height, g.origin) == (1, 1, (0.0, 0.0))
