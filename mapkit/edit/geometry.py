"""Rigid motions of the map plane and how they act on data and objects, exactly.

ARIA stores a rectangle (``ForbiddenArea``, sectors, ``RobotHome`` areas) as two corners in a
frame rotated by its ``theta`` about the map origin (FORMATS.md A.7.3): world corners are
``R(theta) . (x, y)`` for the four corner combinations. So a rigid motion ``w -> R(phi) w + t``
maps such a rectangle to one with ``theta' = theta + phi`` and corners shifted by
``R(-theta') t`` in the rotated frame; no corner is approximated, no bounding box taken.

Rotations by multiples of 90 degrees use exact cosines and sines (0, 1, -1), so integer data
stays exactly integer; other angles round points and segment ends to the nearest millimetre
(ARIA stores integers). Objects keep full float precision in memory (values within 1e-7 mm of a
whole millimetre are snapped to it, so float noise does not pile up); the writer rounds them
(``%.0f``) as ARIA does.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from mapkit.model import MapObject

__all__ = ["Rigid", "is_anchor", "object_centre", "rect_about_centre"]


def _snap(v: float, tol: float = 1e-7) -> float:
    """``v`` rounded to the nearest integer when within ``tol`` of it (float noise of a motion)."""
    r = round(v)
    return float(r) if abs(v - r) < tol else v


def _cos_sin(deg: float) -> tuple[float, float]:
    """cos and sin of an angle in degrees, exact for multiples of 90."""
    q = math.fmod(deg, 360.0)
    if q < 0:
        q += 360.0
    exact = {
        0.0: (1.0, 0.0),
        90.0: (0.0, 1.0),
        180.0: (-1.0, 0.0),
        270.0: (0.0, -1.0),
        360.0: (1.0, 0.0),
    }
    if q in exact:
        return exact[q]
    r = math.radians(deg)
    return math.cos(r), math.sin(r)


def rotate_xy(x: float, y: float, deg: float) -> tuple[float, float]:
    """``R(deg) . (x, y)`` (counter-clockwise), exact for multiples of 90 degrees."""
    c, s = _cos_sin(deg)
    return c * x - s * y + 0.0, s * x + c * y + 0.0


@dataclass(frozen=True)
class Rigid:
    """The motion ``w -> R(angle) . w + (tx, ty)``: angle in degrees counter-clockwise, mm.

    Examples:
        >>> t = Rigid.about(90, (1000, 0)).then(Rigid(0, 5, 5))
        >>> t.apply_xy(2000, 0)
        (1005.0, 1005.0)
        >>> t.inverse().apply_xy(*t.apply_xy(123, -456))
        (123.0, -456.0)
    """

    angle: float = 0.0
    tx: float = 0.0
    ty: float = 0.0

    @classmethod
    def about(cls, angle: float, pivot: tuple[float, float] = (0.0, 0.0)) -> Rigid:
        """A rotation by ``angle`` degrees about ``pivot``."""
        px, py = pivot
        rx, ry = rotate_xy(px, py, angle)
        return cls(angle, px - rx, py - ry)

    @property
    def is_identity(self) -> bool:
        """True when nothing moves."""
        return _cos_sin(self.angle) == (1.0, 0.0) and self.tx == 0 and self.ty == 0

    def then(self, other: Rigid) -> Rigid:
        """This motion followed by ``other``."""
        tx, ty = rotate_xy(self.tx, self.ty, other.angle)
        return Rigid(self.angle + other.angle, tx + other.tx, ty + other.ty)

    def inverse(self) -> Rigid:
        """The motion that undoes this one."""
        tx, ty = rotate_xy(self.tx, self.ty, -self.angle)
        return Rigid(-self.angle, -tx, -ty)

    def apply_xy(self, x: float, y: float) -> tuple[float, float]:
        """Move one point."""
        rx, ry = rotate_xy(x, y, self.angle)
        return rx + self.tx, ry + self.ty

    def apply_array(self, xy: np.ndarray[Any, Any]) -> np.ndarray[Any, np.dtype[np.int64]]:
        """Move ``(N, 2k)`` integer coordinates (x, y pairs per row), rounded to whole mm."""
        c, s = _cos_sin(self.angle)
        a = np.asarray(xy, dtype=np.float64)
        x = a[:, 0::2]
        y = a[:, 1::2]
        out = np.empty_like(a)
        out[:, 0::2] = c * x - s * y + self.tx
        out[:, 1::2] = s * x + c * y + self.ty
        return np.rint(out).astype(np.int64)

    def apply_object(self, obj: MapObject, shape: str) -> MapObject:
        """Move an object of the given shape (``point``, ``line`` or ``rect``); headings follow.

        Zero-size anchor rectangles at the origin (:func:`is_anchor`) are not places and stay.
        """
        if is_anchor(obj) or not obj.is_finite:
            return obj  # an object at infinity (ARIA reads `inf`) has no place to move from
        if shape == "point" or obj.from_to is None:
            x, y = self._xy(obj.x, obj.y)
            return replace(obj, x=x, y=y, theta=_snap(obj.theta + self.angle, 1e-9))
        fx, fy, tx, ty = obj.from_to
        if shape == "line":
            a = self._xy(fx, fy)
            b = self._xy(tx, ty)
            x, y = self._xy(obj.x, obj.y)
            return replace(obj, x=x, y=y, from_to=(a[0], a[1], b[0], b[1]))
        theta = _snap(obj.theta + self.angle, 1e-9)
        dx, dy = rotate_xy(self.tx, self.ty, -theta)
        x, y = (obj.x, obj.y) if (obj.x, obj.y) == (0.0, 0.0) else self._xy(obj.x, obj.y)
        return replace(
            obj,
            x=x,
            y=y,
            theta=theta,
            from_to=(_snap(fx + dx), _snap(fy + dy), _snap(tx + dx), _snap(ty + dy)),
        )

    def _xy(self, x: float, y: float) -> tuple[float, float]:
        nx, ny = self.apply_xy(x, y)
        return _snap(nx), _snap(ny)


def is_anchor(obj: MapObject) -> bool:
    """A zero-size rectangle at the origin: an anchor for task lists, not a place.

    Omron maps use them for ``FeedbackHandler`` and ``RobotArrivalHandler`` (FORMATS.md A.7.4).
    """
    return obj.from_to is not None and not any(obj.from_to) and obj.x == 0 and obj.y == 0


def object_centre(obj: MapObject, shape: str) -> tuple[float, float]:
    """Where an object is in the world: its position, a line's midpoint or a rectangle's centre."""
    if shape == "point" or obj.from_to is None:
        return obj.x, obj.y
    fx, fy, tx, ty = obj.from_to
    mx, my = (fx + tx) / 2.0, (fy + ty) / 2.0
    if shape == "line":
        return mx, my
    return rotate_xy(mx, my, obj.theta)


def rect_about_centre(
    x1: float, y1: float, x2: float, y2: float, angle: float
) -> tuple[float, float, float, float]:
    """Stored corners for the box ``(x1, y1)-(x2, y2)`` turned by ``angle`` about its own centre.

    ARIA turns a stored rectangle about the map origin; this gives the corners to store so the
    rectangle a person sees is the box they drew, turned in place.

    Examples:
        >>> rect_about_centre(1000, 0, 3000, 1000, 90)
        (-500.0, -2500.0, 1500.0, -1500.0)
        >>> ft = rect_about_centre(1000, 0, 3000, 1000, 90)
        >>> a = MapObject("ForbiddenArea", 0, 0, 90, from_to=ft)
        >>> sorted(tuple(round(v) for v in c) for c in a.corners())
        [(1500, -500), (1500, 1500), (2500, -500), (2500, 1500)]
    """
    cx, cy = (x1 + x2) / 2.0, (y1 + y2) / 2.0
    hw, hh = abs(x2 - x1) / 2.0, abs(y2 - y1) / 2.0
    sx, sy = rotate_xy(cx, cy, -angle)
    return sx - hw, sy - hh, sx + hw, sy + hh
