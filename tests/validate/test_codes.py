"""A crafted map for every finding code: each case asserts the exact code and where it is."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest

import mapkit
from mapkit.diagnostics import IssueCode, Severity
from mapkit.model import MapObject
from mapkit.validate import validate
from tests.validate.maps import CLEAN, LINE, edit, insert_after, write

C = IssueCode
GOAL_A = 'Cairn: Goal 3000 2000 0.000000 "" ICON "A"'


@dataclass
class Case:
    """One crafted map and the finding it must produce."""

    code: IssueCode
    text: str | bytes
    line: int | None = None
    object: str | None = None
    xy: tuple[float, float] | None = None
    in_message: str = ""
    kwargs: dict[str, Any] = field(default_factory=dict)


def goal(line: str) -> str:
    """The clean map with goal A's line replaced."""
    return edit(CLEAN, (GOAL_A, line))


CASES = [
    # 1xx: the tolerant reader's findings come through with their lines.
    Case(C.JUNK_BEFORE_INTRO, "hello\n" + CLEAN, line=1),
    Case(C.UNKNOWN_LINE, insert_after(CLEAN, 10, "Foo: bar"), line=11, in_message="Foo:"),
    Case(C.BAD_DATA_ROW, insert_after(CLEAN, 29, " 5 5"), line=30),
    Case(C.LAST_ROW_WITHOUT_NEWLINE, CLEAN[:-1], line=32),
    Case(C.HEADER_LINE_AFTER_DATA, CLEAN + 'Cairn: Goal 1 1 0 "" ICON "late"\n', line=33),
    Case(
        C.LOSSY_OBJECT_LINE,
        goal('Cairn: Goal 3000 2000 0 "" ICON "A" x y'),
        line=LINE["A"],
        object="A",
    ),
    Case(
        C.NON_FINITE_NUMBER, goal('Cairn: Goal nan 2000 0 "" ICON "A"'), line=LINE["A"], object="A"
    ),
    Case(C.DUPLICATE_HEADER_KEY, insert_after(CLEAN, 6, "Resolution: 20"), line=7),
    Case(
        C.CR_IN_HEADER, edit(CLEAN, ("Resolution: 20", "Resolution: 2\r0")), line=LINE["Resolution"]
    ),
    Case(C.BAD_HEADER_LINE, edit(CLEAN, ("NumPoints: 4", "NumPoints: x")), line=LINE["NumPoints"]),
    Case(C.BAD_SOURCES_LINE, insert_after(CLEAN, 1, "Sources: A a"), line=2),
    Case(C.TOO_MANY_TOKENS, insert_after(CLEAN, 15, "MetaInfo: " + " ".join(["x"] * 600)), line=16),
    Case(C.BOX_RECOMPUTED, edit(CLEAN, ("\nMinPos: 0 0", "\nMinPos: -5000000 0")), line=None),
    Case(C.LOSSY_QUOTE, goal('Cairn: Goal 3000 2000 0 "" ICON "say "hi" now"'), line=LINE["A"]),
    # 2**32 + 20: strtol reads it whole, ARIA's int keeps 20 (and so does mapkit, with a warning).
    Case(
        C.NUMBER_OUT_OF_RANGE,
        edit(CLEAN, ("Resolution: 20", "Resolution: 4294967316")),
        line=LINE["Resolution"],
        in_message="read as 20",
    ),
    # 2xx: header consistency.
    Case(
        C.NUM_POINTS_MISMATCH, edit(CLEAN, ("NumPoints: 4", "NumPoints: 5")), line=LINE["NumPoints"]
    ),
    Case(C.NUM_LINES_MISMATCH, edit(CLEAN, ("NumLines: 4", "NumLines: 3")), line=LINE["NumLines"]),
    Case(
        C.BOX_EXCLUDES_DATA, edit(CLEAN, ("\nMinPos: 0 0", "\nMinPos: 100 0")), line=LINE["MinPos"]
    ),
    Case(
        C.BOX_EXCLUDES_DATA,
        edit(CLEAN, ("LineMaxPos: 6000 4000", "LineMaxPos: 6000 3000")),
        line=LINE["LineMaxPos"],
        in_message="lines",
    ),
    Case(
        C.BOX_LARGER_THAN_DATA,
        edit(CLEAN, ("\nMaxPos: 6000 4000", "\nMaxPos: 9000 4000")),
        line=LINE["MaxPos"],
    ),
    Case(C.BOX_MISSING, edit(CLEAN, ("\nMinPos: 0 0\n", "\n")), line=None, in_message="MinPos:"),
    Case(C.RESOLUTION_MISSING, edit(CLEAN, ("Resolution: 20\n", "")), line=None),
    Case(
        C.RESOLUTION_IMPLAUSIBLE,
        edit(CLEAN, ("Resolution: 20", "Resolution: 5000")),
        line=LINE["Resolution"],
    ),
    Case(
        C.RESOLUTION_IMPLAUSIBLE,
        edit(CLEAN, ("Resolution: 20", "Resolution: 0")),
        line=LINE["Resolution"],
    ),
    Case(
        C.NOT_MARKED_SORTED,
        edit(CLEAN, ("PointsAreSorted: true", "PointsAreSorted: false")),
        line=LINE["PointsAreSorted"],
        in_message="in fact sorted",
    ),
    Case(
        C.SORTED_FLAG_WRONG,
        edit(CLEAN, ("DATA\n0 0\n0 4000\n", "DATA\n0 4000\n0 0\n")),
        line=LINE["PointsAreSorted"],
    ),
    Case(
        C.CATEGORY_OLDER_THAN_CONTENT,
        edit(CLEAN, ("2D-Map-Ex2", "2D-Map")),
        line=1,
        in_message="CairnInfo:",
    ),
    Case(
        C.TEMPLATES_NEED_EX4,
        insert_after(CLEAN, 22, 'ChildCairn: Goal 1 1 0.000000 "" ICON "c"'),
        line=1,
    ),
    Case(C.CATEGORY_NEWER_THAN_ARIA_291, edit(CLEAN, ("2D-Map-Ex2", "2D-Map-Ex4")), line=1),
    Case(C.COUNT_NOT_POSITIVE, edit(CLEAN, ("NumLines: 4", "NumLines: 0")), line=LINE["NumLines"]),
    Case(
        C.MISSPELT_KEYWORD,
        insert_after(CLEAN, 10, "OriginLatLonAlt: 42.8 -71.5 72"),
        line=11,
        in_message="OriginLatLongAlt:",
    ),
    # 3xx: geometry.
    Case(C.EMPTY_MAP, "2D-Map\nDATA\n", line=None),
    Case(
        C.ZERO_LENGTH_LINES,
        edit(
            CLEAN,
            ("NumLines: 4", "NumLines: 5"),
            ("6000 0 6000 4000\n", "6000 0 6000 4000\n6000 10 6000 10\n"),
        ),
        xy=(6000, 10),
    ),
    Case(
        C.POINTS_OFF_GRID,
        edit(CLEAN, ("NumPoints: 4", "NumPoints: 5")) + "6000 4007\n",
        xy=(6000, 4007),
    ),
    Case(
        C.COORDINATE_OVERFLOW,
        edit(
            CLEAN,
            ("NumPoints: 4", "NumPoints: 5"),
            ("\nMaxPos: 6000 4000", "\nMaxPos: 6000 3000000000"),
        )
        + "6000 3000000000\n",
        line=None,
    ),
    # 4xx: objects.
    Case(C.DUPLICATE_NAME, edit(CLEAN, ('ICON "D"', 'ICON "a"')), line=LINE["D"], object="a"),
    Case(
        C.EMPTY_NAME,
        goal('Cairn: Goal 3000 2000 0.000000 "" ICON ""'),
        line=LINE["A"],
        xy=(3000, 2000),
    ),
    Case(
        C.EMPTY_NAME,
        edit(
            CLEAN,
            (
                "MapInfo: SectorType Name=SpeedZone",
                "MapInfo: SectorType Name=SpeedZone NameRequired=1",
            ),
            ('ICON "Zone1"', 'ICON ""'),
            ('Params "Zone1"', 'Params "Zone2"'),
        ),
        line=LINE["Zone1"],
        in_message="NameRequired=1",
    ),
    Case(
        C.UNDECLARED_TYPE,
        goal('Cairn: Charger 3000 2000 0.000000 "" ICON "A"'),
        line=LINE["A"],
        object="Charger",
    ),
    Case(
        C.TYPE_NOT_LISTED,
        edit(CLEAN, ("MapInfo: GoalType Name=Goal", "MapInfo: GoalType Name=Special")),
        line=LINE["A"],
        object="A",
    ),
    Case(
        C.HEADING_NOT_NORMALISED,
        edit(CLEAN, ("GoalWithHeading 5000 3000 90.000000", "GoalWithHeading 5000 3000 450")),
        line=LINE["B"],
        in_message="450",
    ),
    Case(
        C.DEGENERATE_FORBIDDEN,
        edit(CLEAN, ("4000 500 4600 1000", "4000 500 4000 1000")),
        line=LINE["FA"],
        xy=(4000, 750),
    ),
    Case(
        C.DEGENERATE_FORBIDDEN,
        edit(CLEAN, ("2000 3500 2000 3900", "2000 3500 2000 3500")),
        line=LINE["FL"],
        xy=(2000, 3500),
    ),
    Case(
        C.OBJECT_OUTSIDE_MAP,
        goal('Cairn: Goal 30000 2000 0.000000 "" ICON "A"'),
        line=LINE["A"],
        object="A",
        xy=(30000, 2000),
    ),
    Case(
        C.GOAL_IN_WALL,
        goal('Cairn: Goal 0 2000 0.000000 "" ICON "A"'),
        line=LINE["A"],
        object="A",
        xy=(0, 2000),
    ),
    Case(
        C.GOAL_IN_WALL,
        goal('Cairn: Goal 5995 3992 0.000000 "" ICON "A"'),
        line=LINE["A"],
        object="A",
        in_message="occupied cell at (6000, 4000)",
    ),
    Case(
        C.GOAL_NEAR_WALL,
        goal('Cairn: Goal 3000 150 0.000000 "" ICON "A"'),
        line=LINE["A"],
        object="A",
        xy=(3000, 150),
        in_message="150 mm from a wall line",
    ),
    Case(
        C.GOAL_NEAR_WALL,
        goal('Cairn: Goal 2100 3600 0.000000 "" ICON "A"'),
        line=LINE["A"],
        object="A",
        in_message="100 mm from a ForbiddenLine",
    ),
    Case(
        C.GOAL_NEAR_WALL,
        goal('Cairn: Goal 3000 2000 0.000000 "" ICON "A"'),
        line=LINE["A"],
        object="A",
        in_message='Goal "A" at (3000, 2000) is 1414 mm from a ForbiddenArea, closer than '
        "the robot radius (2500 mm)",
        kwargs={"robot_radius": 2500},
    ),
    Case(
        C.GOAL_IN_FORBIDDEN_AREA,
        goal('Cairn: Goal 4300 700 0.000000 "" ICON "A"'),
        line=LINE["A"],
        object="A",
        xy=(4300, 700),
    ),
    Case(
        C.NO_ROBOT_HOME,
        edit(CLEAN, ('Cairn: RobotHome 1000 1000 0.000000 "" ICON "Home"\n', "")),
        line=None,
    ),
    Case(
        C.SEVERAL_ROBOT_HOMES,
        insert_after(CLEAN, 16, 'Cairn: RobotHome 1500 1500 0.000000 "" ICON "H2"'),
        line=17,
        object="H2",
    ),
    Case(
        C.WRONG_SHAPE_FOR_TYPE,
        edit(CLEAN, ('ICON "" 4000 500 4600 1000', 'ICON ""')),
        line=LINE["FA"],
        object="ForbiddenArea",
    ),
    Case(
        C.WRONG_SHAPE_FOR_TYPE,
        goal('Cairn: Goal 3000 2000 0.000000 "" ICON "A" 1 1 2 2'),
        line=LINE["A"],
        object="Goal",
    ),
    # ARIA reads INF (and numbers past the double range) in object lines and writes `inf`.
    Case(C.INFINITE_OBJECT, goal('Cairn: Goal INF 2000 0 "" ICON "A"'), line=LINE["A"], object="A"),
    Case(C.INFINITE_OBJECT, goal('Cairn: Goal 3000 2000 -1e999 "" ICON "A"'), line=LINE["A"]),
    # 6xx: info sections.
    Case(
        C.TYPE_WITHOUT_NAME,
        insert_after(CLEAN, 15, "MapInfo: LocationType Label=Nameless"),
        line=16,
    ),
    Case(
        C.TYPE_DECLARED_TWICE,
        insert_after(CLEAN, 15, "MapInfo: GoalType Name=Goal Label=Again"),
        line=16,
        object="Goal",
    ),
    Case(
        C.ARGDESC_PARENT_MISMATCH,
        edit(CLEAN, ("Parent=SpeedZone", "Parent=Other")),
        line=LINE["ArgDesc"],
        object="MaxSpeed",
    ),
    Case(
        C.ARGDESC_BAD_TYPE,
        edit(CLEAN, ("Type=int", "Type=float")),
        line=LINE["ArgDesc"],
        object="MaxSpeed",
    ),
    Case(
        C.ARGDESC_BAD_VALUE,
        edit(CLEAN, ("Value=300", "Value=fast")),
        line=LINE["ArgDesc"],
        object="MaxSpeed",
    ),
    Case(
        C.ARGDESC_BAD_VALUE,
        edit(CLEAN, ("Value=300", "Value=3000")),
        line=LINE["ArgDesc"],
        object="MaxSpeed",
        in_message="outside",
    ),
    Case(
        C.PARAMS_UNKNOWN_OBJECT,
        edit(CLEAN, ('Params "Zone1"', 'Params "Nobody"')),
        line=LINE["Params"],
        object="Nobody",
    ),
    Case(
        C.PARAMS_COUNT_MISMATCH,
        edit(CLEAN, ('Params "Zone1" 500', 'Params "Zone1" 500 600')),
        line=LINE["Params"],
        object="Zone1",
    ),
    Case(
        C.PARAMS_BAD_VALUE,
        edit(CLEAN, ('Params "Zone1" 500', 'Params "Zone1" fast')),
        line=LINE["Params"],
        object="Zone1",
    ),
    Case(
        C.GROUP_MEMBER_MISMATCH,
        insert_after(CLEAN, 11, 'CairnInfo: GroupMember "Zone1" "SpeedZone" "NoGroup" "X"'),
        line=12,
        object="Zone1",
        in_message="not a declared CairnGroupType",
    ),
]


