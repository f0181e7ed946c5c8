"""Hypothesis strategies for the edit tests: small maps with points, lines and objects."""

from __future__ import annotations

import numpy as np
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from mapkit.edit import Region
from mapkit.errors import EditError
from mapkit.model import MapData, MapObject, Scan

SPAN = 20_000  # data within ±20 m keeps examples quick and far from the range limits

coord = st.integers(-SPAN, SPAN)


def points_arrays(max_size: int = 80) -> st.SearchStrategy[np.ndarray]:
    return hnp.arrays(np.int64, st.tuples(st.integers(0, max_size), st.just(2)), elements=coord)


def lines_arrays(max_size: int = 30) -> st.SearchStrategy[np.ndarray]:
    return hnp.arrays(np.int64, st.tuples(st.integers(0, max_size), st.just(4)), elements=coord)


names = st.text(alphabet="abcdefgh XYZ-_1234é", min_size=1, max_size=12).map(str.strip).filter(bool)


@st.composite
def objects(draw: st.DrawFn, max_size: int = 8) -> tuple[MapObject, ...]:
    """Goals, docks, forbidden lines and (turned) areas with integer corners and unique names."""
    n = draw(st.integers(0, max_size))
    used: set[str] = set()
    out = []
    for _ in range(n):
        kind = draw(
            st.sampled_from(["Goal", "GoalWithHeading", "Dock", "ForbiddenLine", "ForbiddenArea"])
        )
        name = draw(names)
        if name.lower() in used:
            name = ""
        if name:
            used.add(name.lower())
        if kind == "ForbiddenLine":
            x1, y1, x2, y2 = draw(
                st.tuples(coord, coord, coord, coord).filter(lambda t: t[:2] != t[2:])
            )
            out.append(MapObject(kind, x1, y1, 0, name=name, from_to=(x1, y1, x2, y2)))
        elif kind == "ForbiddenArea":
            x1, y1, x2, y2 = draw(
                st.tuples(coord, coord, coord, coord).filter(
                    lambda t: t[0] != t[2] and t[1] != t[3]
                )
            )
            theta = draw(st.sampled_from([0, 90, 180, -90, 30, -45.5]))
            out.append(MapObject(kind, 0, 0, theta, name=name, from_to=(x1, y1, x2, y2)))
        else:
            if not name:
                name = f"n{len(out)}"
                used.add(name.lower())
            heading = draw(st.integers(-179, 180)) if kind != "Goal" else 0
            out.append(MapObject(kind, draw(coord), draw(coord), heading, name=name))
    return tuple(out)


@st.composite
def maps(draw: st.DrawFn, sorted_data: bool | None = None) -> MapData:
    """A one-source map with points, lines and objects."""
    pts = draw(points_arrays())
    lns = draw(lines_arrays())
    sort = draw(st.booleans()) if sorted_data is None else sorted_data
    scan = Scan.from_arrays(pts, lns, resolution=20, sort=sort)
    return MapData(scans=(scan,), objects=draw(objects()))


@st.composite
def regions(draw: st.DrawFn) -> Region:
    """A box, or a star-shaped (so simple) polygon of 3 to 8 vertices."""
    if draw(st.booleans()):
        x1, y1 = draw(coord), draw(coord)
        w, h = draw(st.integers(1, SPAN)), draw(st.integers(1, SPAN))
        return Region.box(x1, y1, x1 + w, y1 + h)
    n = draw(st.integers(3, 8))
    cx, cy = draw(coord), draw(coord)
    angles = sorted(draw(st.lists(st.floats(0, 6.2), min_size=n, max_size=n, unique=True)))
    radii = draw(st.lists(st.integers(200, SPAN), min_size=n, max_size=n))
    pts = [
        (round(cx + r * np.cos(a)), round(cy + r * np.sin(a)))
        for a, r in zip(angles, radii, strict=True)
    ]
    try:
        return Region.polygon(pts)
    except EditError:  # degenerate (collinear) draws: fall back to a box
        return Region.box(cx, cy, cx + 1000, cy + 1000)
