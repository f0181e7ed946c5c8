"""Data edits: erase, crop, draw-line, merge; regions and line cutting."""

from __future__ import annotations

import numpy as np
import pytest
import shapely
from hypothesis import given, strategies as st

from mapkit import edit
from mapkit.edit.selection import TOUCH, clip_lines, cut_lines, lines_overlapping, points_inside
from mapkit.errors import EditError
from mapkit.formats.map import dumpb, loads
from mapkit.model import MapData, MapObject, Scan
from tests.edit.edit_strategies import lines_arrays, maps, regions


def _segments(lines: np.ndarray) -> np.ndarray:
    return shapely.linestrings(lines.reshape(-1, 2, 2).astype(float))


def _inside_length(lines: np.ndarray, region: edit.Region) -> np.ndarray:
    """Length of each segment inside the closed region, computed independently of mapkit."""
    if len(lines) == 0:
        return np.zeros(0)
    return shapely.length(shapely.intersection(_segments(lines), shapely.Polygon(region.vertices)))


def _outside_length(lines: np.ndarray, region: edit.Region) -> np.ndarray:
    if len(lines) == 0:
        return np.zeros(0)
    return shapely.length(shapely.difference(_segments(lines), shapely.Polygon(region.vertices)))


def _look(m: MapData, region: edit.Region) -> tuple[int, int]:
    """How many points and how many line parts a person would find inside the region."""
    poly = shapely.Polygon(region.vertices)
    pts = sum(
        int(
            shapely.intersects_xy(
                poly, s.points[:, 0].astype(float), s.points[:, 1].astype(float)
            ).sum()
        )
        for s in m.scans
        if s.num_points
    )
    lines = sum(int((_inside_length(s.lines, region) > TOUCH).sum()) for s in m.scans)
    return pts, lines


# -- regions ------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("make", "message"),
    [
        (lambda: edit.Region.box(0, 0, 0, 10), "no area"),
        (lambda: edit.Region.box(0, 0, float("inf"), 10), "finite"),
        (lambda: edit.Region.box(0, 0, 3_000_000, 10), "outside ARIA's range"),
        (lambda: edit.Region.polygon([(0, 0), (1, 1)]), "at least 3 vertices"),
        (lambda: edit.Region.polygon([(0, 0), (10, 10), (10, 0), (0, 10)]), "not simple"),
        (lambda: edit.Region.polygon([(0, 0), (5, 5), (10, 10)]), "not simple|no area"),
        (lambda: edit.Region.polygon("abc"), "list of"),
        (lambda: edit.Region.polygon([(0, 0, 1), (1, 0, 1), (0, 1, 1)]), "list of"),
    ],
)
def test_bad_regions_are_refused(make, message: str) -> None:  # type: ignore[no-untyped-def]
    with pytest.raises(EditError, match=message):
        make()


def test_polygon_closed_ring_and_json() -> None:
    r = edit.Region.polygon([(0, 0), (10, 0), (0, 10), (0, 0)])
    assert len(r.vertices) == 3 and r.to_json() == {
        "polygon": [[0.0, 0.0], [10.0, 0.0], [0.0, 10.0]]
    }
    assert edit.Region.box(5, 5, 0, 0).to_json() == {"box": [0.0, 0.0, 5.0, 5.0]}
    assert "polygon of 3" in r.describe() and "box (0, 0)" in edit.Region.box(5, 5, 0, 0).describe()


# -- cutting and clipping lines -----------------------------------------------------------------


@given(lines=lines_arrays(40), region=regions())
def test_cut_leaves_nothing_inside_and_keeps_what_was_outside(
    lines: np.ndarray, region: edit.Region
) -> None:
    cut = cut_lines(lines, region)
    assert cut.dtype == np.int64 and cut.shape[1] == 4
    assert not (_inside_length(cut, region) > TOUCH).any()
    # What lay outside survives, up to the rounding of each new end (< 1.5 mm per end).
    pieces_budget = 3.0 * (len(cut) + len(lines))
    assert (
        abs(_outside_length(lines, region).sum() - _outside_length(cut, region).sum())
        <= pieces_budget
    )


@given(lines=lines_arrays(40), region=regions())
def test_clip_keeps_only_what_is_inside(lines: np.ndarray, region: edit.Region) -> None:
    clip = clip_lines(lines, region)
    assert not (_outside_length(clip, region) > TOUCH).any()
    pieces_budget = 3.0 * (len(clip) + len(lines))
    assert (
        abs(_inside_length(lines, region).sum() - _inside_length(clip, region).sum())
        <= pieces_budget
    )


