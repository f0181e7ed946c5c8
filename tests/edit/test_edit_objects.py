"""Object edits: add, remove, rename, move; their checks; what they leave untouched."""

from __future__ import annotations

import math

import numpy as np
import pytest
import shapely
from hypothesis import given, strategies as st
from shapely import affinity

from mapkit import edit
from mapkit.edit.declared import object_params, type_args
from mapkit.errors import EditError
from mapkit.formats.map import dumpb, loads
from mapkit.model import MapData, MapObject
from tests.edit.edit_strategies import coord, maps


def _map(text: str) -> MapData:
    return loads(text)


OMRON_LIKE = (
    "2D-Map-Ex4\n"
    'MapInfo: SectorType Name=Slow "Label=Slow sector" NameRequired=1\n'
    "MapInfo: ArgDesc Name=Importance Parent=Slow Type=string Value=Normal\n"
    "MapInfo: ArgDesc Name=TransVelMax Parent=Slow Type=int Value=0 Min=0 Max=2000\n"
    "MapInfo: ArgDesc Name=Enabled Parent=Slow Type=bool Value=true\n"
    "MapInfo: BoundaryType Name=Measure Shape=Measure\n"
    "MapInfo: GoalType Name=Goal\n"
    "MapInfo: GoalType Name=DoorGoal Heading=Optional\n"
    "MapInfo: DockType Name=DockLynx\n"
    "MapInfo: LocationType Name=Label Heading=Never\n"
    "MapInfo: CairnGroupType Name=Group\n"
    'CairnInfo: GroupMember "c1" "Goal" "Group" "x"\n'
    'CairnInfo: Params "Alpha" "Normal" 10 true\n'
    'CairnInfo: Params "Zulu" "Normal" 20 false\n'
    'RouteInfo: GoalAfter "Goal1"\n'
    'Cairn: Slow 0 0 0.000000 "" ICON "Alpha" 0 0 1000 1000\n'
    'Cairn: Slow 0 0 0.000000 "" ICON "Zulu" 2000 0 3000 1000\n'
    'Cairn: GoalWithHeading 1240 8152 90.000000 "" ICON "Goal1"\n'
    "DATA\n"
)


# -- the rule the lead asked for: an edit and its undo give back the original bytes -------------


def test_add_goal_then_remove_gives_back_the_canonical_bytes(
    sample: MapData, canonical: bytes
) -> None:
    m = edit.add_goal(sample, "mapkit test goal", 1234, -567, heading=45)
    assert m.scans is sample.scans  # objects-only edits keep the scans themselves
    assert dumpb(m) != canonical
    assert dumpb(edit.remove(m, "mapkit test goal")) == canonical


def test_every_object_kind_added_and_removed_restores_the_bytes(
    sample: MapData, canonical: bytes
) -> None:
    m = edit.add_dock(sample, "t dock", 100, 200, heading=-90)
    m = edit.add_home(m, 0, 0, heading=10, name="t home")
    m = edit.add_home(m, area=(0, 0, 1000, 500), angle=30, name="t home area")
    m = edit.forbid_area(
        m, -1000, -1000, 1000, 1000, angle=15, rotate_about_centre=True, name="t area"
    )
    m = edit.forbid_line(m, 0, 0, 5000, 0, name="t line")
    assert len(m.objects) == len(sample.objects) + 5
    assert m.objects[: len(sample.objects)] == sample.objects  # order of existing objects kept
    back = edit.remove(m, "t dock", "t home", "t home area", "t area", "t line")
    assert dumpb(back) == canonical


def test_objects_edits_round_trip_through_write_and_read(sample: MapData) -> None:
    m = edit.add_goal(sample, "rt goal", 1000, 2000, heading=-12.5, description="by the window")
    m = edit.forbid_area(m, 10, 20, 3010, 1020, angle=90)
    m = edit.move(m, "rt goal", 1500, 2500)
    again = loads(dumpb(m))
    assert again == m
    assert dumpb(again) == dumpb(m)


@given(m=maps(), x=coord, y=coord, heading=st.integers(-179, 180))
def test_add_remove_is_identity_property(m: MapData, x: int, y: int, heading: int) -> None:
    name = "zz unique name"
    added = edit.add_goal(m, name, x, y, heading=heading)
    assert added.objects[-1] == MapObject("GoalWithHeading", x, y, heading, name=name)
    assert edit.remove(added, name) == m
    again = loads(dumpb(added))
    assert again.objects == added.objects
    assert dumpb(again) == dumpb(added)


# -- rectangles --