def _ids(case: Case) -> str:
    return f"MK{int(case.code)}-{case.code.name}"


@pytest.mark.parametrize("case", CASES, ids=_ids)
def test_crafted_file(case: Case, tmp_path: Path) -> None:
    path = write(tmp_path, case.text)
    report = validate(path, navigation=False, **case.kwargs)
    found = [i for i in report.issues if i.code is case.code and case.in_message in i.message]
    assert len(found) == 1, f"expected one {case.code.name}, got: " + "\n".join(
        map(str, report.issues)
    )
    issue = found[0]
    assert issue.severity is mapkit.diagnostics.CODE_SUMMARY[case.code][0]
    assert issue.location.source == str(path)
    assert issue.location.line == case.line
    if case.object is not None:
        assert issue.location.object == case.object
    if case.xy is not None:
        assert issue.location.xy == pytest.approx(case.xy)


def test_clean_map_has_no_findings(tmp_path: Path) -> None:
    assert validate(write(tmp_path, CLEAN)).issues == ()
    assert validate(mapkit.loads(CLEAN)).issues == ()


def test_model_view_non_finite_object() -> None:
    m = mapkit.loads(CLEAN)
    bad = MapObject("Goal", math.nan, 5, name="N")
    report = validate(m.replace(objects=(*m.objects, bad)), navigation=False)
    found = [i for i in report.issues if i.code is C.NON_FINITE_OBJECT]
    assert len(found) == 1 and found[0].location.object == "N" and found[0].location.line is None
    assert found[0].severity is Severity.ERROR