def test_cut_and_clip_examples() -> None:
    box = edit.Region.box(0, 0, 10, 10)
    lines = np.array(
        [[-10, 5, 20, 5], [2, 2, 8, 8], [20, 20, 30, 30], [0, 0, 0, 10], [10, 0, 20, 0]]
    )
    assert cut_lines(lines, box).tolist() == [
        [-10, 5, 0, 5],
        [10, 5, 20, 5],
        [20, 20, 30, 30],
        [10, 0, 20, 0],
    ]
    assert clip_lines(lines, box).tolist() == [[0, 5, 10, 5], [2, 2, 8, 8], [0, 0, 0, 10]]
    assert lines_overlapping(lines, box).tolist() == [True, True, False, True, False]
    assert cut_lines(np.zeros((0, 4), np.int64), box).shape == (0, 4)


# -- erase --------------------------------------------------------------------------------------


@given(m=maps(), region=regions())
def test_erase_then_look_finds_nothing_inside(m: MapData, region: edit.Region) -> None:
    out = edit.erase(m, region)
    assert _look(out, region) == (0, 0)
    # Points outside all survive, in order; objects are not touched.
    keep = ~points_inside(m.points, region)
    assert np.array_equal(out.points, m.points[keep]) or out.scan.points_sorted
    assert sorted(map(tuple, out.points.tolist())) == sorted(map(tuple, m.points[keep].tolist()))
    assert out.objects == m.objects
    if m.scan.points_sorted and out.scan.num_points:
        p = out.points
        assert np.all(np.lexsort((p[:, 1], p[:, 0])) == np.arange(len(p)))
    assert dumpb(loads(dumpb(out))) == dumpb(out)


def test_erase_on_real_samples(sample: MapData, canonical: bytes) -> None:
    b = sample.scan.data_bounds()
    assert b is not None
    (x0, y0), (x1, y1) = b
    region = edit.Region.box(
        x0 + (x1 - x0) // 3, y0 + (y1 - y0) // 3, x1 - (x1 - x0) // 3, y1 - (y1 - y0) // 3
    )
    out = edit.erase(sample, region)
    assert _look(out, region) == (0, 0)
    assert out.objects == sample.objects and dict(out.info) == dict(sample.info)
    assert out.remainder == sample.remainder and out.origin_lla == sample.origin_lla
    assert out.scan.points_sorted == sample.scan.points_sorted
    assert out.scan.lines_sorted == sample.scan.lines_sorted
    assert out.scan.num_points + out.scan.num_lines < sample.scan.num_points + sample.scan.num_lines
    again = loads(dumpb(out))
    assert np.array_equal(again.points, out.points) and np.array_equal(again.lines, out.lines)
    # Erasing where there is nothing changes nothing at all.
    far = edit.Region.box(x1 + 1000, y1 + 1000, x1 + 2000, y1 + 2000)
    assert edit.erase(sample, far) is sample


def test_erase_only_the_named_source() -> None:
    a = Scan.from_arrays([[0, 0], [100, 100]], name="Laser")
    b = Scan.from_arrays([[0, 0]], name="Sonar")
    m = MapData(category="2D-Map-Ex", scans=(a, b))
    out = edit.erase(m, edit.Region.box(-10, -10, 10, 10), sources=["sonar"])
    assert out.scans[0] is a and out.scans[1].num_points == 0
    with pytest.raises(EditError, match="no scan source 'Radar'"):
        edit.erase(m, edit.Region.box(-10, -10, 10, 10), sources=["Radar"])
    with pytest.raises(EditError, match="needs a Region"):
        edit.erase(m, (0, 0, 1, 1))  # type: ignore[arg-type]


# -- crop -----------------------------------------------------------------------------------------


@given(m=maps(), region=regions())
def test_crop_keeps_only_the_inside(m: MapData, region: edit.Region) -> None:
    out = edit.crop(m, region)
    poly = shapely.Polygon(region.vertices)
    if out.scan.num_points:
        assert shapely.intersects_xy(
            poly, out.points[:, 0].astype(float), out.points[:, 1].astype(float)
        ).all()
    assert not (_outside_length(out.lines, region) > TOUCH).any()
    kept = [o for o in m.objects if o in out.objects]
    for o in m.objects:
        shape = m.object_shape(o)
        geom = (
            shapely.Point(o.x, o.y)
            if shape == "point"
            else shapely.LineString([o.from_to[:2], o.from_to[2:]])
            if shape == "line"
            else shapely.Polygon(o.corners())
        )
        assert (o in kept) == bool(poly.intersects(geom))
    assert edit.crop(m, region, keep_objects=True).objects == m.objects


