"""diff: empty for equal maps, and exactly the edit for an edited one."""

from __future__ import annotations

import json

import numpy as np
from hypothesis import given, strategies as st

from mapkit import edit
from mapkit.formats.map import dumpb, loads
from mapkit.model import MapData, MapObject, Scan
from tests.edit.edit_strategies import coord, maps


@given(m=maps())
def test_diff_of_a_map_with_itself_is_empty(m: MapData) -> None:
    d = edit.diff(m, m)
    assert d.equal and d.summary() == [] and d.to_json()["equal"] is True
    assert edit.diff(m, loads(dumpb(m))).objects == ()  # objects survive the file


def test_diff_of_real_samples_with_themselves_and_their_rewrite(sample: MapData) -> None:
    assert edit.diff(sample, sample).equal
    again = loads(dumpb(sample))
    d = edit.diff(sample, again)
    assert not d.objects and not d.info and not d.data


@given(m=maps(), x=coord, y=coord)
def test_diff_names_an_added_goal_exactly(m: MapData, x: int, y: int) -> None:
    d = edit.diff(m, edit.add_goal(m, "zz new", x, y))
    assert [(c.kind, c.after.name) for c in d.objects] == [("added", "zz new")]
    assert not (d.info or d.data or d.values)


@given(m=maps(), data=st.data())
def test_diff_names_a_removed_moved_or_renamed_object_exactly(
    m: MapData, data: st.DataObject
) -> None:
    named = [i for i, o in enumerate(m.objects) if o.name and len(m.find(o.name)) == 1]
    if not named:
        return
    i = data.draw(st.sampled_from(named))
    obj = m.objects[i]
    d = edit.diff(m, edit.remove(m, obj.name))
    assert [(c.kind, c.before) for c in d.objects] == [("removed", obj)]
    dx = data.draw(st.integers(1, 5000))
    d = edit.diff(m, edit.move(m, obj.name, by=(dx, 0)))
    assert [(c.kind, c.before, c.after.name) for c in d.objects] == [("moved", obj, obj.name)]
    d = edit.diff(m, edit.rename(m, obj.name, "zz renamed"))
    assert [(c.kind, c.fields) for c in d.objects] == [("changed", ("name",))]
    assert not (d.info or d.data or d.values)


def test_diff_names_an_erase_as_data_only(sample: MapData) -> None:
    b = sample.scan.data_bounds()
    assert b is not None
    region = edit.Region.box(*b[0], (b[0][0] + b[1][0]) // 2, (b[0][1] + b[1][1]) // 2)
    out = edit.erase(sample, region)
    d = edit.diff(sample, out)
    assert not d.objects and not d.info
    removed = sum(c.removed for c in d.data if c.kind == "points")
    assert removed == sample.scan.num_points - out.scan.num_points
    for c in d.data:
        if c.kind == "points" and c.removed:
            (x0, _y0), (x1, _y1) = c.removed_box
            assert region.bounds[0] <= x0 and x1 <= region.bounds[2]


def test_diff_reports_info_values_and_sources() -> None:
    a = loads("2D-Map\nMapInfo: GoalType Name=Goal\n# note\nDATA\n1 1\n")
    b = loads(
        "2D-Map-Ex2\nMapInfo: GoalType Name=Goal\nMapInfo: DockType Name=Dock\n"
        "OriginLatLongAlt: 1 2 3\nResolution: 20\nDATA\n1 1\n"
    )
    d = edit.diff(a, b)
    assert [(c.section, c.added) for c in d.info] == [("MapInfo", (("DockType", "Name=Dock"),))]
    what = {v.what: (v.before, v.after) for v in d.values}
    assert what["category"] == ("2D-Map", "2D-Map-Ex2")
    assert what["origin_lla"] == (None, (1.0, 2.0, 3.0))
    assert what["resolution"] == (0, 20)
    assert what["unknown line"] == ("# note", None)
    doc = json.loads(json.dumps(d.to_json()))
    assert doc["equal"] is False and doc["info"][0]["added"] == ["DockType Name=Dock"]
    two = MapData(
        category="2D-Map-Ex",
        scans=(Scan.from_arrays([[1, 1]], name="Laser"), Scan.from_arrays([[2, 2]], name="Sonar")),
    )
    one = MapData(category="2D-Map-Ex", scans=(Scan.from_arrays([[1, 1]], name="Laser"),))
    d = edit.diff(one, two)
    assert ("source", None, "Sonar") in [(v.what, v.before, v.after) for v in d.values]
    assert [(c.source, c.kind, c.added) for c in d.data] == [("Sonar", "points", 1)]
    d = edit.diff(two, one)
    assert [(c.source, c.removed) for c in d.data] == [("Sonar", 1)]


def test_diff_pairs_unnamed_and_retyped_objects() -> None:
    lines = tuple(MapObject("ForbiddenLine", i, 0, from_to=(i, 0, i, 100)) for i in range(3))
    a = MapData(objects=(*lines, MapObject("Goal", 0, 0, name="G")))
    b = edit.transform(a, translate=(10, 0))
    d = edit.diff(a, b)
    assert [c.kind for c in d.objects] == ["moved"] * 4
    c = edit.diff(a, edit.move(a, "G", heading=90)).objects
    assert [(x.kind, x.fields) for x in c] == [("changed", ("type", "theta"))]
    assert "type 'Goal' -> 'GoalWithHeading'" in c[0].describe()
    inactive = MapData(inactive_objects=(MapObject("Goal", 0, 0, name="I"),))
    assert (
        edit.diff(MapData(), inactive).objects[0].describe() == "added inactive Goal 'I' at (0, 0)"
    )


def test_data_change_of_reordered_rows() -> None:
    a = MapData(scans=(Scan.from_arrays([[1, 1], [2, 2]]),))
    b = MapData(scans=(Scan.from_arrays([[2, 2], [1, 1]]),))
    d = edit.diff(a, b)
    assert [(c.added, c.removed) for c in d.data] == [(0, 0)]
    assert "other order" in d.summary()[0]
    assert np.array_equal(a.points[::-1], b.points)
