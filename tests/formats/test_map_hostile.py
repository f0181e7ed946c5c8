"""Hostile and odd .map / .2d input: mapkit's own error or ARIA's reading, in linear time.

The expected bytes below were recorded by running ARIA 2.9.1's own ``ArMap::readFile`` and
``ArMap::writeFile`` (the library of the bundled ArNetworking peer) on each input.
"""

from __future__ import annotations

import pytest

import mapkit
from mapkit.diagnostics import IssueCode
from mapkit.errors import LogFormatError, MapFormatError, MapkitError
from mapkit.formats.laser2d import dumps_log, loads_log, recover_log
from mapkit.validate import validate

C = IssueCode

# name: (input, what ARIA 2.9.1 writes after reading it)
ARIA_REWRITES = {
    "origin_nan_sign": (
        b"2D-Map\nOriginLatLongAlt: -nan NaN(x) -0\nDATA\n1 2\n",
        b"2D-Map\nMinPos: 0 0\nMaxPos: 1 2\nNumPoints: 1\nPointsAreSorted: false\nResolution: 0\n"
        b"OriginLatLongAlt: -nan nan -0.000000\nDATA\n1 2\n",
    ),
    "unknown_keywords": (
        b'2D-Map\n2D-Map-Ex2\nFoo:\n"quoted kw" x\n  "Cairn:" Goal 1 2 3 "" ICON "q"\n'
        b'"unterminated kw\n# comment  with   spaces \nDATA\n1 2\n',
        b"2D-Map\nMinPos: 0 0\nMaxPos: 1 2\nNumPoints: 1\nPointsAreSorted: false\nResolution: 0\n"
        b'Cairn: Goal 1 2 3.000000 "" ICON "q"\n2D-Map-Ex2\nFoo:\nquoted kw" x\nunterminated kw\n'
        b"# comment with spaces\nDATA\n1 2\n",
    ),
    "cairn_inf_hex": (
        b'2D-Map\nCairn: Goal INF -INF 0x10 "" ICON "a"\n'
        b'Cairn: ForbiddenArea 0 0 0 "" ICON "b" INF 0x10 -inf 1e400\nDATA\n1 2\n',
        b"2D-Map\nMinPos: 0 0\nMaxPos: 1 2\nNumPoints: 1\nPointsAreSorted: false\nResolution: 0\n"
        b'Cairn: Goal inf -inf 16.000000 "" ICON "a"\n'
        b'Cairn: ForbiddenArea 0 0 0.000000 "" ICON "b" inf 16 -inf inf\nDATA\n1 2\n',
    ),
    "cairn_strtod": (
        b'2D-Map\nCairn: Goal 1e400 -1e400 1e-400 "" ICON "a"\n'
        b'Cairn: Goal 0x1.8p1 .5 -0X10 "" ICON "b"\nDATA\n1 2\n',
        b"2D-Map\nMinPos: 0 0\nMaxPos: 1 2\nNumPoints: 1\nPointsAreSorted: false\nResolution: 0\n"
        b'Cairn: Goal inf -inf 0.000000 "" ICON "a"\nCairn: Goal 3 0 -16.000000 "" ICON "b"\n'
        b"DATA\n1 2\n",
    ),
    "header_ints": (
        b"2D-Map\nMinPos: 0x-10 99999999999999999999999\nMaxPos: 0x0x10 +5\nDATA\n1 2\n",
        b"2D-Map\nMinPos: -16 -1\nMaxPos: 16 5\nNumPoints: 1\nPointsAreSorted: false\n"
        b"Resolution: 0\nDATA\n1 2\n",
    ),
    "header_wrap": (
        b"2D-Map\nMinPos: 4294967297 -99999999999999999999999\nNumPoints: 0x1\nDATA\n1 2\n",
        b"2D-Map\nMinPos: 1 0\nMaxPos: 1 2\nNumPoints: 1\nPointsAreSorted: false\nResolution: 0\n"
        b"DATA\n1 2\n",
    ),
    "origin_strtod": (
        b"2D-Map\nOriginLatLongAlt: INF 0x1p4 1e400\nDATA\n1 2\n",
        b"2D-Map\nMinPos: 0 0\nMaxPos: 1 2\nNumPoints: 1\nPointsAreSorted: false\nResolution: 0\n"
        b"OriginLatLongAlt: inf 16.000000 inf\nDATA\n1 2\n",
    ),
    "origin_words": (
        b"2D-Map\nOriginLatLongAlt: infinity -Infinity 0x.8\nDATA\n1 2\n",
        b"2D-Map\nMinPos: 0 0\nMaxPos: 1 2\nNumPoints: 1\nPointsAreSorted: false\nResolution: 0\n"
        b"OriginLatLongAlt: inf -inf 0.500000\nDATA\n1 2\n",
    ),
    "flags_case": (
        b"2D-Map\nPointsAreSorted: TRUE\nLinesAreSorted: 0\nResolution: 0x14\nDATA\n1 2\n",
        b"2D-Map\nMinPos: 0 0\nMaxPos: 1 2\nNumPoints: 1\nPointsAreSorted: true\nResolution: 20\n"
        b"DATA\n1 2\n",
    ),
    "sources_bytes": (
        b"2D-Map-Ex\nSources: \xff\xfe Abc\n\xff\xfeMinPos: 1 1\n\xff\xfe_DATA\n1 1\nabc_DATA\n"
        b"2 2\n",
        b'2D-Map-Ex\nSources: \xff\xfe Abc\n\xff\xfeDisplay: "\xff\xfe"\n\xff\xfeMinPos: 1 1\n'
        b"\xff\xfeMaxPos: 1 1\n\xff\xfeNumPoints: 1\n\xff\xfePointsAreSorted: false\n"
        b'\xff\xfeResolution: 0\nAbcDisplay: "Abc"\nAbcMinPos: 0 0\nAbcMaxPos: 2 2\n'
        b"AbcNumPoints: 1\nAbcPointsAreSorted: false\nAbcResolution: 0\n\xff\xfe_DATA\n1 1\n"
        b"Abc_DATA\n2 2\n",
    ),
    "long_source": (
        b"2D-Map-Ex\n"
        b"Sources: SickLaser SSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSS"
        b"SSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSS\n"
        b"SSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSMinPos: 1 1\n"
        b"SSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSS_DATA\n3 3\nDATA\n"
        b"4 4\n",
        b"2D-Map-Ex\n"
        b"Sources: SickLaser SSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSS"
        b"SSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSS\n"
        b'Display: "SickLaser"\nMinPos: 0 0\nMaxPos: 4 4\nNumPoints: 1\nPointsAreSorted: false\n'
        b"Resolution: 0\n"
        b"SSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSS"
        b'SSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSDisplay: "'
        b'SSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSS"\n'
        b"SSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSMinPos: 1 1\n"
        b"SSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSMaxPos: 3 3\n"
        b"SSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSNumPoints: 1\n"
        b"SSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSS"
        b"SSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSPointsAreSorted: false\n"
        b"SSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSResolution: 0\n"
        b"DATA\n4 4\nSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSSS_DATA\n"
        b"3 3\n",
    ),
    "unicode_keyword": (
        b"2D-Map\nTas\xe2\x84\xaaInfo: x\nTaskInfo: y\nDATA\n1 2\n",
        b"2D-Map\nMinPos: 0 0\nMaxPos: 1 2\nNumPoints: 1\nPointsAreSorted: false\nResolution: 0\n"
        b"TaskInfo: y\nTas\xe2\x84\xaaInfo: x\nDATA\n1 2\n",
    ),
}