@pytest.mark.parametrize(
    "change, what",
    [
        ({"name": 'say "hi" now'}, "name"),
        ({"description": "two\nlines"}, "description"),
        ({"type": "Two words"}, "type"),
        ({"icon": ""}, "icon"),
    ],
)
def test_model_view_unwritable_text(change: dict[str, str], what: str) -> None:
    m = mapkit.loads(CLEAN)
    bad = MapObject(**{"type": "Goal", "x": 3000, "y": 2500, "name": "Q", **change})  # type: ignore[arg-type]
    report = validate(m.replace(objects=(*m.objects, bad)), navigation=False)
    found = [i for i in report.issues if i.code is C.UNWRITABLE_TEXT]
    assert len(found) == 1, report.issues
    assert what in found[0].message and found[0].location.object == bad.name


def test_model_view_unwritable_info_token() -> None:
    m = mapkit.loads(CLEAN)
    info = dict(m.info)
    info["MetaInfo"] = (("Scan", "two words"),)
    report = validate(m.replace(info=info), navigation=False)
    assert [i.code for i in report.issues] == [C.UNWRITABLE_TEXT]
    assert "MetaInfo: line 1" in report.issues[0].message


def test_every_code_has_a_crafted_case() -> None:
    from tests.validate.test_navigation import NAV_CODES

    covered = {c.code for c in CASES} | {C.NON_FINITE_OBJECT, C.UNWRITABLE_TEXT} | NAV_CODES
    expected = {c for c in IssueCode if int(c) < 700}
    assert expected - covered == set()


