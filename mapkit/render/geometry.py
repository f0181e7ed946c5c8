"""Geometry helpers for drawing: colours, labels, the data's extent, scale-bar lengths."""

from __future__ import annotations

import math
from collections.abc import Iterable

from mapkit.model import MapData, MapObject

# -- geometry helpers -------------------------------------------------------------------------


def _color(value: str | None, default: str) -> str:
    """``0xRRGGBB`` (ARIA's colour form) as ``#rrggbb``; the default when absent or malformed."""
    if value:
        v = value.strip().lower()
        if v.startswith("0x"):
            v = v[2:]
        if len(v) == 6 and all(c in "0123456789abcdef" for c in v):
            return "#" + v
    return default


def _text(s: str) -> str:
    """A name as text matplotlib can draw: undecodable bytes become U+FFFD."""
    return s.encode("utf-8", "surrogateescape").decode("utf-8", "replace")


def _label(s: str) -> str:
    """A legend label: no mathtext, and not hidden by a leading underscore."""
    s = _text(s).replace("$", r"\$")
    return " " + s if s.startswith("_") else s


def _is_degenerate(obj: MapObject) -> bool:
    if obj.from_to is None:
        return False
    fx, fy, tx, ty = obj.from_to
    return fx == tx and fy == ty


def _finite(obj: MapObject) -> bool:
    vals = [obj.x, obj.y, obj.theta, *(obj.from_to or ())]
    return all(math.isfinite(v) for v in vals)


def _data_extent(
    m: MapData, objects: Iterable[MapObject]
) -> tuple[float, float, float, float] | None:
    """Extent in metres of the scan data and the drawn objects."""
    xs: list[float] = []
    ys: list[float] = []
    for scan in m.scans:
        b = scan.data_bounds()
        if b is not None:
            xs += [b[0][0], b[1][0]]
            ys += [b[0][1], b[1][1]]
    for o in objects:
        for cx, cy in o.corners():
            xs.append(cx)
            ys.append(cy)
    if not xs:
        return None
    return min(xs) / 1000, min(ys) / 1000, max(xs) / 1000, max(ys) / 1000


def _nice(x: float) -> float:
    """The largest 1, 2 or 5 times a power of ten that is at most ``x`` (``x`` > 0)."""
    p = 10.0 ** math.floor(math.log10(x))
    for f in (5.0, 2.0, 1.0):
        if f * p <= x:
            return f * p
    return p


def _scale_label(length: float) -> str:
    if length >= 1:
        return f"{length:g} m"
    return f"{length * 100:g} cm" if length >= 0.01 else f"{length * 1000:g} mm"