@pytest.mark.parametrize("name", sorted(ARIA_REWRITES))
def test_rewrite_is_byte_exact_with_aria(name: str) -> None:
    """Unknown and quoted keywords, strtod/strtol numbers, any source name: as ARIA writes them."""
    data, aria = ARIA_REWRITES[name]
    m, _issues = mapkit.recover(data)
    assert mapkit.dumpb(m) == aria
    assert mapkit.dumpb(mapkit.loads(data)) == aria  # ARIA loads them all: so does strict mode


def test_unknown_keyword_without_arguments_has_no_trailing_space() -> None:
    m = mapkit.loads(b"2D-Map\n2D-Map-Ex2\n  Foo:   \nDATA\n")
    assert m.remainder == ("2D-Map-Ex2", "Foo:")
    assert b"\n2D-Map-Ex2\nFoo:\nDATA\n" in mapkit.dumpb(m)


def test_quoted_keyword_loses_only_its_opening_quote() -> None:
    m = mapkit.loads(b'2D-Map\n"quoted kw" x\n"Cairn:" Goal 1 2 0 "" ICON "g"\nDATA\n')
    assert m.remainder == ('quoted kw" x',)
    assert [o.name for o in m.objects] == ["g"]


def test_cairn_inf_and_hex_are_kept_and_warned() -> None:
    text = (
        b'2D-Map\nCairn: Goal INF -INF 0x10 "" ICON "far"\nCairn: Goal 1 2 0 "" ICON "near"\n'
        b"DATA\n1 1\n"
    )
    m = mapkit.loads(text)
    far = m.objects[0]
    assert (far.x, far.y, far.theta) == (float("inf"), float("-inf"), 16.0)
    assert b'Cairn: Goal inf -inf 16.000000 "" ICON "far"\n' in mapkit.dumpb(m)
    found = [i for i in validate(m, navigation=False).issues if i.code is C.INFINITE_OBJECT]
    assert [i.location.object for i in found] == ["far"]


