"""What a rendering is: output formats, size limits, the result and the error."""

from __future__ import annotations

from dataclasses import dataclass

from mapkit.errors import MapkitError

__all__ = ["FORMATS", "MAX_PIXELS", "MIN_PIXELS", "RenderError", "Rendering"]


#: Output formats by file suffix.
FORMATS = {".png": "png", ".svg": "svg", ".pdf": "pdf"}

#: Largest picture side in pixels (a 20000 x 20000 RGBA image is 1.6 GB in memory).
MAX_PIXELS = 20000
#: Smallest picture side in pixels.
MIN_PIXELS = 32
#: Narrower pictures get no legend (it would leave too little room for the map).
_LEGEND_MIN_WIDTH = 560


class RenderError(MapkitError, ValueError):
    """A picture could not be made: bad size, no window to show it in, ..."""


@dataclass(frozen=True, slots=True)
class Rendering:
    """What :func:`render` made.

    Attributes:
        path: The file written, or ``None`` when only shown.
        format: ``"png"``, ``"svg"`` or ``"pdf"`` (``None`` when only shown).
        width: Picture width in pixels (PNG pixels; SVG/PDF are ``width * 72 / dpi`` points).
        height: Picture height in pixels.
        dpi: Dots per inch the sizes were computed with.
        view: The part of the map shown, ``(xmin, ymin, xmax, ymax)`` in metres.
        metres_per_pixel: Scale of the map area.
        names_hidden: Names left out because they would have overlapped others.
    """

    path: str | None
    format: str | None
    width: int
    height: int
    dpi: float
    view: tuple[float, float, float, float]
    metres_per_pixel: float
    names_hidden: int = 0