def test_crop_drops_params_of_removed_objects_and_keeps_anchors() -> None:
    m = loads(
        "2D-Map-Ex2\nMapInfo: SectorType Name=S\n"
        "MapInfo: ArgDesc Name=V Parent=S Type=int Value=1\n"
        'CairnInfo: Params "Far" 5\n'
        'Cairn: S 0 0 0.000000 "" ICON "Far" 50000 50000 51000 51000\n'
        'Cairn: S 0 0 0.000000 "" ICON "Anchor" 0 0 0 0\n'
        'Cairn: Goal 10 10 0.000000 "" ICON "Near"\nDATA\n5 5\n90000 0\n'
    )
    out = edit.crop(m, edit.Region.box(-1000, -1000, 1000, 1000))
    assert [o.name for o in out.objects] == ["Anchor", "Near"]
    assert "CairnInfo" not in out.info
    assert out.points.tolist() == [[5, 5]]


# -- draw-line ----------------------------------------------------------------------------------


def test_draw_line_adds_a_segment_or_lattice_points(sample: MapData) -> None:
    out = edit.draw_line(sample, -1000, -1000, 1000, 1500)
    assert out.scan.num_lines == sample.scan.num_lines + 1
    assert [-1000, -1000, 1000, 1500] in out.lines.tolist()
    res = sample.scan.resolution or 20
    pts = edit.draw_line(sample, -1000, -1000, 1000, 1500, as_points=True)
    new = pts.points[
        ~np.isin(
            pts.points.view([("x", "i8"), ("y", "i8")]),
            sample.points.view([("x", "i8"), ("y", "i8")]),
        ).ravel()
    ]
    assert len(new) > 0 and (new % res == 0).all()
    assert len(np.unique(pts.points, axis=0)) == len(np.unique(sample.points, axis=0)) + len(new)
    if sample.scan.points_sorted:
        p = pts.points
        assert np.all(np.lexsort((p[:, 1], p[:, 0])) == np.arange(len(p)))
    assert (
        edit.draw_line(pts, -1000, -1000, 1000, 1500, as_points=True) is pts
    )  # nothing new to add


def test_draw_line_checks() -> None:
    with pytest.raises(EditError, match="no length"):
        edit.draw_line(MapData(), 1, 1, 1, 1)
    with pytest.raises(EditError, match="outside ARIA's range"):
        edit.draw_line(MapData(), 0, 0, 2_500_000, 0)
    wide = MapData(scans=(Scan.from_arrays([[-1_500_000, 0]]),))
    with pytest.raises(EditError, match="span 2500000 mm, more than the 2 km"):
        edit.draw_line(wide, 1_000_000, 0, 1_000_000, 10)
    with pytest.raises(EditError, match="no scan source"):
        edit.draw_line(MapData(), 0, 0, 10, 0, source="Sonar")


# -- merge ----------------------------------------------------------------------------------------


def _two() -> tuple[MapData, MapData]:
    base = loads(
        "2D-Map-Ex2\nMapInfo: GoalType Name=Goal\n"
        'Cairn: Goal 0 0 0.000000 "" ICON "Shared"\n'
        'Cairn: Goal 100 0 0.000000 "" ICON "Same"\n'
        "LINES\n-1000 0 1000 0\nDATA\n0 0\n500 500\n5000 5000\n"
    )
    other = loads(
        "2D-Map-Ex2\nMapInfo: SectorType Name=Slow\n"
        "MapInfo: ArgDesc Name=V Parent=Slow Type=int Value=1\n"
        'CairnInfo: Params "Zone" 7\n'
        'Cairn: Goal 999 0 0.000000 "" ICON "shared"\n'
        'Cairn: Goal 100 0 0.000000 "" ICON "Same"\n'
        'Cairn: Slow 0 0 0.000000 "" ICON "Zone" 0 0 10 10\n'
        "LINES\n0 -1000 0 1000\nDATA\n0 0\n600 600\n9000 9000\n"
    )
    return base, other


def test_merge_without_region_adds_everything_once() -> None:
    base, other = _two()
    out = edit.merge(base, other)
    assert sorted(map(tuple, out.points.tolist())) == [
        (0, 0),
        (500, 500),
        (600, 600),
        (5000, 5000),
        (9000, 9000),
    ]
    assert out.lines.tolist() == [[-1000, 0, 1000, 0], [0, -1000, 0, 1000]]
    assert [o.name for o in out.objects] == ["Shared", "Same", "shared", "Zone"]
    assert out.declared_types()["Slow"] == "SectorType"
    assert ("Params", '"Zone"', "7") in out.info["CairnInfo"]
    assert [(a.name, b.name) for a, b in edit.merge_clashes(base, other)] == [("Shared", "shared")]


