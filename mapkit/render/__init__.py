"""Pictures of maps: PNG, SVG and PDF drawn with matplotlib.

:func:`render` draws a map the way a person wants to look at it: the scan points as one density
image (fast for millions of points), the LINES as one line collection, goals with their names and
heading arrows, the home and docks, forbidden areas hatched and rotated by ARIA's rule (about the
map origin, see :meth:`~mapkit.model.MapObject.corners`), forbidden lines, sectors and boundaries
of declared types in their declared colours, a grid and a scale bar in metres and a legend.
:func:`make_figure` gives the matplotlib figure itself, for notebooks and tests.

matplotlib is imported inside the functions (with the Agg canvas, no pyplot) unless a window is
asked for with ``show=True``.

Examples:
    >>> import tempfile, pathlib
    >>> from mapkit.model import MapData, MapObject, Scan
    >>> m = MapData(scans=(Scan.from_arrays([[0, 0], [4000, 3000]], [[0, 0, 4000, 0]]),),
    ...             objects=(MapObject("Goal", 2000, 1500, name="Desk"),))
    >>> out = pathlib.Path(tempfile.mkdtemp()) / "tiny.png"
    >>> r = render(m, out, width=400)
    >>> r.format, r.width, out.read_bytes()[:4] == b"\\x89PNG"
    ('png', 400, True)
"""

from __future__ import annotations

from mapkit.render.base import (
    FORMATS,
    MAX_PIXELS as MAX_PIXELS,
    MIN_PIXELS as MIN_PIXELS,
    RenderError,
    Rendering,
)
from mapkit.render.figure import (
    make_figure,
)
from mapkit.render.kinds import (
    COLORS as COLORS,
    object_kind,
    type_params,
)
from mapkit.render.output import (
    render,
)

__all__ = [
    "FORMATS",
    "RenderError",
    "Rendering",
    "make_figure",
    "object_kind",
    "render",
    "type_params",
]
