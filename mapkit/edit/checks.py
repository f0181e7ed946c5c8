"""The checks every edit makes on its input, each raising :class:`~mapkit.errors.EditError`.

ARIA's limits (FORMATS.md A.7, A.8, A.11):

* Data rows are read with a 32-bit ``atoi``, and ARIA 2.9.4 and AriaCoda refuse a map whose data
  spans more than 2 km (2,000,000 mm) in x or y. Edits therefore keep every coordinate they write
  within :data:`COORD_LIMIT` = ±2,000,000 mm of the origin (a map centred anywhere inside that
  square can hold the widest data ARIA accepts, every value stays an exact 32-bit integer with a
  thousandfold margin, and float arithmetic on it is exact to far below a millimetre), and refuse
  a result whose data spans more than :data:`SPAN_LIMIT` when the input did not.
* Object fields are written as ``"name"`` with no escape, so a ``"`` or a line break in a name or
  description would corrupt the line (A.6.1); a type is one bare token.
* NaN and infinities crash ARIA (A.11).
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterable
from typing import Any

import numpy as np

from mapkit.errors import EditError
from mapkit.model import MapData, Scan
from mapkit.model.map import missing_rows

__all__ = [
    "COORD_LIMIT",
    "SPAN_LIMIT",
    "check_coord",
    "check_data_range",
    "check_name",
    "check_number",
    "check_span",
    "check_text",
    "check_type_name",
    "missing_rows",
]

#: Largest absolute coordinate (mm) an edit writes.
COORD_LIMIT = 2_000_000
#: Widest data extent (mm) ARIA 2.9.4 and AriaCoda load.
SPAN_LIMIT = 2_000_000

_TYPE_TOKEN = re.compile(r'^[^\s"]+$')


def check_number(value: Any, what: str) -> float:
    """A finite number as float, or :class:`EditError` naming ``what``.

    Examples:
        >>> check_number(3, "x")
        3.0
        >>> check_number(float("nan"), "heading")
        Traceback (most recent call last):
        ...
        mapkit.errors.EditError: heading must be a finite number, got nan
    """
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise EditError(f"{what} must be a number, got {value!r}")
    v = float(value)
    if not math.isfinite(v):
        raise EditError(f"{what} must be a finite number, got {v!r}")
    return v


def check_coord(value: Any, what: str) -> float:
    """A finite coordinate within ±:data:`COORD_LIMIT` mm.

    Examples:
        >>> check_coord(-1500, "x")
        -1500.0
        >>> check_coord(3e6, "y")
        Traceback (most recent call last):
        ...
        mapkit.errors.EditError: y = 3000000 mm is outside ARIA's range (±2000000 mm)
    """
    v = check_number(value, what)
    if abs(v) > COORD_LIMIT:
        raise EditError(f"{what} = {v:.0f} mm is outside ARIA's range (±{COORD_LIMIT} mm)")
    return v


def check_coords(values: Iterable[Any], what: str) -> tuple[float, ...]:
    """Several coordinates (see :func:`check_coord`)."""
    return tuple(check_coord(v, f"{what}[{i}]") for i, v in enumerate(values))


def check_data_range(arr: np.ndarray[Any, Any], what: str) -> None:
    """Every value of an integer data array within ±:data:`COORD_LIMIT` (vectorised)."""
    if arr.size and int(np.abs(arr).max()) > COORD_LIMIT:
        bad = int(np.abs(arr).max())
        raise EditError(
            f"{what}: a coordinate of {bad} mm is outside ARIA's range (±{COORD_LIMIT} mm)"
        )


def _span(scan: Scan) -> int:
    b = scan.data_bounds()
    if b is None:
        return 0
    return max(b[1][0] - b[0][0], b[1][1] - b[0][1])


def check_span(before: MapData, after: MapData) -> None:
    """Refuse a result whose data spans more than 2 km when the input's did not (ARIA would)."""
    old = {s.name.lower(): _span(s) for s in before.scans}
    for s in after.scans:
        span = _span(s)
        if span > SPAN_LIMIT and old.get(s.name.lower(), 0) <= SPAN_LIMIT:
            label = f"source {s.name!r}" if s.name else "the map"
            raise EditError(
                f"the edit would make {label}'s data span {span} mm, more than the 2 km "
                f"({SPAN_LIMIT} mm) ARIA 2.9.4 and AriaCoda load"
            )


def check_text(value: Any, what: str) -> str:
    """A name or description ARIA can store: a str with no ``"`` and no line break.

    Examples:
        >>> check_text('say "hi"', "name")  # doctest: +ELLIPSIS
        Traceback (most recent call last):
        ...
        mapkit.errors.EditError: name 'say "hi"' contains '"': ARIA has no escape for it...
    """
    if not isinstance(value, str):
        raise EditError(f"{what} must be text, got {value!r}")
    if '"' in value:
        raise EditError(
            f"{what} {value!r} contains '\"': ARIA has no escape for it in a quoted field"
        )
    if "\n" in value or "\r" in value or "\0" in value:
        raise EditError(
            f"{what} {value!r} contains a line break or NUL: it would break the map line"
        )
    return value


def check_name(value: Any, what: str = "name") -> str:
    """An object name (see :func:`check_text`)."""
    return check_text(value, what)


def check_type_name(value: Any) -> str:
    """An object type: one token without spaces or quotes.

    Examples:
        >>> check_type_name("Sim.BoxObstacle")
        'Sim.BoxObstacle'
        >>> check_type_name("Forbidden Area")  # doctest: +ELLIPSIS
        Traceback (most recent call last):
        ...
        mapkit.errors.EditError: object type 'Forbidden Area' must be one word without spaces...
    """
    if not isinstance(value, str) or not _TYPE_TOKEN.match(value):
        raise EditError(f"object type {value!r} must be one word without spaces or quotes")
    return value
