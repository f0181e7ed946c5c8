"""Properties: checking a map as mapkit writes it equals checking the file it writes.

``validate(map)`` checks the map as :func:`mapkit.save` would write it; ``validate(path)`` checks
the file as ARIA reads it. For any map mapkit can write, both must report the same findings (the
file view adds only the reader's 1xx notes, e.g. MK102 for unknown lines), so a map without
error-level findings stays clean after a save/load round trip.
"""

from __future__ import annotations

from pathlib import Path

from hypothesis import given, settings, strategies as st

import mapkit
from mapkit.diagnostics import Severity
from mapkit.model import MapData, MapObject, Scan
from mapkit.validate import ValidationReport, validate
from tests.strategies import maps
from tests.validate.maps import CLEAN


def findings(report: ValidationReport) -> list[tuple[int, str | None, tuple[float, float] | None]]:
    """The validator's findings (2xx and up) without line numbers, in a stable order."""
    return sorted(
        (
            (int(i.code), i.location.object, i.location.xy)
            for i in report.issues
            if int(i.code) >= 200
        ),
        key=repr,
    )


@settings(max_examples=60)  # the maps() strategy itself is slow to draw
@given(maps())
def test_model_view_equals_file_view(m: MapData) -> None:
    model = validate(m, navigation=False)
    data = mapkit.dumpb(m)
    from_file = validate(data, navigation=False)
    assert findings(model) == findings(from_file)
    # Writing again changes nothing.
    assert findings(validate(mapkit.loads(data), navigation=False)) == findings(model)
    if not model.errors:
        assert not from_file.errors


room_coord = st.integers(-6000, 6000)


@st.composite
def rooms(draw: st.DrawFn) -> MapData:
    """Small maps with walls, a home maybe, goals, docks and forbidden zones (navigation-sized)."""
    walls = draw(
        st.lists(st.tuples(room_coord, room_coord, room_coord, room_coord), min_size=1, max_size=12)
    )
    pts = draw(
        st.lists(
            st.tuples(room_coord, room_coord).map(lambda p: (p[0] // 20 * 20, p[1] // 20 * 20)),
            max_size=30,
        )
    )
    objs = [
        MapObject(
            draw(st.sampled_from(["Goal", "GoalWithHeading", "Dock"])),
            draw(room_coord),
            draw(room_coord),
            draw(st.integers(-179, 180)),
            name=f"G{k}",
        )
        for k in range(draw(st.integers(0, 5)))
    ]
    if draw(st.booleans()):
        objs.append(MapObject("RobotHome", draw(room_coord), draw(room_coord), name="Home"))
    for _ in range(draw(st.integers(0, 2))):
        fx, fy = draw(room_coord), draw(room_coord)
        objs.append(
            MapObject(
                "ForbiddenArea",
                0,
                0,
                draw(st.sampled_from([0, 30, 90, 180])),
                from_to=(fx, fy, fx + draw(st.integers(1, 2000)), fy + draw(st.integers(1, 2000))),
            )
        )
    if draw(st.booleans()):
        objs.append(
            MapObject(
                "ForbiddenLine",
                0,
                0,
                from_to=(draw(room_coord), draw(room_coord), draw(room_coord), draw(room_coord)),
            )
        )
    scan = Scan.from_arrays(pts, walls, resolution=20, sort=draw(st.booleans()))
    return MapData(scans=(scan,), objects=tuple(objs))


@settings(max_examples=25)
@given(rooms(), st.sampled_from([0.0, 200.0, 300.0]))
def test_round_trip_with_navigation(m: MapData, radius: float) -> None:
    model = validate(m, robot_radius=radius)
    from_file = validate(mapkit.dumpb(m), robot_radius=radius)
    assert findings(model) == findings(from_file)
    assert model.checked["navigation"] == from_file.checked["navigation"]


@settings(max_examples=20)
@given(
    st.lists(st.tuples(st.integers(300, 5700), st.integers(300, 3700)), min_size=1, max_size=4),
    st.integers(-10, 10),
)
def test_edited_clean_map_stays_clean(
    tmp_path_factory, goals: list[tuple[int, int]], shift: int
) -> None:
    """Edits made with MapData.replace (new goals, moved data) on the clean map, saved and read
    back: what was free of errors before saving is free of errors after."""
    m = mapkit.loads(CLEAN)
    new = tuple(MapObject("Goal", x, y, name=f"N{k}") for k, (x, y) in enumerate(goals))
    scan = m.scan.with_data(points=m.points + shift)
    edited = m.replace(objects=m.objects + new).with_scan(scan)
    before = validate(edited)
    path = Path(tmp_path_factory.mktemp("edit")) / "edited.map"
    mapkit.save(edited, path)
    after = validate(path)
    assert findings(before) == findings(after)
    if not before.errors:
        assert not [i for i in after.issues if i.severity is Severity.ERROR]