@pytest.mark.parametrize("size", [12_500, 40_000])
def test_long_header_lines_are_kept_whole_and_reported(size: int) -> None:
    info = "MapInfo: " + " ".join(f"k{i}=v" for i in range(size // 6))
    unknown = "Foo " + "y" * size
    quoted = 'CustomInfo: "' + "z " * (size // 2) + '"'
    data = f"2D-Map\n{info}\n{unknown}\n{quoted}\nDATA\n1 1\n".encode()
    m, issues = mapkit.recover(data)
    assert len(m.info["MapInfo"][0]) == size // 6  # nothing cut at 511 arguments
    assert m.remainder == (unknown,)
    assert m.info["CustomInfo"][0] == (quoted.split(" ", 1)[1],)
    text = mapkit.dumpb(m)
    for line in (info, unknown, quoted):
        assert ("\n" + line + "\n").encode() in text
    long = [i for i in issues if i.code is C.TOO_MANY_TOKENS]
    assert [i.location.line for i in long] == [2, 3, 4]
    assert all("ARIA will split or cut it" in i.message for i in long)
    assert "12,000" in long[1].message or "11,999" in long[1].message


def test_511_arguments_and_9999_bytes_are_the_limits() -> None:
    # Checked with ARIA 2.9.1: a known keyword keeps 511 arguments, an unknown line 511 tokens
    # (its keyword is one of them), and the argument splitter reads 9,999 bytes.
    ok = "MapInfo: " + " ".join(["x"] * 511)
    cut = "MapInfo: " + " ".join(["x"] * 512)
    wide = "MapInfo: " + "w" * 10_000
    unknown_ok = "Foo " + " ".join(["y"] * 510)
    unknown_cut = "Bar " + " ".join(["y"] * 511)
    data = f"2D-Map\n{ok}\n{cut}\n{wide}\n{unknown_ok}\n{unknown_cut}\nDATA\n".encode()
    _m, issues = mapkit.recover(data)
    long = [i for i in issues if i.code is C.TOO_MANY_TOKENS]
    assert [i.location.line for i in long] == [3, 4, 6]
    assert "512 arguments" in long[0].message and "10,000 bytes" in long[1].message
    assert "512 arguments" in long[2].message


DIGITS = "9" * 50_000


@pytest.mark.parametrize(
    "line",
    [
        f"MinPos: {DIGITS} -{DIGITS}",
        f"MaxPos: 0x{DIGITS} 1",
        f"NumPoints: {DIGITS}",
        f"Resolution: -{DIGITS}",
        f"LineMinPos: {DIGITS} 0",
        f"LineMaxPos: 0 {DIGITS}",
        f"NumLines: {DIGITS}",
    ],
)
def test_header_integers_with_thousands_of_digits(line: str) -> None:
    data = f"2D-Map\n{line}\nDATA\n1 1\n".encode()
    m = mapkit.loads(data)  # strtol saturates, ARIA's int keeps -1 or 0
    _m, issues = mapkit.recover(data)
    assert C.NUMBER_OUT_OF_RANGE in [i.code for i in issues]
    h = m.scan.header
    values = [v for v in (h.min_pos, h.max_pos, h.line_min_pos, h.line_max_pos) if v is not None]
    values += [v for v in (h.num_points, h.num_lines, h.resolution) if v is not None]
    assert values and all(v in (-1, 0, 1) or isinstance(v, tuple) for v in values)
    assert all(-(2**31) <= x < 2**31 for v in values for x in (v if isinstance(v, tuple) else (v,)))


@pytest.mark.parametrize("digits", [50_000, 500_000])
def test_object_and_origin_numbers_with_many_digits_in_linear_time(digits: int) -> None:
    # 50,000 digits took 44 s through a backtracking regex; 500,000 would take over an hour.
    d = "9" * digits
    text = (
        f"2D-Map\nOriginLatLongAlt: {d} 0.{d} 1e-{d}\n"
        f'Cairn: Goal {d} -{d}.5 1e{d} "" ICON "g"\n'
        f'Cairn: ForbiddenArea 0 0 0 "" ICON "a" 0x{d} {d} 0 1\n'
        f"DATA\n{d} 1\n1 -{d}\n"
    ).encode()
    m = mapkit.loads(text)
    assert m.origin_lla == (float("inf"), 1.0, 0.0)
    assert (m.objects[0].x, m.objects[0].y, m.objects[0].theta) == (
        float("inf"),
        float("-inf"),
        float("inf"),
    )
    # atoi's strtol saturates (and the rows, wider than 2 km, are sorted as ARIA 2.9.4 does)
    assert sorted(m.points.tolist()) == [[1, -(2**63)], [2**63 - 1, 1]]
    bad = f'2D-Map\nCairn: Goal 1{d}x 1 0 "" ICON "g"\nOriginLatLongAlt: {d} 1{d}x 1\nDATA\n'
    with pytest.raises(MapFormatError, match=r"^<string>:2: Cairn: expects a number, got '1999"):
        mapkit.loads(bad)
    m, issues = mapkit.recover(bad.encode())
    assert [(i.code, i.location.line) for i in issues if i.code is not C.TOO_MANY_TOKENS] == [
        (C.BAD_HEADER_LINE, 2),
        (C.BAD_HEADER_LINE, 3),
    ]  # and both lines are longer than ARIA reads
    assert all(len(i.message) < 300 for i in issues)  # the line is named, not copied


def test_info_values_with_many_digits_are_checked_in_linear_time() -> None:
    # ArgDesc and CairnInfo: values were matched by a backtracking regex in validate.
    d = "9" * 50_000
    text = (
        "2D-Map\nMapInfo: GoalType Name=Goal\n"
        f"MapInfo: ArgDesc Name=Speed Parent=Goal Type=double Value={d}x Min=-{d}\n"
        f"MapInfo: ArgDesc Name=N Parent=Goal Type=int Value={d}\n"
        f'CairnInfo: Params "g" {d}x {d}\nCairn: Goal 1 1 0 "" ICON "g"\nDATA\n1 1\n'
    )
    codes = validate(mapkit.loads(text), navigation=False).codes()
    assert int(C.ARGDESC_BAD_VALUE) in codes and int(C.PARAMS_BAD_VALUE) in codes


def test_data_rows_beyond_64_bits_saturate_and_validate_warns() -> None:
    m = mapkit.loads(b"2D-Map\nDATA\n" + b"9" * 30 + b" 1\n-" + b"9" * 5000 + b" 3\n4294967297 3\n")
    assert m.points.tolist() == [[2**63 - 1, 1], [-(2**63), 3], [4294967297, 3]]
    assert C.COORDINATE_OVERFLOW in [i.code for i in validate(m, navigation=False).issues]


def test_sources_with_invalid_utf8_round_trip() -> None:
    data = b"2D-Map-Ex\nSources: \xff\xfe\x80 B\n\xff\xfe\x80_DATA\n1 1\nB_DATA\n2 2\n"
    m = mapkit.loads(data)
    assert [s.num_points for s in m.scans] == [1, 1]
    text = mapkit.dumpb(m)
    assert b"Sources: \xff\xfe\x80 B\n" in text and b"\n\xff\xfe\x80_DATA\n1 1\n" in text
    assert mapkit.dumpb(mapkit.loads(text)) == text


def test_keywords_are_matched_in_ascii_case_only() -> None:
    # The Kelvin sign lower-cases to 'k' in Python but not in C: not TaskInfo: for ARIA.
    m = mapkit.loads("2D-Map\nTas\u212aInfo: x\nDATA\n".encode())
    assert m.info == {} and m.remainder == ("Tas\u212aInfo: x",)


LOG_HEAD = (
    b"LaserOdometryLog\n#Created by ArLaserLogger\nversion: 4\nsick1pose: 0 0 0.00\n"
    b"sick1conf: -90.00 90.00 2\n"
)
LOG_REC = (
    b"logTime: 0.100\nvelocities: 0.00 0.00 0.00\nscanId: 0\nrobot: 1000 0 90.00\n"
    b"robotGlobal: 1000 0 90.00\nscan1: 500 0  0 0 \n"
)
D2 = b"9" * 50_000


@pytest.mark.parametrize(
    ("old", "new"),
    [
        (b"version: 4", b"version: " + D2),
        (b"sick1pose: 0 0 0.00", b"sick1pose: " + D2 + b" 0 0.00"),
        (b"sick1conf: -90.00 90.00 2", b"sick1conf: -90.00 90.00 " + D2),
        (b"sick1conf: -90.00 90.00 2", b"sick1conf: -" + D2 + b".5 90.00 2"),
        (b"scanId: 0", b"scanId: " + D2),
        (b"scanId: 0", b"#scan" + D2),
        (b"logTime: 0.100", b"logTime: " + D2 + b".100"),
        (b"logTime: 0.100", b"logTime: 1e" + D2),
        (b"velocities: 0.00", b"velocities: 1e" + D2),
        (b"robot: 1000 0 90.00", b"robot: " + D2 + b" 0 90.00"),
        (b"robot: 1000 0 90.00", b"robot: 0." + D2 + b" 0 1_0"),
        (b"scan1: 500 0", b"scan1: " + D2 + b" 0"),
        (b"scan1: 500 0", b"scan1: 5." + D2 + b" 0"),
        (b"scan1: 500 0", b"scan1: 5" + D2 + b"x 0"),
        (b"scan1:", b"scan" + D2 + b":"),
        (b"scan1:", b"reflector" + D2 + b": 1 1\nscan1:"),
    ],
)
def test_2d_numbers_with_thousands_of_digits(old: bytes, new: bytes) -> None:
    data = (LOG_HEAD + LOG_REC).replace(old, new, 1)
    assert data != LOG_HEAD + LOG_REC
    try:
        log = loads_log(data)
        dumps_log(log)
    except LogFormatError:
        pass
    log, _issues = recover_log(data)
    dumps_log(log)


@pytest.mark.parametrize("value", [b"1e306", b"-1e300", b"99999999999999999999.5", b"9" * 300])
def test_2d_huge_times_and_values_write_and_read_back(value: bytes) -> None:
    rec = LOG_REC.replace(b"logTime: 0.100", b"logTime: " + value)
    rec = rec.replace(b"robot: 1000 0 90.00", b"robot: 1e308 -1e308 90.00")
    text = dumps_log(loads_log(LOG_HEAD + rec))  # t * 1000 overflowed to inf here
    assert dumps_log(loads_log(text)) == text


def test_2d_velocities_infinite_is_reported_as_such() -> None:
    data = (LOG_HEAD + LOG_REC).replace(b"velocities: 0.00", b"velocities: inf")
    with pytest.raises(LogFormatError, match="velocities: NaN or infinite value"):
        loads_log(data)


def test_2d_hex_and_saturated_values_read_as_strtod() -> None:
    data = (LOG_HEAD + LOG_REC).replace(b"scan1: 500 0", b"scan1: 0x1f4 " + D2[:30])
    scan = loads_log(data).scans[0]
    assert scan.xy.tolist()[0] == [500.0, 1e30]
    text = dumps_log(loads_log(data))
    assert "scan1: 500 1000000000000000019884624838656  0 0 \n" in text  # %.0f of 1e30
    # The same number on a line of plain integers reads the same (no int64 saturation).
    plain = (LOG_HEAD + LOG_REC).replace(b"scan1: 500 0", b"scan1: 500 " + D2[:30])
    assert loads_log(plain).scans[0].xy.tolist()[0] == [500.0, 1e30]


def test_every_error_is_a_mapkit_error() -> None:
    assert issubclass(MapFormatError, MapkitError) and issubclass(LogFormatError, MapkitError)
