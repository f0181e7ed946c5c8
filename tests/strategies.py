"""Hypothesis strategies for mapkit's values (maps, objects, scans)."""

from __future__ import annotations

import dataclasses

import numpy as np
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from mapkit.model import INFO_KEYWORDS, MapData, MapObject, Scan

COORD = st.integers(-2_000_000, 2_000_000)
_SAFE = st.characters(blacklist_categories=("Cs", "Cc"), blacklist_characters='"')
#: Text ARIA can carry inside a quoted field (no double quote, no control characters).
field_text = st.text(_SAFE, max_size=20)
#: One token without whitespace or quotes.
word = st.text(
    st.characters(whitelist_categories=("L", "N"), whitelist_characters="._-=|;#"),
    min_size=1,
    max_size=12,
)
theta = st.integers(-179_999_999, 180_000_000).map(lambda k: float(f"{k / 1e6:.6f}"))


@st.composite
def map_objects(draw: st.DrawFn) -> MapObject:
    """Any object ARIA can write and read back unchanged."""
    ft = draw(st.none() | st.tuples(COORD, COORD, COORD, COORD))
    return MapObject(
        type=draw(
            st.sampled_from(
                [
                    "Goal",
                    "GoalWithHeading",
                    "Dock",
                    "RobotHome",
                    "ForbiddenArea",
                    "ForbiddenLine",
                    "Sim.BoxObstacle",
                ]
            )
            | word
        ),
        x=draw(COORD),
        y=draw(COORD),
        theta=draw(theta),
        name=draw(field_text),
        description=draw(field_text),
        icon=draw(st.sampled_from(["ICON", "ID=3"]) | word),
        from_to=ft,
    )


def int_rows(cols: int, max_rows: int = 40) -> st.SearchStrategy[np.ndarray]:
    return hnp.arrays(
        np.int64,
        st.tuples(st.integers(0, max_rows), st.just(cols)),
        elements=st.integers(-1_000_000, 1_000_000),
    )  # within ARIA's 2 km


@st.composite
def scans(draw: st.DrawFn, name: str = "") -> Scan:
    s = Scan.from_arrays(
        draw(int_rows(2)),
        draw(int_rows(4)),
        name=name,
        display=draw(st.just(name) | word),
        resolution=draw(st.integers(0, 100)),
    )
    # The flags are only written (and so only survive) when there is data to flag.
    return dataclasses.replace(
        s,
        points_sorted=bool(s.num_points) and draw(st.booleans()),
        lines_sorted=bool(s.num_lines) and draw(st.booleans()),
    )


info_token = word | field_text.map(lambda t: f'"{t}"')
info_line = st.lists(info_token, max_size=6).map(tuple)


@st.composite
def maps(draw: st.DrawFn) -> MapData:
    """Any map mapkit can write and read back to an equal value (category as ARIA writes it)."""
    n_sources = draw(st.integers(1, 3))
    if n_sources == 1:
        names = [draw(st.sampled_from(["", "SickLaser"]))]
    else:
        names = draw(
            st.lists(
                st.sampled_from(["SickLaser", "Sonar", "Lidar2", "Low"]),
                min_size=n_sources,
                max_size=n_sources,
                unique=True,
            )
        )
    scan_values = tuple(draw(scans(name)) for name in names)
    info = {
        k: draw(st.lists(info_line, max_size=3))
        for k in draw(st.lists(st.sampled_from(INFO_KEYWORDS), max_size=3, unique=True))
    }
    inactive = {
        k: draw(st.lists(info_line, min_size=1, max_size=2))
        for k in draw(st.lists(st.sampled_from(INFO_KEYWORDS), max_size=2, unique=True))
    }
    remainder = draw(
        st.lists(
            st.tuples(word, st.lists(info_token, max_size=3)).map(
                lambda kv: " ".join(["X-" + kv[0] + ":", *kv[1]])
            ),
            max_size=3,
        )
    )  # as ARIA joins them
    lla = draw(
        st.none() | st.tuples(*[st.integers(-90_000_000, 90_000_000).map(lambda v: v / 1e6)] * 3)
    )
    category = draw(
        st.sampled_from(["2D-Map", "2D-Map-Ex", "2D-Map-Ex2", "2D-Map-Ex3", "2D-Map-Ex4"])
    )
    m = MapData(
        category=category,
        scans=scan_values,
        objects=tuple(draw(st.lists(map_objects(), max_size=6))),
        inactive_objects=tuple(draw(st.lists(map_objects(), max_size=2))),
        child_objects=tuple(draw(st.lists(map_objects(), max_size=2))),
        info=info,
        inactive_info=inactive,
        origin_lla=lla,
        remainder=tuple(remainder),
    )
    from mapkit.formats.map import written_category

    return m.replace(category=written_category(m))
