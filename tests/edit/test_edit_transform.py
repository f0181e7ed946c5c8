"""transform: rigid motions of points, lines and every object, exact for rotated rectangles."""

from __future__ import annotations

import math

import numpy as np
import pytest
import shapely
from hypothesis import given, strategies as st

from mapkit import edit
from mapkit.edit.geometry import Rigid, is_anchor
from mapkit.errors import EditError
from mapkit.formats.map import dumpb, loads
from mapkit.model import MapData, MapObject, Scan
from tests.edit.edit_strategies import coord, maps

quarter = st.sampled_from([0, 90, 180, 270, -90, 360, 450])
angle = st.floats(-720, 720, allow_nan=False, allow_infinity=False)


def _inverse(
    m: MapData, rotate: float, dx: float, dy: float, about: tuple[float, float]
) -> MapData:
    motion = edit.transform_motion(m, rotate=rotate, translate=(dx, dy), about=about)
    return edit.apply_motion(edit.apply_motion(m, motion), motion.inverse())


@given(m=maps(), rotate=quarter, dx=coord, dy=coord, px=coord, py=coord)
def test_transform_then_inverse_is_the_identity_for_right_angles(
    m: MapData, rotate: int, dx: int, dy: int, px: int, py: int
) -> None:
    assert _inverse(m, rotate, dx, dy, (px, py)) == m


@given(m=maps(sorted_data=False), rotate=angle, dx=coord, dy=coord)
def test_transform_then_inverse_is_the_identity_within_rounding(
    m: MapData, rotate: float, dx: int, dy: int
) -> None:
    back = _inverse(m, rotate, dx, dy, (0.0, 0.0))
    # Data is integer millimetres: each of the two motions rounds once (unsorted data keeps its
    # order; sorted data is re-sorted, which the right-angle test above covers exactly).
    assert back.points.shape == m.points.shape and back.lines.shape == m.lines.shape
    assert np.abs(back.points - m.points).max(initial=0) <= 1
    assert np.abs(back.lines - m.lines).max(initial=0) <= 1
    # Objects keep full precision: the identity up to float error, rectangles included.
    for a, b in zip(m.objects, back.objects, strict=False):
        assert (a.type, a.name) == (b.type, b.name)
        assert math.isclose(a.x, b.x, abs_tol=1e-6) and math.isclose(a.y, b.y, abs_tol=1e-6)
        assert abs(((a.theta - b.theta) + 180) % 360 - 180) < 1e-9
        if a.from_to is not None:
            assert np.allclose(a.from_to, b.from_to, atol=1e-6)


@given(m=maps(), rotate=angle, dx=coord, dy=coord, px=coord, py=coord)
def test_objects_move_with_the_world(
    m: MapData, rotate: float, dx: int, dy: int, px: int, py: int
) -> None:
    out = edit.transform(m, rotate=rotate, translate=(dx, dy), about=(px, py))
    motion = Rigid.about(rotate, (px, py)).then(Rigid(0, dx, dy))
    for a, b in zip(m.objects, out.objects, strict=False):
        shape = m.object_shape(a)
        if shape == "rect":
            # The exact rectangle, not a box around it: world corners move with the world.
            want = [motion.apply_xy(x, y) for x, y in a.corners()]
            assert np.allclose(b.corners(), want, atol=1e-6)
        elif shape == "line":
            assert np.allclose(
                b.from_to, [*motion.apply_xy(*a.from_to[:2]), *motion.apply_xy(*a.from_to[2:])]
            )
        else:
            assert np.allclose((b.x, b.y), motion.apply_xy(a.x, a.y))
            assert abs(((b.theta - a.theta - rotate) + 180) % 360 - 180) < 1e-9


@given(m=maps(), rotate=quarter, dx=coord, dy=coord)
def test_transformed_maps_round_trip_through_write_and_read(
    m: MapData, rotate: int, dx: int, dy: int
) -> None:
    out = edit.transform(m, rotate=rotate, translate=(dx, dy))
    again = loads(dumpb(out))
    for a, b in zip(out.objects, again.objects, strict=False):
        if a.from_to is None or a.theta % 90 == 0:
            assert a == b  # integer in, integer out
        else:  # a rectangle turned off the axes: its shifted corners are written to the mm (%.0f)
            assert np.allclose(a.from_to, b.from_to, atol=0.5) and a.theta == b.theta
    assert np.array_equal(again.points, out.points) and np.array_equal(again.lines, out.lines)
    assert dumpb(again) == dumpb(out)