def test_misspelt_keyword_replaces_unknown_line(tmp_path: Path) -> None:
    text = insert_after(CLEAN, 10, "OriginLatLonAlt: 42.8 -71.5 72")
    codes = validate(write(tmp_path, text), navigation=False).codes()
    assert codes == [int(C.MISSPELT_KEYWORD)]  # the reader's MK102 for that line is dropped


def test_many_bad_rows_are_summarised(tmp_path: Path) -> None:
    text = CLEAN + "".join(f" {k} {k}\n" for k in range(50))
    report = validate(write(tmp_path, text), navigation=False)
    rows = [i for i in report.issues if i.code is C.BAD_DATA_ROW]
    assert len(rows) == 10
    assert rows[-1].message.startswith("41 more like this (lines 42 .. 82)")
    assert [i.location.line for i in rows[:9]] == list(range(33, 42))


def test_non_finite_objects_are_left_out_of_navigation() -> None:
    m = mapkit.loads(CLEAN)
    bad = MapObject("ForbiddenArea", 0, 0, 0, name="NaN area", from_to=(0, 0, math.nan, 5))
    report = validate(m.replace(objects=(*m.objects, bad)))
    assert report.codes() == [int(C.NON_FINITE_OBJECT)]
    assert report.checked["navigation"]["reachable"] == 3


MULTI = b"""2D-Map-Ex
Sources: SickLaser Sonar
MinPos: 0 0
MaxPos: 20 20
NumPoints: 2
PointsAreSorted: true
Resolution: 20
SonarMinPos: 100 100
SonarMaxPos: 200 200
SonarNumPoints: 3
SonarPointsAreSorted: true
SonarResolution: 20
Sonar_LINES
100 100 200 200
DATA
0 0
20 20
Sonar_DATA
100 100
200 200
"""


def test_named_source_keywords_have_their_lines(tmp_path: Path) -> None:
    report = validate(write(tmp_path, MULTI), navigation=False)
    by_code = {i.code: i for i in report.issues}
    assert by_code[C.NUM_POINTS_MISMATCH].location.line == 10
    assert by_code[C.NUM_POINTS_MISMATCH].message.startswith("SonarNumPoints: 3 but the file has 2")
    missing = by_code[C.BOX_MISSING]
    assert missing.message.startswith("1 line but no SonarLineMinPos: or SonarLineMaxPos: line")
