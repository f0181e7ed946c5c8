"""Data rows of a ``.map`` (``DATA``: 2 integers, ``LINES``: 4) to numpy and back.

ARIA's row rules (FORMATS.md A.8): a row is ``<int><ws+><int>...`` then anything; an int is an
optional ``-`` and decimal digits (a lone ``-`` is 0); no ``+``, hex or decimals; a row that
starts with whitespace or does not fit is skipped silently. Here every row is checked with those
rules; rows that fail are reported by index.
"""

from __future__ import annotations

import re
from typing import Any

import numpy as np

__all__ = ["format_rows", "parse_rows"]

_WS = rb"[ \t\r\x0b\x0c]+"
_INT = rb"(-[0-9]*|[0-9]+)"
_ROW = {
    2: re.compile(rb"^" + _INT + _WS + _INT + rb"[^\n]?", re.M),
    4: re.compile(rb"^" + _INT + _WS + _INT + _WS + _INT + _WS + _INT + rb"[^\n]?", re.M),
}


def _int(tok: bytes) -> int:
    return 0 if tok == b"-" else int(tok)


def parse_rows(seg: bytes, ncols: int) -> tuple[np.ndarray[Any, np.dtype[np.int64]], list[int]]:
    """Parse complete data rows with ARIA's rules.

    Args:
        seg: LF-separated rows, each starting with a digit or ``-``. Every row, the last included,
            ends with LF.
        ncols: 2 for ``DATA`` rows, 4 for ``LINES`` rows.

    Returns:
        ``(values, bad)``: an ``(K, ncols)`` int64 array of the rows ARIA keeps, and the 0-based
        indices (within ``seg``) of the rows it skips.

    Examples:
        >>> v, bad = parse_rows(b"1 2\\n12 34.7\\n1.5 2\\n- 3\\n", 2)
        >>> v.tolist(), bad
        ([[1, 2], [12, 34], [0, 3]], [2])
    """
    pattern = _ROW[ncols]
    lines = seg.split(b"\n")
    if lines and lines[-1] == b"":
        lines.pop()
    out: list[list[int]] = []
    bad: list[int] = []
    for i, line in enumerate(lines):
        m = pattern.match(line + b"\n")
        if m is None:
            bad.append(i)
        else:
            out.append([_int(g) for g in m.groups()])
    values = np.array(out, dtype=np.int64).reshape(-1, ncols)
    return values, bad


def format_rows(values: np.ndarray[Any, Any]) -> bytes:
    """Rows of integers as ARIA writes them: single spaces, one row per line, LF-terminated.

    Examples:
        >>> format_rows(np.array([[1, -2], [30, 4]]))
        b'1 -2\\n30 4\\n'
    """
    if len(values) == 0:
        return b""
    fmt = " ".join(["%d"] * values.shape[1]) + "\n"
    return "".join(fmt % tuple(row) for row in values.tolist()).encode("ascii")
