"""The vectorised data-row codec (``mapkit/formats/_rows.py``) against its reference functions.

The fast reader and writer must give exactly what the per-line reference functions give, on any
row text (canonical or not) and any integer array; the map reader must report the same rows and
the same issues (codes, lines, messages) whether its data phase runs vectorised or line by line.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator

import numpy as np
import pytest
from hypothesis import example, given, strategies as st
from hypothesis.extra import numpy as hnp

import mapkit
from mapkit.formats import _rows
from mapkit.formats._rows import (
    RowReader,
    _format_rows_reference,
    _parse_rows_reference,
    format_rows,
    parse_rows,
)
from mapkit.formats.map import parser as map_parser, writer as map_writer
from tests.strategies import maps

INT32 = st.integers(-(2**31), 2**31 - 1)


@contextlib.contextmanager
def small_chunks(threads: bool = True) -> Iterator[None]:
    """Shrink the chunk sizes so small examples cross chunk and split boundaries.

    With ``threads`` the map reader's worker threads parse from the second chunk on; without,
    the data phase runs on the calling thread only.
    """
    names = [
        (_rows, "_PARSE_CHUNK", 48),
        (_rows, "_MIN_SPLIT", 16),
        (_rows, "_FORMAT_CHUNK", 3),
        (map_parser, "_DATA_CHUNK", 40),
        (map_parser, "_PARALLEL_SPANS", 2 if threads else 1 << 40),
    ]
    saved = [getattr(module, name) for module, name, _ in names]
    for module, name, value in names:
        setattr(module, name, value)
    try:
        yield
    finally:
        for (module, name, _), value in zip(names, saved, strict=True):
            setattr(module, name, value)


def same_parse(seg: bytes, ncols: int) -> None:
    got, bad = parse_rows(seg, ncols)
    ref, ref_bad = _parse_rows_reference(seg, ncols)
    assert got.dtype == np.int64
    assert got.shape == ref.shape
    assert np.array_equal(got, ref)
    assert bad == ref_bad


# -- strategies -----------------------------------------------------------------------------


def number(limit: int = 10**9) -> st.SearchStrategy[bytes]:
    return st.integers(-limit, limit).map(lambda v: b"%d" % v)


#: Bytes a messy row may contain (never LF: rows are cut at LF by the caller).
MESSY = st.sampled_from([*b"0123456789", *b"0123456789", *b"-- \t\r\x0b\x0c+./:xX,", 0xC3, 0x00])


@st.composite
def canonical_row(draw: st.DrawFn, ncols: int) -> bytes:
    """What ARIA writes: single spaces, numbers of at most 8 characters (sometimes longer)."""
    limit = draw(st.sampled_from([99, 99_999, 9_999_999, 99_999_999, 10**12]))
    return b" ".join(draw(number(limit)) for _ in range(ncols))


@st.composite
def messy_row(draw: st.DrawFn) -> bytes:
    """Anything that starts with a digit or '-' (the caller splits off every other line)."""
    first = draw(st.sampled_from(list(b"0123456789-")))
    rest = draw(st.lists(MESSY, max_size=24))
    return bytes([first, *rest])


@st.composite
def near_canonical_row(draw: st.DrawFn, ncols: int) -> bytes:
    """A canonical row with one byte replaced, inserted or removed."""
    row = bytearray(draw(canonical_row(ncols)))
    i = draw(st.integers(0, len(row)))
    op = draw(st.sampled_from(["replace", "insert", "delete"]))
    byte = draw(MESSY)
    if op == "insert":
        row.insert(i, byte)
    elif i < len(row):
        if op == "replace":
            row[i] = byte
        else:
            del row[i]
    if not row or row[0] not in b"0123456789-":
        row.insert(0, ord("7"))
    return bytes(row)


@st.composite
def segments(draw: st.DrawFn, ncols: int) -> bytes:
    row = st.one_of(
        canonical_row(ncols), canonical_row(ncols), near_canonical_row(ncols), messy_row()
    )
    rows = draw(st.lists(row, max_size=30))
    eol = draw(st.sampled_from([b"\n", b"\n", b"\r\n"]))
    return b"".join(r + eol for r in rows)


# -- reading --------------------------------------------------------------------------------


@pytest.mark.parametrize("ncols", [2, 4])
@given(data=st.data())
def test_parse_equals_reference(ncols: int, data: st.DataObject) -> None:
    same_parse(data.draw(segments(ncols)), ncols)


@pytest.mark.parametrize("ncols", [2, 4])
@given(data=st.data())
def test_parse_equals_reference_across_chunks(ncols: int, data: st.DataObject) -> None:
    seg = data.draw(segments(ncols))
    with small_chunks():
        same_parse(seg, ncols)


T7_ROWS = b"1.5 2\n12 34.7\n5 6 7\n-7 -8\n+9 10\n0x10 5\n- 3\n4\t4\n"


@pytest.mark.parametrize(
    ("seg", "ncols", "rows", "bad"),
    [
        # FORMATS.md T7 (the rows that start with a digit or '-'; see the map-level test below).
        (T7_ROWS, 2, [[12, 34], [5, 6], [-7, -8], [0, 3], [4, 4]], [0, 4, 5]),
        (b"- -\n-0 0\n007 -08\n", 2, [[0, 0], [0, 0], [7, -8]], []),
        (
            b"--5 1\n5-3 1\n1 --\n1 -.\n1 .5\n1 /5\n-/ 1\n-. 1\n",
            2,
            [[1, 0], [1, 0]],
            [0, 1, 4, 5, 6, 7],
        ),
        (
            b"99999999 -9999999\n-99999999 123456789\n",
            2,
            [[99999999, -9999999], [-99999999, 123456789]],
            [],
        ),
        (b"12345678901234567 -1\n", 2, [[12345678901234567, -1]], []),
        (b"1 2\r\n3 4\r\n", 2, [[1, 2], [3, 4]], []),
        (b"1 2\r\n3 4\n5\r6\n", 2, [[1, 2], [3, 4], [5, 6]], []),
        (b"1  2\n1 2 \n1\x0b2\n1\x0c\t2\n1 \n1\n", 2, [[1, 2], [1, 2], [1, 2], [1, 2]], [4, 5]),
        (
            b"1 2 3 4\n1 2 3\n-1 -2 -3 -4 x\n1 2\t3  4\r\n",
            4,
            [[1, 2, 3, 4], [-1, -2, -3, -4], [1, 2, 3, 4]],
            [1],
        ),
        (b"1 2 3 4\r\n5 6 7 8\r\n", 4, [[1, 2, 3, 4], [5, 6, 7, 8]], []),
    ],
)
def test_crafted_rows(seg: bytes, ncols: int, rows: list[list[int]], bad: list[int]) -> None:
    values, skipped = parse_rows(seg, ncols)
    assert values.tolist() == rows
    assert skipped == bad
    same_parse(seg, ncols)


@pytest.mark.parametrize(
    "text",
    [
        b"1 2\n-3 -4\n",
        b"99999999 -9999999\n0 -0\n",
        b"- 5\n",
        b"1 2\r\n-3 4\r\n",
        b"-1 -22 -333 -4444\n55555 666666 7777777 88888888\n",
    ],
)
def test_canonical_text_takes_the_vectorised_path(text: bytes) -> None:
    ncols = len(text.split(b"\n", 1)[0].split())
    data = b"DATA\n" * 2 + text
    values = RowReader(data).fast(10, len(data), ncols)
    assert values is not None
    assert np.array_equal(values, _parse_rows_reference(text, ncols)[0])


@pytest.mark.parametrize(
    "text",
    [
        b"1 2\n3\n",
        b"1  2\n",
        b"1 2 \n",
        b"1\t2\n",
        b"1 +2\n",
        b"1 2.5\n",
        b"1 2-\n",
        b"1 2x\n",
        b"1 123456789\n",
        b"-12345678 1\n",
        b"1 2\n3 4",
        b"1 2\r\n3 4\n",
        b"1 \xc3\n",
    ],
)
def test_non_canonical_text_is_left_to_the_reference(text: bytes) -> None:
    data = b"DATA\n" * 2 + text
    assert RowReader(data).fast(10, len(data), 2) is None
    same_parse(text if text.endswith(b"\n") else text + b"\n", 2)


def test_a_large_section_reads_like_the_reference() -> None:
    rng = np.random.default_rng(7)
    values = rng.integers(-(2**31), 2**31, size=(60_000, 2))
    values[::7] //= 10**5  # short numbers too
    text = format_rows(values)
    seg = text.replace(b"\n", b"\n1 2.5\n", 3)  # three odd rows in the first chunk
    same_parse(seg, 2)
    got, bad = parse_rows(text, 2)
    assert np.array_equal(got, values) and bad == []


# -- writing --------------------------------------------------------------------------------


def int_arrays(ncols: int, elements: st.SearchStrategy[int]) -> st.SearchStrategy[np.ndarray]:
    return hnp.arrays(np.int64, st.tuples(st.integers(0, 50), st.just(ncols)), elements=elements)


@pytest.mark.parametrize("ncols", [2, 4])
@given(data=st.data())
def test_format_equals_reference(ncols: int, data: st.DataObject) -> None:
    elements = data.draw(
        st.sampled_from([INT32, st.integers(-(2**63), 2**63 - 1), st.integers(-(10**8), 10**8)])
    )
    values = data.draw(int_arrays(ncols, elements))
    assert format_rows(values) == _format_rows_reference(values)
    with small_chunks():
        assert format_rows(values) == _format_rows_reference(values)


@pytest.mark.parametrize("ncols", [2, 4])
@given(data=st.data())
@example(data=None)
def test_format_then_parse_is_identity(ncols: int, data: st.DataObject | None) -> None:
    if data is None:  # the extremes
        values = np.array([[-(2**31), 2**31 - 1, -(10**8), 10**8 - 1][:ncols]] * 3, np.int64)
    else:
        values = data.draw(
            int_arrays(ncols, data.draw(st.sampled_from([INT32, st.integers(-(2**63), 2**63 - 1)])))
        )
    parsed, bad = parse_rows(format_rows(values), ncols)
    assert bad == []
    assert np.array_equal(parsed, values)


@pytest.mark.parametrize(
    ("values", "text"),
    [
        ([[0, -0], [7, -7]], b"0 0\n7 -7\n"),
        ([[99999999, -99999999]], b"99999999 -99999999\n"),
        ([[100000000, -100000000]], b"100000000 -100000000\n"),
        ([[10**4, 10**4 - 1], [-(10**4), -(10**4 - 1)]], b"10000 9999\n-10000 -9999\n"),
        ([[-(2**63), 2**63 - 1, 1, 2]], b"-9223372036854775808 9223372036854775807 1 2\n"),
    ],
)
def test_crafted_format(values: list[list[int]], text: bytes) -> None:
    assert format_rows(np.array(values, np.int64)) == text


def test_format_accepts_read_only_and_strided_arrays() -> None:
    base = np.arange(40, dtype=np.int64).reshape(10, 4) - 20
    view = base[::2, :2]
    view.flags.writeable = False
    assert format_rows(view) == _format_rows_reference(view)
    assert format_rows(np.zeros((0, 2), np.int64)) == b""


# -- the map reader's data phase ------------------------------------------------------------


@contextlib.contextmanager
def line_by_line() -> Iterator[None]:
    """The data phase without the vectorised path and without chunks (the original algorithm)."""
    saved = (RowReader.fast, map_parser._DATA_CHUNK)
    RowReader.fast = lambda self, s, e, k: None  # type: ignore[method-assign]
    map_parser._DATA_CHUNK = 1 << 40
    try:
        yield
    finally:
        RowReader.fast, map_parser._DATA_CHUNK = saved  # type: ignore[method-assign]


def outcome(text: bytes) -> tuple[object, ...]:
    m, issues = mapkit.recover(text)
    return (
        [s.points.tolist() for s in m.scans],
        [s.lines.tolist() for s in m.scans],
        [(i.code, i.severity, i.message, i.location) for i in issues],
        mapkit.dumpb(m),
    )


@st.composite
def data_sections(draw: st.DrawFn) -> bytes:
    header = draw(st.sampled_from([b"2D-Map\n", b"2D-Map-Ex\nSources: A B\n"]))
    tags = [b"DATA", b"LINES", b"data extra", b"LINESxyz", b"A_DATA", b"B_LINES"]
    lines = [draw(st.sampled_from(tags[:2] if header == b"2D-Map\n" else tags))]
    ncols = 2
    for _ in range(draw(st.integers(0, 40))):
        kind = draw(st.integers(0, 9))
        if kind == 0:
            lines.append(draw(st.sampled_from(tags)))
        elif kind == 1:
            odd = [b"", b" 2 2", b"\t3 3", b"MinPos: 1 2", b"\r", b"#x"]
            lines.append(draw(st.sampled_from(odd)))
        else:
            ncols = draw(st.sampled_from([2, 4]))
            row = st.one_of(canonical_row(ncols), near_canonical_row(ncols), messy_row())
            lines.append(draw(row))
    eol = draw(st.sampled_from([b"\n", b"\n", b"\r\n"]))
    body = eol.join(lines)
    if draw(st.booleans()):
        body += eol
    return header + body


@pytest.mark.parametrize("threads", [True, False])
@given(text=data_sections())
@example(text=b"2D-Map\nDATA\n" + T7_ROWS.replace(b"4\t4", b" 2 2\n\t3 3\n4\t4"))
def test_data_phase_equals_line_by_line(threads: bool, text: bytes) -> None:
    with small_chunks(threads):
        fast = outcome(text)
    with line_by_line():
        slow = outcome(text)
    assert fast == slow


def test_t7_kept_rows() -> None:
    text = b"2D-Map\nDATA\n" + T7_ROWS.replace(b"4\t4", b" 2 2\n\t3 3\n4\t4")
    m, issues = mapkit.recover(text)
    assert m.points.tolist() == [[12, 34], [5, 6], [-7, -8], [0, 3], [4, 4]]
    assert sorted(i.location.line for i in issues if i.location) == [3, 7, 8, 10, 11]


def test_large_map_with_odd_rows_between_chunks() -> None:
    rng = np.random.default_rng(3)
    points = rng.integers(-50_000, 50_000, size=(40_000, 2))
    rows = format_rows(points).split(b"\n")
    rows[20_000:20_000] = [b"LINES", b"1 2 3 4", b"5 6 7", b"DATA"]  # mid-file, mid-chunk
    rows[5] = b"1 2.5"
    text = b"2D-Map\nDATA\n" + b"\n".join(rows)
    fast = outcome(text)
    with line_by_line():
        slow = outcome(text)
    assert fast == slow
    m = mapkit.loads(text)
    assert len(m.points) == 40_000 and m.lines.tolist() == [[1, 2, 3, 4]]


# -- the map writer's threads ---------------------------------------------------------------


@given(m=maps())
def test_threaded_writer_and_reader_round_trip(m: mapkit.MapData) -> None:
    sequential = b"".join(map_writer._map_chunks(m, None))
    saved = map_writer._PARALLEL_ROWS
    map_writer._PARALLEL_ROWS = 1
    try:
        with small_chunks(threads=True):
            text = mapkit.dumpb(m)
            back = mapkit.loads(text)
    finally:
        map_writer._PARALLEL_ROWS = saved
    assert text == sequential
    assert back.equals(m)
