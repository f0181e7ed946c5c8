"""What the ``.2d`` reader and writer share: versions, tags and number tokens as ARIA reads them."""

from __future__ import annotations

import re
from typing import Any

import numpy as np

from mapkit.formats._numbers import token_double, token_long

__all__ = ["VERSIONS"]


VERSIONS = (1, 2, 3, 4)

_INTRO = b"LaserOdometryLog"
_END_MARK = "# End of log"
_CREATED = {
    1: None,
    2: "#Created by ARIA's ArSickLogger",
    3: "#Created by ARIA's ArLaserLogger",
    4: "#Created by ArLaserLogger",
}
_INT_CHARS = b"0123456789- \t"
_RECORD_TAGS = {b"scanId:", b"scan1Id:", b"time:", b"logTime:", b"robot:", b"velocities:"}


def _decode(b: bytes) -> str:
    return b.decode("utf-8", "surrogateescape")


# A line of plain decimal numbers (what ARIA's loggers write), which numpy reads exactly as C's
# strtod does; atomic groups keep the match linear whatever the line holds.
_PLAIN_NUMBERS = re.compile(
    rb"[ \t\r\x0b\x0c]*(?>[+-]?(?:[0-9]+(?:\.[0-9]*+)?+|\.[0-9]+)(?:[eE][+-]?[0-9]+)?+"
    rb"(?:[ \t\r\x0b\x0c]++|\Z))*+"
)


_BIG_INT = 10**18


def _numbers(rest: bytes) -> np.ndarray[Any, np.dtype[np.float64]]:
    """Whitespace-separated numbers to float64 (C's ``strtod``, any length in linear time).

    Every value is a double as ``strtod`` reads it (a 30-digit integer is 1e30); ValueError on
    a token that is not a whole number. The result may hold NaN or infinities only when
    :func:`_all_ints` is false.
    """
    if _all_ints(rest):
        ints = np.fromstring(rest, dtype=np.int64, sep=" ")
        if len(ints) == 0 or not ((ints >= _BIG_INT) | (ints <= -_BIG_INT)).any():
            return ints.astype(np.float64)
        # 19 digits or more: int64 may have saturated; strtod reads them as doubles (below).
    if _PLAIN_NUMBERS.fullmatch(rest):
        return np.array(rest.split(), dtype=np.float64)
    return np.array(_small(rest), dtype=np.float64)


def _all_ints(rest: bytes) -> bool:
    """True when ``rest`` is only optionally negative decimal integers separated by blanks."""
    if rest.translate(None, _INT_CHARS):
        return False
    n = rest.count(b"-")
    return n == 0 or (
        n == rest.count(b" -") + rest.count(b"\t-") + rest.startswith(b"-")
        and b"- " not in rest
        and b"-\t" not in rest
        and b"--" not in rest
        and not rest.endswith(b"-")
    )


def _finite(v: np.ndarray[Any, Any]) -> bool:
    return bool(np.isfinite(v).all()) if len(v) else True


def _small(rest: bytes) -> list[float]:
    """A few numbers (a pose line) as floats (C's ``strtod``); ValueError on a bad token."""
    return [_float(t) for t in rest.split()]


def _float(tok: bytes) -> float:
    """One whole token read by C's ``strtod``; ValueError when it is not a number."""
    v = token_double(tok.decode("latin-1"))
    if v is None:
        raise ValueError(f"not a number: {tok[:40]!r}")
    return v


def _int(tok: bytes) -> int:
    """One whole token read by C's ``strtol`` in base 10 (saturating); ValueError otherwise."""
    v = token_long(tok.decode("latin-1"))
    if v is None:
        raise ValueError(f"not an integer: {tok[:40]!r}")
    return v


def _time(tok: bytes) -> float:
    """``S.M`` with M milliseconds (ARIA's unpadded ``%ld.%ld``), else a decimal number."""
    s, dot, m = tok.partition(b".")
    if (
        dot
        and 0 < len(m) <= 3
        and m.isdigit()
        and len(s) <= 16
        and (s.isdigit() or (s[:1] == b"-" and s[1:].isdigit()))
    ):
        # (Longer seconds: milliseconds are below a double's precision; strtod reads them.)
        sec = int(s)
        ms = int(m)
        return (sec * 1000 + (ms if not s.startswith(b"-") else -ms)) / 1000.0
    return _float(tok)