def test_merge_region_takes_other_inside_base_outside() -> None:
    base, other = _two()
    region = edit.Region.box(-100, -100, 700, 700)
    out = edit.merge(base, other, region=region)
    assert sorted(map(tuple, out.points.tolist())) == [(0, 0), (600, 600), (5000, 5000)]
    assert sorted(map(tuple, out.lines.tolist())) == [
        (-1000, 0, -100, 0),
        (0, -100, 0, 700),
        (700, 0, 1000, 0),
    ]


@pytest.mark.parametrize(
    ("policy", "names"),
    [
        ("keep", ["Shared", "Same", "shared", "Zone"]),
        ("rename", ["Shared", "Same", "shared 2", "Zone"]),
        ("base", ["Shared", "Same", "Zone"]),
        ("other", ["Same", "shared", "Zone"]),
    ],
)
def test_merge_clash_policies(policy: str, names: list[str]) -> None:
    base, other = _two()
    assert [o.name for o in edit.merge(base, other, on_clash=policy).objects] == names


def test_merge_refusals() -> None:
    base, other = _two()
    with pytest.raises(EditError, match="1 name clash"):
        edit.merge(base, other, on_clash="error")
    with pytest.raises(EditError, match="on_clash must be one of"):
        edit.merge(base, other, on_clash="newest")
    far = MapData(scans=(Scan.from_arrays([[1_900_000, 0]]),))
    with pytest.raises(EditError, match="more than the 2 km"):
        edit.merge(MapData(scans=(Scan.from_arrays([[-500_000, 0]]),)), far)


def test_merge_renamed_params_follow() -> None:
    base = loads(
        "2D-Map-Ex2\nMapInfo: SectorType Name=Slow\nMapInfo: ArgDesc Name=V Parent=Slow Type=int\n"
        'CairnInfo: Params "Zone" 1\nCairn: Slow 0 0 0.000000 "" ICON "Zone" 0 0 10 10\nDATA\n'
    )
    other = loads(
        "2D-Map-Ex2\nMapInfo: SectorType Name=Slow\nMapInfo: ArgDesc Name=V Parent=Slow Type=int\n"
        'CairnInfo: Params "Zone" 2\nCairn: Slow 0 0 0.000000 "" ICON "Zone" 0 0 20 20\nDATA\n'
    )
    out = edit.merge(base, other, on_clash="rename")
    params = [ln for ln in out.info["CairnInfo"] if ln[0] == "Params"]
    assert params == [("Params", '"Zone"', "1"), ("Params", '"Zone 2"', "2")]
    assert out.info["MapInfo"] == base.info["MapInfo"]


@given(a=maps(), b=maps(), policy=st.sampled_from(["keep", "rename", "base", "other"]))
def test_merge_keeps_every_point_of_both(a: MapData, b: MapData, policy: str) -> None:
    out = edit.merge(a, b, on_clash=policy)
    have = set(map(tuple, out.points.tolist()))
    assert have == set(map(tuple, a.points.tolist())) | set(map(tuple, b.points.tolist()))
    assert all(o in out.objects for o in a.objects if policy != "other")
    names = [o.name.lower() for o in out.objects if o.name]
    if policy in ("rename", "base", "other") and len(
        set(o.name.lower() for o in a.objects if o.name)
    ) == len([o for o in a.objects if o.name]):
        assert len(names) == len(set(names))


def test_merge_two_real_columbias(shared_dir) -> None:  # type: ignore[no-untyped-def]
    from mapkit.formats.map import load

    a = load(shared_dir / "real" / "aria294-columbia.map")
    b = load(shared_dir / "real" / "aria291-columbia.map")
    out = edit.merge(a, b)
    assert np.array_equal(out.points, a.points)  # same scan: nothing new
    assert out.scans[0] is not None and len(out.objects) > len(a.objects)
    assert [o for o in out.objects[: len(a.objects)]] == list(a.objects)


def test_merge_other_sources() -> None:
    base = MapData(category="2D-Map-Ex", scans=(Scan.from_arrays([[0, 0]], name="Laser"),))
    other = MapData(
        category="2D-Map-Ex",
        scans=(Scan.from_arrays([[1, 1]], name="Laser"), Scan.from_arrays([[2, 2]], name="Sonar")),
    )
    out = edit.merge(base, other)
    assert [s.name for s in out.scans] == ["Laser", "Sonar"]
    assert out.scans[1].points.tolist() == [[2, 2]]
    with pytest.raises(EditError, match="lacks"):
        edit.merge(MapData(), other)
    obj = MapObject("Goal", 5, 5, name="g")
    assert edit.merge(MapData(objects=(obj,)), MapData(objects=(obj,))).objects == (obj,)