def test_real_samples_turned_four_times_and_shifted_back_are_byte_identical(
    sample: MapData, canonical: bytes
) -> None:
    m = sample
    for _ in range(4):
        m = edit.transform(m, rotate=90, about=(1000, -2000))
    m = loads(dumpb(edit.transform(m, translate=(1234, -5678))))  # through the file once
    m = edit.transform(m, translate=(-1234, 5678))
    assert dumpb(m) == canonical


def test_sorted_data_stays_sorted_and_objects_keep_their_order(sample: MapData) -> None:
    out = edit.transform(sample, rotate=90)
    assert out.scan.points_sorted == sample.scan.points_sorted
    if out.scan.points_sorted and out.scan.num_points:
        p = out.points
        assert np.all(np.lexsort((p[:, 1], p[:, 0])) == np.arange(len(p)))
    assert [o.name for o in out.objects] == [o.name for o in sample.objects]
    assert out.child_objects == sample.child_objects
    assert dict(out.info) == dict(sample.info) and out.remainder == sample.remainder


def test_recenter_puts_the_data_centre_at_the_origin(sample: MapData) -> None:
    out = edit.transform(sample, recenter=True)
    b = out.scan.data_bounds()
    assert b is not None
    res = sample.scan.resolution or 1
    assert abs((b[0][0] + b[1][0]) / 2) <= res and abs((b[0][1] + b[1][1]) / 2) <= res
    motion = edit.transform_motion(sample, recenter=True)
    assert motion.tx % res == 0 and motion.ty % res == 0
    if sample.scan.resolution > 0:  # lattice points stay on the lattice
        assert (out.points % sample.scan.resolution == sample.points % sample.scan.resolution).all()
    assert edit.transform(MapData(), recenter=True) == MapData()


def test_anchors_and_inactive_objects() -> None:
    anchor = MapObject("FeedbackHandler", 0, 0, 0, name="Custom Responses", from_to=(0, 0, 0, 0))
    goal = MapObject("Goal", 1000, 0, 0, name="g")
    m = MapData(objects=(anchor, goal), inactive_objects=(goal,))
    out = edit.transform(m, rotate=90)
    assert is_anchor(out.objects[0]) and out.objects[0] is anchor
    assert out.inactive_objects[0] == out.objects[1] == MapObject("Goal", 0, 1000, 90, name="g")


def test_transform_refusals() -> None:
    m = MapData(scans=(Scan.from_arrays([[1_900_000, 0], [1_000_000, 0]]),))
    with pytest.raises(EditError, match="outside ARIA's range"):
        edit.transform(m, translate=(200_000, 0))
    side = 1_500_000
    square = MapData(scans=(Scan.from_arrays([[0, 0], [side, 0], [0, side], [side, side]]),))
    with pytest.raises(EditError, match="more than the 2 km"):
        edit.transform(square, rotate=45, about=(side // 2, side // 2))
    with pytest.raises(EditError, match="finite"):
        edit.transform(m, rotate=float("nan"))
    with pytest.raises(EditError, match="2 numbers"):
        edit.transform(m, translate=(1, 2, 3))
    goal = MapData(objects=(MapObject("Goal", 1_999_000, 0, name="far"),))
    with pytest.raises(EditError, match="Goal 'far': x"):
        edit.transform(goal, translate=(5000, 0))


def test_rigid_algebra() -> None:
    t = Rigid.about(30, (100, 200)).then(Rigid(45, 7, -3))
    x, y = t.apply_xy(500, -250)
    assert np.allclose(t.inverse().apply_xy(x, y), (500, -250))
    assert Rigid(360, 0, 0).is_identity and not Rigid(90).is_identity
    pts = np.array([[1, 2], [3, 4]])
    assert Rigid(90).apply_array(pts).tolist() == [[-2, 1], [-4, 3]]
    assert Rigid(180, 1, 1).apply_array(np.array([[1, 2, 3, 4]])).tolist() == [[0, -1, -2, -3]]
    assert shapely.Polygon(
        MapObject("A", 0, 0, 30, from_to=(0, 0, 10, 10)).corners()
    ).area == pytest.approx(100)
