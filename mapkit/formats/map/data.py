"""The data section and what the header parser needs to know of it: scan keywords, parallel
spans of rows, ARIA's bounding boxes, the MD5 computed in the background."""

from __future__ import annotations

import hashlib
import re
import threading
from typing import Any

import numpy as np

from mapkit.formats._rows import (
    RowReader,
    column_extremes,
)
from mapkit.formats.map.tokens import _INACTIVE_INFO_LOWER, _INFO_LOWER, _OBJECT_KEYWORDS

_SCAN_KEYS = {
    "minpos:": "MinPos:",
    "maxpos:": "MaxPos:",
    "numpoints:": "NumPoints:",
    "pointsaresorted:": "PointsAreSorted:",
    "resolution:": "Resolution:",
    "lineminpos:": "LineMinPos:",
    "linemaxpos:": "LineMaxPos:",
    "numlines:": "NumLines:",
    "linesaresorted:": "LinesAreSorted:",
    "display:": "Display:",
}

_KNOWN_KEYWORDS = {
    *_OBJECT_KEYWORDS,
    *_INFO_LOWER,
    *_INACTIVE_INFO_LOWER,
    *_SCAN_KEYS,
    "sources:",
    "originlatlongalt:",
}


def _short(text: str, limit: int = 60) -> str:
    """Text for a message, cut to ``limit`` characters (a hostile line can be megabytes)."""
    return text if len(text) <= limit else text[:limit] + f"... ({len(text):,} characters)"


_NONNUMERIC_LINE = re.compile(rb"^(?![0-9-]).*$", re.M)
_BACKGROUND_MD5_BYTES = 1 << 20


class _BackgroundMD5:
    """MD5 of a buffer computed by a thread (hashlib releases the GIL on large buffers)."""

    def __init__(self, data: bytes) -> None:
        self._hash = hashlib.md5()
        self._thread = threading.Thread(target=self._hash.update, args=(data,), daemon=True)
        self._thread.start()

    def hexdigest(self) -> str:
        self._thread.join()
        return self._hash.hexdigest()


def _parse_span(
    reader: RowReader, span: tuple[int, int]
) -> tuple[np.ndarray[Any, Any], tuple[np.ndarray[Any, Any], np.ndarray[Any, Any]]] | None:
    """A worker thread's job: the rows of a canonical chunk and their extremes (or ``None``)."""
    values = reader.fast(*span)
    if values is None or len(values) == 0:
        return None
    return values, column_extremes(values)


def _spans(data: bytes, start: int, end: int, size: int) -> list[tuple[int, int]]:
    """``data[start:end]`` cut into pieces of about ``size`` bytes that end with LF."""
    out = []
    s = start
    while s < end:
        e = end
        if end - s > size:
            cut = data.rfind(b"\n", s, s + size)
            e = data.find(b"\n", s + size, end) + 1 if cut < 0 else cut + 1
            e = e or end
        out.append((s, e))
        s = e
    return out


def _aria_box(
    xy: np.ndarray[Any, Any],
    hmin: tuple[int, int] | None,
    hmax: tuple[int, int] | None,
    count: int | None,
    data_box: tuple[tuple[int, int], tuple[int, int]] | None = None,
) -> tuple[tuple[int, int] | None, tuple[int, int] | None]:
    """ARIA's box: the header box (or the origin) widened by the data; empty if ``NumX: 0``.

    ``data_box`` is the data's own box when already known (``None``: computed here).
    """
    if len(xy) == 0:
        return None, None  # nothing to bound; the writer writes no box then
    lo, hi = data_box or _column_bounds(xy)
    if count is not None and count <= 0:
        return lo, hi
    lo0 = hmin if hmin is not None else (0, 0)
    hi0 = hmax if hmax is not None else (0, 0)
    return (min(lo0[0], lo[0]), min(lo0[1], lo[1])), (max(hi0[0], hi[0]), max(hi0[1], hi[1]))


def _column_bounds(xy: np.ndarray[Any, Any]) -> tuple[tuple[int, int], tuple[int, int]]:
    # Column by column: numpy's min(axis=0) over an (N, 2) array is ten times slower.
    x, y = xy[:, 0], xy[:, 1]
    return (int(x.min()), int(y.min())), (int(x.max()), int(y.max()))