@given(
    box=st.tuples(coord, coord, coord, coord).filter(lambda t: t[0] != t[2] and t[1] != t[3]),
    angle=st.floats(-360, 360, allow_nan=False),
)
def test_rotate_about_centre_gives_the_box_turned_in_place(
    box: tuple[int, int, int, int], angle: float
) -> None:
    x1, y1, x2, y2 = box
    m = edit.forbid_area(MapData(), x1, y1, x2, y2, angle=angle, rotate_about_centre=True)
    seen = shapely.Polygon(m.objects[0].corners())
    drawn = affinity.rotate(
        shapely.box(min(x1, x2), min(y1, y2), max(x1, x2), max(y1, y2)), angle, origin="centroid"
    )
    # Stored corners are whole millimetres (as ARIA writes them): each is within 0.5 mm per axis.
    assert seen.hausdorff_distance(drawn) <= 0.5 * 2**0.5 + 1e-9


@pytest.mark.parametrize(
    "how", [{"rotate_about": "origin"}, {"rotate_about_centre": False}], ids=["origin", "legacy"]
)
def test_rotate_about_origin_turns_as_aria_does(how: dict[str, object]) -> None:
    m = edit.forbid_area(MapData(), -21124, 1564, 6001, 7648, angle=180, **how)  # type: ignore[arg-type]
    xs = sorted(round(c[0]) for c in m.objects[0].corners())
    ys = sorted(round(c[1]) for c in m.objects[0].corners())
    assert (xs[0], xs[-1], ys[0], ys[-1]) == (-6001, 21124, -7648, -1564)  # FORMATS.md T24


@pytest.mark.parametrize("angle", [20, 90, -135, 179.5])
@pytest.mark.parametrize("how", [{}, {"rotate_about": "centre"}, {"rotate_about_centre": True}])
def test_an_angle_turns_the_box_about_its_own_centre_by_default(
    angle: float, how: dict[str, object]
) -> None:
    # drawn 7 m from the origin, it stays 7 m from the origin (it landed 4 m away before)
    area = {"add_home": "RobotHome", "forbid_area": "ForbiddenArea"}
    for fn in area:
        if fn == "forbid_area":
            m = edit.forbid_area(MapData(), 6000, 3000, 8000, 4000, angle=angle, **how)  # type: ignore[arg-type]
        else:
            m = edit.add_home(MapData(), area=(6000, 3000, 8000, 4000), angle=angle, **how)  # type: ignore[arg-type]
        corners = m.objects[0].corners()
        cx = sum(c[0] for c in corners) / 4
        cy = sum(c[1] for c in corners) / 4
        assert m.objects[0].type == area[fn]
        assert (cx, cy) == pytest.approx((7000, 3500), abs=1)
        assert m.objects[0].theta == pytest.approx(angle)


def test_rotating_about_both_is_refused() -> None:
    with pytest.raises(EditError, match="not both"):
        edit.forbid_area(
            MapData(), 0, 0, 1, 1, angle=5, rotate_about="origin", rotate_about_centre=True
        )
    with pytest.raises(EditError, match="'centre' or 'origin'"):
        edit.forbid_area(MapData(), 0, 0, 1, 1, angle=5, rotate_about="middle")


# -- checks --


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (lambda m: edit.add_goal(m, "Goal1", 0, 0), "already exists"),
        (lambda m: edit.add_goal(m, "goal1", 0, 0), "case-insensitively"),
        (lambda m: edit.add_goal(m, 'say "hi"', 0, 0), "contains '\"'"),
        (lambda m: edit.add_goal(m, "two\nlines", 0, 0), "line break"),
        (lambda m: edit.add_goal(m, "", 0, 0), "needs a name"),
        (lambda m: edit.add_goal(m, "A", float("nan"), 0), "finite"),
        (lambda m: edit.add_goal(m, "A", 0, 0, heading=float("inf")), "finite"),
        (lambda m: edit.add_goal(m, "A", 2_000_001, 0), "outside ARIA's range"),
        (lambda m: edit.add_goal(m, "A", "12", 0), "must be a number"),
        (lambda m: edit.add_goal(m, "A", 0, 0, description='a "b'), "description"),
        (lambda m: edit.forbid_area(m, 0, 0, 0, 100), "degenerate"),
        (lambda m: edit.forbid_area(m, 0, 0, 100, 100, angle=float("nan")), "angle"),
        (
            lambda m: edit.forbid_area(
                m, 1_900_000, 1_900_000, 1_950_000, 1_950_000, angle=45, rotate_about="origin"
            ),
            "corner y",
        ),
        (lambda m: edit.forbid_line(m, 5, 5, 5, 5), "no length"),
        (lambda m: edit.add_object(m, "Nope", at=(0, 0), name="x"), "not declared"),
        (lambda m: edit.add_object(m, "Slow", at=(0, 0), name="x"), "takes an area"),
        (lambda m: edit.add_object(m, "Measure", area=(0, 0, 1, 1)), "takes a line"),
        (lambda m: edit.add_object(m, "Slow", area=(0, 0, 1, 1)), "needs a name"),
        (lambda m: edit.add_object(m, "Group", at=(0, 0), name="g"), "group template"),
        (lambda m: edit.add_object(m, "Label", at=(0, 0), heading=5, name="l"), "Heading=Never"),
        (
            lambda m: edit.add_object(m, "Goal", at=(0, 0), area=(0, 0, 1, 1), name="g"),
            "exactly one",
        ),
        (
            lambda m: edit.add_object(m, "Slow", area=(0, 0, 1, 1), heading=3, name="s"),
            "only point objects",
        ),
        (lambda m: edit.add_object(m, "Bad Type", at=(0, 0)), "one word"),
        (lambda m: edit.add_object(m, "Goal", at=(0, 0), name="g", icon="A B"), "icon"),
        (lambda m: edit.add_goal(m, "A", 0, 0, type="Slow"), "not a goal type"),
        (lambda m: edit.add_dock(m, "A", 0, 0, type="DoorGoal"), "not a dock type"),
        (lambda m: edit.add_home(m, 0, 0, area=(0, 0, 1, 1)), "not both"),
        (lambda m: edit.add_home(m), "position X Y or an area"),
    ],
)
def test_bad_input_is_refused_with_a_clear_message(call, message: str) -> None:  # type: ignore[no-untyped-def]
    m = _map(OMRON_LIKE)
    with pytest.raises(EditError, match=message):
        call(m)


