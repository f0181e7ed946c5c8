"""The shared number reader against the real C library (glibc's strtod/strtol through ctypes)."""

from __future__ import annotations

import ctypes
import ctypes.util
import math
import time

import pytest
from hypothesis import given, strategies as st

from mapkit.formats._numbers import (
    LONG_MAX,
    LONG_MIN,
    aria_double,
    aria_int,
    atoi,
    c_int,
    strtod,
    strtol,
)


def _libc() -> ctypes.CDLL:
    name = ctypes.util.find_library("c") or "libc.so.6"
    try:
        lib = ctypes.CDLL(name)
    except OSError as err:  # pragma: no cover - every Linux has a C library
        pytest.fail(f"the C library cannot be loaded: {err}")
    lib.strtod.restype = ctypes.c_double
    lib.strtod.argtypes = [ctypes.c_char_p, ctypes.POINTER(ctypes.c_char_p)]
    lib.strtol.restype = ctypes.c_long
    lib.strtol.argtypes = [ctypes.c_char_p, ctypes.POINTER(ctypes.c_char_p), ctypes.c_int]
    return lib


LIBC = _libc()


def c_strtod(s: str) -> tuple[float, int]:
    buf = ctypes.create_string_buffer(s.encode("ascii"))
    end = ctypes.c_char_p()
    v = LIBC.strtod(buf, ctypes.byref(end))
    return v, (ctypes.cast(end, ctypes.c_void_p).value or 0) - ctypes.addressof(buf)


def c_strtol(s: str, base: int) -> tuple[int, int]:
    buf = ctypes.create_string_buffer(s.encode("ascii"))
    end = ctypes.c_char_p()
    v = LIBC.strtol(buf, ctypes.byref(end), base)
    return v, (ctypes.cast(end, ctypes.c_void_p).value or 0) - ctypes.addressof(buf)


def same_double(a: float, b: float) -> bool:
    if math.isnan(a) or math.isnan(b):
        return math.isnan(a) and math.isnan(b)
    return a == b and math.copysign(1.0, a) == math.copysign(1.0, b)


# Text made of what numbers are made of, so most draws are (prefixes of) numbers.
number_text = st.text(alphabet="0123456789.eEpPxX+-infatyINFATY() _\t", max_size=24)
long_digits = st.builds(
    lambda a, n, d, b: a + d * n + b,
    number_text,
    st.integers(300, 1200),
    st.sampled_from("0159f"),
    number_text,
)


@given(st.one_of(number_text, long_digits))
def test_strtod_is_glibcs(s: str) -> None:
    mine, used = strtod(s)
    theirs, their_used = c_strtod(s)
    assert used == their_used
    assert same_double(mine, theirs), (s, mine, theirs)


@given(st.one_of(number_text, long_digits, st.text(max_size=12)))
def test_whole_token_reading_is_glibcs(s: str) -> None:
    from mapkit.formats._numbers import token_double

    if "\x00" in s or not s.isascii():
        return  # a token never holds NUL; non-ASCII is never a number for either
    theirs, their_used = c_strtod(s)
    mine = token_double(s)
    if their_used == len(s) and s:
        assert mine is not None and same_double(mine, theirs), (s, mine, theirs)
    else:
        assert mine is None, (s, mine)


@given(st.one_of(number_text, long_digits), st.sampled_from([10, 16]))
def test_strtol_is_glibcs(s: str, base: int) -> None:
    assert strtol(s, base) == c_strtol(s, base)


@given(st.floats(allow_nan=False), st.sampled_from(["%r", "%.17g", "%a", "%.0f", "%e"]))
def test_strtod_reads_printed_doubles_back(v: float, fmt: str) -> None:
    text = float.hex(v) if fmt == "%a" else fmt % v
    assert same_double(strtod(text)[0], c_strtod(text)[0])


@pytest.mark.parametrize(
    "text",
    [
        "2.4703282292062327e-324",  # just below half the smallest subnormal: 0
        "2.4703282292062328e-324",  # just above: the smallest subnormal
        "1.7976931348623158e308",  # rounds down to the largest double
        "1.7976931348623159e308",  # overflows to inf
        "0x1.fffffffffffff8p1023",  # a hexadecimal tie that overflows
        "9007199254740993" + "0" * 1000 + "1e-1000",  # a tie broken at the 1017th digit
        "9007199254740993" + "0" * 1000 + "e-1000",  # an exact tie: to even
        "0." + "0" * 400 + "1e400",
        "1e-99999999999999999999",
        "0x1.00000000000000000001p-1075",
    ],
)
def test_strtod_rounds_as_glibc_at_the_edges(text: str) -> None:
    assert same_double(strtod(text)[0], c_strtod(text)[0])
    assert strtod(text)[1] == c_strtod(text)[1]


def test_aria_getargint_rules() -> None:
    # Checked with ARIA 2.9.1's own reader: MinPos: 0x-10 9999...; MaxPos: 0x0x10 +5; 0x and
    # +0x10 refused; the long is cast to int.
    assert aria_int("0x-10") == -16
    assert aria_int("0x0x10") == 16
    assert aria_int("+5") == 5
    assert aria_int("0x") is None and aria_int("+0x10") is None and aria_int("-0x10") is None
    assert aria_int("1.5") is None and aria_int("12abc") is None and aria_int("") is None
    assert c_int(aria_int("9" * 23) or 0) == -1  # LONG_MAX as int
    assert c_int(aria_int("-" + "9" * 23) or 0) == 0  # LONG_MIN as int
    assert c_int(4294967297) == 1


def test_aria_getargdouble_and_atoi() -> None:
    assert aria_double("INF") == math.inf and aria_double("-INF") == -math.inf
    assert aria_double("0x10") == 16.0 and aria_double("1e400") == math.inf
    assert aria_double("1_000") is None and aria_double("infinit") is None
    assert aria_double("nan(abc_1)") is not None and aria_double("nan(") is None
    assert atoi("-") == 0 and atoi("-12") == -12
    assert atoi("9" * 50_000) == LONG_MAX and atoi("-" + "9" * 50_000) == LONG_MIN


@pytest.mark.parametrize("digits", [50_000, 500_000])
def test_huge_numbers_are_read_in_linear_time(digits: int) -> None:
    # Python's int() refuses more than 4,300 digits and a backtracking regex takes quadratic
    # time; both readers must simply finish (500,000 digits in well under a second here).
    t0 = time.perf_counter()
    for body in ("9" * digits, "0." + "5" * digits, "1e" + "9" * digits, "0x" + "f" * digits):
        for text in (body, "-" + body, body + "x"):
            strtod(text)
            strtol(text, 10)
            strtol(text, 16)
    elapsed = time.perf_counter() - t0
    print(f"{digits} digits: {elapsed:.3f} s")  # shown with -s; no assertion on wall time
