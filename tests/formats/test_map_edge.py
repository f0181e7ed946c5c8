"""Crafted inputs: ARIA's documented behaviour (FORMATS.md part D) and every reader error path."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

import mapkit
from mapkit import IssueCode, MapFormatError
from mapkit.formats.map import tokenize, written_category


def codes(text: bytes) -> list[int]:
    return [int(i.code) for i in mapkit.recover(text)[1]]


def test_t5_last_row_without_newline_is_kept_and_reported() -> None:
    text = b"2D-Map\nNumPoints: 3\nDATA\n1 1\n2 2\n3 3"
    m, issues = mapkit.recover(text)
    assert m.points.tolist() == [[1, 1], [2, 2], [3, 3]]
    assert [i.code for i in issues] == [IssueCode.LAST_ROW_WITHOUT_NEWLINE]
    assert issues[0].location.line == 6


def test_t6_counts_are_corrected_and_box_widened() -> None:
    m = mapkit.loads(b"2D-Map\nNumPoints: 2\nDATA\n1 1\n2 2\n30 30\n")
    out = mapkit.dumps(m)
    assert "NumPoints: 3\n" in out
    assert "MaxPos: 30 30\n" in out
    assert "MinPos: 0 0\n" in out  # no MinPos in the file: the box starts at the origin
    assert m.scan.header.num_points == 2  # the raw header value is kept for validation


def test_t7_data_rows_follow_arias_scanner() -> None:
    rows = [
        b"1.5 2",
        b"12 34.7",
        b"5 6 7",
        b"-7 -8",
        b"+9 10",
        b"0x10 5",
        b"- 3",
        b" 2 2",
        b"\t3 3",
        b"4\t4",
    ]
    m, issues = mapkit.recover(b"2D-Map\nDATA\n" + b"\n".join(rows) + b"\n")
    assert m.points.tolist() == [[12, 34], [5, 6], [-7, -8], [0, 3], [4, 4]]
    bad_lines = sorted(i.location.line for i in issues if i.code == IssueCode.BAD_DATA_ROW)
    assert bad_lines == [3, 7, 8, 10, 11]


def test_t8_header_only_fails() -> None:
    with pytest.raises(MapFormatError, match="no DATA or LINES section"):
        mapkit.loads(b"2D-Map\nResolution: 20\n")
    m, issues = mapkit.recover(b"2D-Map\nResolution: 20\n")
    assert m.scan.resolution == 20 and issues[0].code == IssueCode.BAD_HEADER_LINE


def test_t9_numpoints_zero_is_accepted() -> None:
    m = mapkit.loads(b"2D-Map\nNumPoints: 0\nMinPos: 5 5\nMaxPos: 9 9\nDATA\n")
    assert m.scan.num_points == 0


@pytest.mark.parametrize(
    ("line", "match"),
    [
        (b"MinPos: 1 2 3", r"bad.map:2: MinPos: expects exactly 2 integers, got 3"),
        (b"MinPos: 1.5 2", r"bad.map:2: MinPos: expects integers, got '1.5'"),
        (b"MaxPos: -0x10 2", r"bad.map:2: MaxPos: expects integers, got '-0x10'"),
        (b"PointsAreSorted: yes", r"bad.map:2: PointsAreSorted: expects true, false, 1 or 0"),
        (b"Resolution: 20 30", r"bad.map:2: Resolution: expects exactly 1 integer"),
        (b"NumPoints: many", r"bad.map:2: NumPoints: expects integers, got 'many'"),
        (b"LineMinPos:", r"bad.map:2: LineMinPos: expects exactly 2 integers, got 0"),
        (b"Display:", r"bad.map:2: Display: expects a label"),
        (b"Sources:", r"bad.map:2: Sources: expects at least one source name"),
        (b"OriginLatLongAlt: 1 2", r"bad.map:2: OriginLatLongAlt: expects 3 numbers"),
        (b"OriginLatLongAlt: a b c", r"bad.map:2: OriginLatLongAlt: expects 3 numbers"),
        (b'Cairn: Goal 1 2 0 "" ICON', r"bad.map:2: Cairn: expects at least 7 fields"),
        (b"Cairn:", r"bad.map:2: Cairn: expects at least 7 fields"),
        (b'_Cairn: Goal x 2 0 "" ICON "a"', r"bad.map:2: _Cairn: expects a number, got 'x'"),
        (
            b'ChildCairn: Goal 1 2 0 "" ICON "a" 1 2 3 four',
            r"bad.map:2: ChildCairn: expects a number, got 'four'",
        ),
        (b'Cairn: Goal 1 2 nan "" ICON "a"', r"bad.map:2: Cairn: 'a' has a NaN coordinate"),
        (b'Cairn: Goal 1 -NaN(x1) 0 "" ICON "a"', r"bad.map:2: Cairn: 'a' has a NaN coordinate"),
        (b"MinPos: +0x10 1", r"bad.map:2: MinPos: expects integers, got '\+0x10'"),
        (b"MinPos: 0x 1", r"bad.map:2: MinPos: expects integers, got '0x'"),
        (b'Cairn: Goal 1_000 2 0 "" ICON "a"', r"bad.map:2: Cairn: expects a number, got '1_000'"),
    ],
)
def test_t10_t11_fatal_header_lines(line: bytes, match: str) -> None:
    text = b"2D-Map\n" + line + b"\nDATA\n1 1\n"
    with pytest.raises(MapFormatError, match=match) as info:
        mapkit.loads(text, source="bad.map")
    assert info.value.line == 2 and info.value.source == "bad.map"
    m, issues = mapkit.recover(text)  # tolerant mode loads the rest and reports the line
    assert m.points.tolist() == [[1, 1]]
    assert issues[0].location.line == 2
    assert issues[0].severity is mapkit.Severity.ERROR


def test_t12_description_override_moves_to_slot_4() -> None:
    m = mapkit.loads(b'2D-Map\nCairn: Goal 1 2 0 "" ICON "N" "my desc"\nDATA\n')
    assert m.objects[0].description == "my desc"
    assert 'Cairn: Goal 1 2 0.000000 "my desc" ICON "N"\n' in mapkit.dumps(m)


@pytest.mark.parametrize(
    ("theta", "expected"), [("270", -90), ("-180", 180), ("540", 180), ("1e2", 100)]
)
def test_t13_theta_normalised(theta: str, expected: float) -> None:
    m = mapkit.loads(f'2D-Map\nCairn: GoalWithHeading 1 2 {theta} "" ICON "a"\nDATA\n')
    assert m.objects[0].theta == expected
    assert m.objects[0].base_type == "Goal"


def test_t14_rounding_half_even() -> None:
    text = (
        '2D-Map\nCairn: Goal 1.5 2.5 0.1234567 "" ICON "g"\n'
        'Cairn: ForbiddenArea 0.4 -0.6 30 "" ICON "f" 10.5 11.5 -3.5 20.49\nDATA\n'
    )
    out = mapkit.dumps(mapkit.loads(text))
    assert 'Cairn: Goal 2 2 0.123457 "" ICON "g"\n' in out
    assert 'Cairn: ForbiddenArea 0 -1 30.000000 "" ICON "f" 10 12 -4 20\n' in out


def test_t15_three_coordinates_is_a_lossy_point_object() -> None:
    m, issues = mapkit.recover(b'2D-Map\nCairn: ForbiddenLine 0 0 0 "" ICON "" 1 2 3\nDATA\n')
    assert m.objects[0].from_to is None and m.objects[0].description == "1"
    assert [i.code for i in issues] == [IssueCode.LOSSY_OBJECT_LINE]


def test_t16_info_lines_normalised() -> None:
    m = mapkit.loads(b'2D-Map\nMapInfo:   GoalType    Name=Goal   "Label=A  B"  \nDATA\n')
    assert m.info["MapInfo"] == (("GoalType", "Name=Goal", '"Label=A  B"'),)
    assert 'MapInfo: GoalType Name=Goal "Label=A  B"\n' in mapkit.dumps(m)


def test_t17_info_order_and_upgrade_to_ex4() -> None:
    keys = [
        "TaskInfo",
        "RouteInfo",
        "CairnInfo",
        "MapInfo",
        "CustomInfo",
        "SchedTaskInfo",
        "SchedInfo",
        "MacroInfo",
        "MetaInfo",
    ]
    text = "2D-Map\n" + "".join(f"{k}: x{i}\n" for i, k in enumerate(keys)) + "DATA\n"
    m = mapkit.loads(text)
    out = mapkit.dumps(m).splitlines()
    assert out[0] == "2D-Map-Ex4" and written_category(m) == "2D-Map-Ex4" and m.category == "2D-Map"
    written = [line.split(":")[0] for line in out if "Info:" in line]
    assert written == [
        "CairnInfo",
        "CustomInfo",
        "MacroInfo",
        "MapInfo",
        "MetaInfo",
        "RouteInfo",
        "SchedInfo",
        "SchedTaskInfo",
        "TaskInfo",
    ]


def test_t18_comment_lines_are_kept_after_objects() -> None:
    m, issues = mapkit.recover(b'2D-Map\n# a comment line\nCairn: Goal 1 2 0 "" ICON "a"\nDATA\n')
    out = mapkit.dumps(m).splitlines()
    assert out.index("# a comment line") > out.index('Cairn: Goal 1 2 0.000000 "" ICON "a"')
    assert issues[0].code == IssueCode.UNKNOWN_LINE and issues[0].location.line == 2


def test_t19_bom_fails_junk_before_intro_loads() -> None:
    with pytest.raises(MapFormatError, match="byte-order mark"):
        mapkit.loads(b"\xef\xbb\xbf2D-Map\nDATA\n")
    m, issues = mapkit.recover(b"hello\n2D-Map\nDATA\n1 1\n")
    assert m.points.tolist() == [[1, 1]] and issues[0].code == IssueCode.JUNK_BEFORE_INTRO


def test_t20_multi_source_layout() -> None:
    text = (
        b'2D-Map-Ex\nSources: SickLaser Sonar\nSonarDisplay: "Sonar data"\nsonarminpos: 100 100\n'
        b"Sonar_LINES\n100 100 200 200\nDATA\n1 1\nsonar_data\n150 150\n"
    )
    m = mapkit.loads(text)
    assert [s.name for s in m.scans] == ["SickLaser", "Sonar"]
    assert m.scans[1].points.tolist() == [[150, 150]] and m.scans[1].display == "Sonar data"
    assert mapkit.dumps(m) == (
        '2D-Map-Ex\nSources: SickLaser Sonar\nDisplay: "SickLaser"\nMinPos: 0 0\nMaxPos: 1 1\n'
        'NumPoints: 1\nPointsAreSorted: false\nResolution: 0\nSonarDisplay: "Sonar data"\n'
        "SonarMinPos: 100 100\nSonarMaxPos: 150 150\nSonarNumPoints: 1\n"
        "SonarPointsAreSorted: false\n"
        "SonarResolution: 0\nSonarLineMinPos: 0 0\nSonarLineMaxPos: 200 200\nSonarNumLines: 1\n"
        "SonarLinesAreSorted: false\nSonar_LINES\n100 100 200 200\nDATA\n1 1\nSonar_DATA\n150 150\n"
    )
    assert mapkit.loads(mapkit.dumpb(m)) == m


def test_single_default_source_ex_is_written_as_2d_map() -> None:
    m = mapkit.loads(b"2D-Map-Ex\nDATA\n1 1\n")
    assert mapkit.dumps(m).startswith("2D-Map\n")


def test_t21_tags_are_case_insensitive_prefixes() -> None:
    m = mapkit.loads(b"2D-Map\nDATA\n1 1\nLINESxyz\n0 0 5 5\ndata\n2 2\n")
    assert m.points.tolist() == [[1, 1], [2, 2]] and m.lines.tolist() == [[0, 0, 5, 5]]


def test_t22_two_km_rule() -> None:
    m, issues = mapkit.recover(b"2D-Map\nMinPos: -5000000 0\nDATA\n1 1\n")
    assert m.scan.min_pos == (1, 1) and m.scan.max_pos == (1, 1)
    assert IssueCode.BOX_RECOMPUTED in [i.code for i in issues]
    wide, issues = mapkit.recover(b"2D-Map\nDATA\n0 0\n3000000 0\n")
    assert wide.scan.num_points == 2  # ARIA 2.9.4 refuses it; mapkit keeps it and says so
    assert [i.code for i in issues].count(IssueCode.BOX_RECOMPUTED) == 2


def test_t23_quote_inside_name_does_not_crash() -> None:
    m, issues = mapkit.recover(b'2D-Map\nCairn: Goal 1 2 0 "" ICON "say "hi" now"\nDATA\n')
    assert m.objects[0].name == 'say "hi' and m.objects[0].description == 'now"'
    assert IssueCode.LOSSY_QUOTE in [i.code for i in issues]


def test_t24_rotated_forbidden_area_corners() -> None:
    m = mapkit.loads(
        b'2D-Map\nCairn: ForbiddenArea 0 0 180 "" ICON "FA3" -21124 1564 6001 7648\nDATA\n'
    )
    xs = [c[0] for c in m.objects[0].corners()]
    ys = [c[1] for c in m.objects[0].corners()]
    assert (round(min(xs)), round(max(xs)), round(min(ys)), round(max(ys))) == (
        -6001,
        21124,
        -7648,
        -1564,
    )


def test_keywords_case_insensitive_and_quoted_keyword() -> None:
    m = mapkit.loads(b'2d-map extra words\nminpos: 0x10 16\n"Cairn:" Goal 1 2 0 "" ICON a\nData\n')
    assert m.category == "2D-Map" and m.scan.header.min_pos == (16, 16)
    assert m.objects[0].name == "a"
    assert 'Cairn: Goal 1 2 0.000000 "" ICON "a"' in mapkit.dumps(m)


def test_crlf_and_cr_inside_header() -> None:
    m, issues = mapkit.recover(
        b'2D-Map\r\nCairn: RobotHome 1 2 0 "" ICON "Ho\rme" 0 0 10 10\r\nDATA\r\n1 1\r\n'
    )
    assert m.objects[0].name == "Home" and m.objects[0].from_to == (0, 0, 10, 10)
    assert m.points.tolist() == [[1, 1]]
    assert [i.code for i in issues] == [IssueCode.CR_IN_HEADER]
    assert b"\r" not in mapkit.dumpb(m)


def test_header_after_data_is_dropped_and_reported() -> None:
    m, issues = mapkit.recover(b'2D-Map\nDATA\n1 1\nCairn: Goal 1 2 0 "" ICON "late"\n')
    assert m.objects == () and issues[0].code == IssueCode.HEADER_LINE_AFTER_DATA
    assert issues[0].location.line == 4


def test_duplicate_key_last_wins() -> None:
    m, issues = mapkit.recover(b"2D-Map\nResolution: 10\nResolution: 20\nDATA\n")
    assert m.scan.resolution == 20 and issues[0].code == IssueCode.DUPLICATE_HEADER_KEY


def test_newer_category_and_missing_intro_fail() -> None:
    with pytest.raises(MapFormatError, match="newer than mapkit supports"):
        mapkit.loads(b"2D-Map-Ex5\nDATA\n")
    with pytest.raises(MapFormatError, match="no intro line"):
        mapkit.loads(b"hello\nworld\n")
    with pytest.raises(MapFormatError, match="the file is empty"):
        mapkit.loads(b"")


def test_undecodable_bytes_survive() -> None:
    raw = b'2D-Map\nCairn: Goal 1 2 0.000000 "" ICON "caf\xe9 \xea\xb0\x80"\nDATA\n'
    m = mapkit.loads(raw)
    assert mapkit.dumpb(m).endswith(b'"caf\xe9 \xea\xb0\x80"\nDATA\n')


def test_inactive_and_child_sections_round_trip() -> None:
    text = (
        b'2D-Map-Ex4\n_MapInfo: GoalType Name=X\n_Cairn: Goal 1 2 0 "" ICON "off"\n'
        b'ChildCairn: Goal 3 4 0 "" ICON "kid"\nFoo: bar\nDATA\n'
    )
    m = mapkit.loads(text)
    assert m.inactive_info == {"MapInfo": (("GoalType", "Name=X"),)}
    assert m.inactive_objects[0].name == "off" and m.child_objects[0].name == "kid"
    assert mapkit.dumps(m) == (
        "2D-Map-Ex4\nResolution: 0\n_MapInfo: GoalType Name=X\n"
        '_Cairn: Goal 1 2 0.000000 "" ICON "off"\n'
        'ChildCairn: Goal 3 4 0.000000 "" ICON "kid"\nFoo: bar\nDATA\n'
    )


def test_tokenizer_rules() -> None:
    assert tokenize('a  "b c"  d"e f') == ["a", '"b c"', 'd"e', "f"]
    assert tokenize('"unterminated here') == ['"unterminated here']
    assert tokenize("") == []


def test_origin_lla() -> None:
    m = mapkit.loads(b"2D-Map\nOriginLatLongAlt: 42.807191 -71.578661 72\nDATA\n")
    assert m.origin_lla is not None and math.isclose(m.origin_lla[0], 42.807191)
    assert "OriginLatLongAlt: 42.807191 -71.578661 72.000000\n" in mapkit.dumps(m)


def test_load_missing_file_raises_oserror(tmp_path: Path) -> None:
    with pytest.raises(FileNotFoundError):
        mapkit.load(tmp_path / "nope.map")


def test_save_is_atomic_when_writing_fails(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    target = tmp_path / "a.map"
    target.write_bytes(b"old")
    m = mapkit.loads(b"2D-Map\nDATA\n1 1\n")

    def boom(_m: object) -> object:
        yield b"2D-Map\n"
        raise OSError(28, "No space left on device")

    monkeypatch.setattr("mapkit.formats.map.writer.iter_map_chunks", boom)
    with pytest.raises(OSError, match="No space left"):
        mapkit.save(m, target)
    assert target.read_bytes() == b"old"
    assert [p.name for p in tmp_path.iterdir()] == ["a.map"]


def test_save_backup(tmp_path: Path) -> None:
    target = tmp_path / "a.map"
    target.write_bytes(b"old")
    mapkit.save(mapkit.loads(b"2D-Map\nDATA\n"), target, backup=True)
    assert (tmp_path / "a.map.bak").read_bytes() == b"old"
    assert target.read_bytes() == b"2D-Map\nResolution: 0\nDATA\n"