def test_duplicates_and_undeclared_types_can_be_asked_for() -> None:
    m = _map(OMRON_LIKE)
    m2 = edit.add_goal(m, "GOAL1", 0, 0, allow_duplicate=True)
    assert [o.name for o in m2.find("goal1")] == ["Goal1", "GOAL1"]
    m3 = edit.add_object(m, "Sim.BoxObstacle", area=(0, 0, 500, 500), allow_undeclared=True)
    assert m3.objects[-1].type == "Sim.BoxObstacle" and m3.object_shape(m3.objects[-1]) == "rect"


def test_declared_goal_type_with_heading_becomes_with_heading() -> None:
    m = edit.add_goal(_map(OMRON_LIKE), "Door A", 0, 0, type="DoorGoal", heading=90)
    assert m.objects[-1].type == "DoorGoalWithHeading"
    assert edit.add_goal(m, "Door B", 0, 0, type="DoorGoal").objects[-1].type == "DoorGoal"


# -- parameters --


def test_params_line_is_written_in_name_order_with_defaults() -> None:
    m = edit.add_object(
        _map(OMRON_LIKE), "Slow", area=(0, 0, 500, 500), name="Mike", params={"transvelmax": 300}
    )
    lines = m.info["CairnInfo"]
    params = [ln for ln in lines if ln[0] == "Params"]
    assert [p[1] for p in params] == ['"Alpha"', '"Mike"', '"Zulu"']
    assert params[1] == ("Params", '"Mike"', '"Normal"', "300", "true")
    assert lines[0][0] == "GroupMember"  # other lines stay where they were
    assert object_params(m, m.objects[-1]) == {
        "Importance": "Normal",
        "TransVelMax": "300",
        "Enabled": "true",
    }


@pytest.mark.parametrize(
    ("params", "message"),
    [
        ({"Speed": 1}, "unknown parameter"),
        ({"TransVelMax": "fast"}, "must be an integer"),
        ({"TransVelMax": 5000}, "above its maximum"),
        ({"TransVelMax": -1}, "below its minimum"),
        ({"Enabled": "maybe"}, "true or false"),
        ({"Importance": 'x"y'}, "contains"),
    ],
)
def test_bad_params_are_refused(params: dict[str, object], message: str) -> None:
    with pytest.raises(EditError, match=message):
        edit.add_object(_map(OMRON_LIKE), "Slow", area=(0, 0, 500, 500), name="Mike", params=params)


def test_params_for_a_type_without_argdesc_are_refused() -> None:
    with pytest.raises(EditError, match="declares no parameters"):
        edit.add_goal(_map(OMRON_LIKE), "G", 0, 0, params={"x": 1})


def test_type_args_read_the_real_omron_declarations(shared_dir) -> None:  # type: ignore[no-untyped-def]
    from mapkit.formats.map import load

    m = load(shared_dir / "real" / "omron-ld-showroom-ex4.map")
    names = [a.name for a in type_args(m, "Door")]
    assert names[:2] == ["FirstEnter", "FirstExit"] and "WaitTime" in names
    door = MapObject("Door", 0, 0, 0, name="ChildDoorForEnter101", from_to=(-50, -500, 50, 500))
    assert object_params(m, door)["WaitTime"] == "10"


