"""Map objects (``Cairn:`` lines) and the geometry ARIA gives them."""

from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = [
    "BUILTIN_LINE_TYPES",
    "BUILTIN_POINT_TYPES",
    "BUILTIN_RECT_TYPES",
    "MapObject",
    "normalize_theta",
]

#: Types ARIA and its applications know without a ``MapInfo:`` declaration.
BUILTIN_POINT_TYPES = frozenset({"Goal", "GoalWithHeading", "Dock", "RobotHome"})
BUILTIN_LINE_TYPES = frozenset({"ForbiddenLine"})
BUILTIN_RECT_TYPES = frozenset({"ForbiddenArea", "RobotHome"})


def normalize_theta(theta: float) -> float:
    """Normalise an angle in degrees to ARIA's half-open range (-180, 180].

    Examples:
        >>> normalize_theta(270), normalize_theta(-180), normalize_theta(540), normalize_theta(45.5)
        (-90.0, 180.0, 180.0, 45.5)
    """
    if not math.isfinite(theta):
        return theta
    t = math.fmod(theta, 360.0)
    if t > 180.0:
        t -= 360.0
    elif t <= -180.0:
        t += 360.0
    return t + 0.0  # no negative zero


@dataclass(frozen=True, slots=True)
class MapObject:
    """One map object: a goal, home, dock, forbidden line or area, sector, ...

    Coordinates are millimetres and headings degrees, as ARIA stores them. ``from_to`` holds the two
    corners of a rectangle or the two ends of a line (``(x1, y1, x2, y2)``); point objects have
    ``None``. For rectangles the corners are in a frame rotated by ``theta`` about the map origin
    (ARIA's rule, see :meth:`corners`).

    Attributes:
        type: The object type, case preserved (``Goal``, ``ForbiddenArea``, ``Sim.BoxObstacle``).
        x: X in mm.
        y: Y in mm.
        theta: Heading in degrees, normalised to (-180, 180].
        name: The object's name (may be empty, may contain spaces and UTF-8).
        description: Free text, written in the description slot.
        icon: ARIA's icon token (``ICON`` or ``ID=<n>``).
        from_to: ``(from_x, from_y, to_x, to_y)`` for lines and rectangles.

    Examples:
        >>> g = MapObject("GoalWithHeading", 1000, 2000, 90, name="Kitchen")
        >>> g.base_type, g.is_point
        ('Goal', True)
        >>> MapObject("Goal", 0, 0, 450).theta
        90.0
    """

    type: str
    x: float
    y: float
    theta: float = 0.0
    name: str = ""
    description: str = ""
    icon: str = "ICON"
    from_to: tuple[float, float, float, float] | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "theta", normalize_theta(float(self.theta)))
        object.__setattr__(self, "x", float(self.x))
        object.__setattr__(self, "y", float(self.y))
        if self.from_to is not None:
            object.__setattr__(self, "from_to", tuple(float(v) for v in self.from_to))

    @property
    def base_type(self) -> str:
        """The type without a ``WithHeading`` suffix, as ARIA's lookups use it (point objects
        only)."""
        suffix = "WithHeading"
        if self.from_to is None and len(self.type) > len(suffix) and self.type.endswith(suffix):
            return self.type[: -len(suffix)]
        return self.type

    @property
    def is_finite(self) -> bool:
        """True when every coordinate and the heading are finite numbers.

        ARIA reads ``inf`` (and overflowing numbers) in object lines and writes them back; such
        an object has no place in the world, so drawings, checks and edits leave it as it is.
        """
        return all(math.isfinite(v) for v in (self.x, self.y, self.theta, *(self.from_to or ())))

    @property
    def is_point(self) -> bool:
        """True for objects without from/to corners."""
        return self.from_to is None

    def corners(self) -> tuple[tuple[float, float], ...]:
        """World coordinates of a rectangle's four corners (ARIA's rule: rotate about the origin).

        For a line object this gives its two ends (not rotated: ARIA ignores theta for lines only
        by convention, lines are written with theta 0). Point objects give their one position.

        Examples:
            >>> a = MapObject("ForbiddenArea", 0, 0, 180, from_to=(-21124, 1564, 6001, 7648))
            >>> [tuple(round(v) for v in c) for c in a.corners()]
            [(21124, -1564), (-6001, -1564), (-6001, -7648), (21124, -7648)]
        """
        if self.from_to is None:
            return ((self.x, self.y),)
        fx, fy, tx, ty = self.from_to
        t = math.radians(self.theta)
        # An infinite heading (ARIA reads `inf`) rotates to nowhere: NaN corners, as numpy gives.
        c, s = (math.cos(t), math.sin(t)) if math.isfinite(t) else (math.nan, math.nan)
        pts = ((fx, fy), (tx, fy), (tx, ty), (fx, ty))
        return tuple((c * px - s * py + 0.0, s * px + c * py + 0.0) for px, py in pts)