# -- selection, remove, rename --


def test_select_by_name_index_and_type() -> None:
    m = _map(OMRON_LIKE)
    assert edit.select(m, "alpha") == [0]
    assert edit.select(m, "#3") == [2]
    assert edit.select(m, "goal1", type="Goal") == [2]  # base type matches GoalWithHeading
    with pytest.raises(EditError, match="did you mean 'Alpha'"):
        edit.select(m, "Alpah")
    with pytest.raises(EditError, match="no object #9"):
        edit.select(m, "#9")
    with pytest.raises(EditError, match="is a Slow, not a Goal"):
        edit.select(m, "#1", type="Goal")
    with pytest.raises(EditError, match="by name or #N"):
        edit.select(m, 3)  # type: ignore[arg-type]


def test_remove_drops_params_and_refuses_ambiguity() -> None:
    m = _map(OMRON_LIKE)
    out = edit.remove(m, "Alpha")
    assert [ln[1] for ln in out.info["CairnInfo"] if ln[0] == "Params"] == ['"Zulu"']
    twice = edit.add_goal(m, "alpha", 0, 0, allow_duplicate=True)
    with pytest.raises(EditError, match="2 objects are named 'alpha'"):
        edit.remove(twice, "alpha")
    assert len(edit.remove(twice, "alpha", all_matches=True).objects) == len(m.objects) - 1
    one = edit.remove(twice, "#4")
    assert one.objects == m.objects and dict(one.info) == dict(
        m.info
    )  # Alpha's Params stay: Alpha is still there
    with pytest.raises(EditError, match="at least one"):
        edit.remove(m)


def test_rename_moves_params_and_reports_references() -> None:
    m = _map(OMRON_LIKE)
    out = edit.rename(m, "Alpha", "Yankee")
    assert [ln[1] for ln in out.info["CairnInfo"] if ln[0] == "Params"] == ['"Yankee"', '"Zulu"']
    assert out.objects[0].name == "Yankee"
    with pytest.raises(EditError, match="already exists"):
        edit.rename(m, "Alpha", "zulu")
    with pytest.raises(EditError, match="needs a name"):
        edit.rename(m, "Goal1", "")
    refs = edit.name_references(m, "Goal1")
    assert refs == [("RouteInfo", 0, ("GoalAfter", '"Goal1"'))]
    assert edit.rename(m, "alpha", "ALPHA").info["CairnInfo"][1][1] == '"ALPHA"'


# -- move --


def test_move_point_line_and_area() -> None:
    m = edit.forbid_line(_map(OMRON_LIKE), 0, 0, 1000, 0, name="L")
    m = edit.forbid_area(m, 0, 0, 1000, 500, angle=30, name="A")
    g = edit.move(m, "Goal1", 10, 20).find("Goal1")[0]
    assert (g.x, g.y, g.theta) == (10, 20, 90)
    g = edit.move(m, "Goal1", by=(5, -5), heading=-45).find("Goal1")[0]
    assert (g.x, g.y, g.theta) == (1245, 8147, -45)
    line = edit.move(m, "L", 0, 0).find("L")[0]
    assert line.from_to == (-500, 0, 500, 0) and (line.x, line.y) == (-500, 0)
    area = m.find("A")[0]
    moved = edit.move(m, "A", by=(100, 200)).find("A")[0]
    assert moved.theta == area.theta
    # Stored corners are whole millimetres, so a turned area moves to within 0.71 mm.
    mm = 0.5 * 2**0.5 + 1e-9
    assert np.allclose(np.array(moved.corners()) - np.array(area.corners()), [100, 200], atol=mm)
    turned = edit.move(m, "A", heading=120).find("A")[0]
    before, after = shapely.Polygon(area.corners()), shapely.Polygon(turned.corners())
    assert turned.theta == 120 and turned.from_to is not None
    assert math.isclose(after.area, before.area)  # same size: only the position was rounded
    assert after.centroid.distance(before.centroid) <= mm
    with pytest.raises(EditError, match="has no heading"):
        edit.move(m, "L", heading=3)
    with pytest.raises(EditError, match="not both"):
        edit.move(m, "L", 1, 2, by=(1, 1))
    with pytest.raises(EditError, match="nothing to do"):
        edit.move(m, "L")
    with pytest.raises(EditError, match="both X and Y"):
        edit.move(m, "L", 1)


def test_goal_given_a_heading_by_move_becomes_goal_with_heading() -> None:
    m = edit.add_goal(_map(OMRON_LIKE), "Plain", 0, 0)
    assert m.find("Plain")[0].type == "Goal"
    assert edit.move(m, "Plain", heading=30).find("Plain")[0].type == "GoalWithHeading"
