"""5xx: reachability for a robot of a given radius, on the rasterised map."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import mapkit
from mapkit.diagnostics import IssueCode, Severity
from mapkit.model import MapData, MapObject, Scan
from mapkit.raster import inflate
from mapkit.validate import validate
from mapkit.validate._context import Context
from mapkit.validate.navigation import clearance_grid

C = IssueCode
NAV_CODES = {C.UNREACHABLE, C.NARROW_PASSAGE, C.NAVIGATION_SKIPPED}


def two_rooms(
    door: float | None, *objects: MapObject, extra_lines: list[list[int]] | None = None
) -> MapData:
    """Two 4 x 4 m rooms side by side; the wall between them at x = 4000 has a door of width
    ``door`` centred on y = 2000 (``None``: no door)."""
    walls = [[0, 0, 8000, 0], [8000, 0, 8000, 4000], [8000, 4000, 0, 4000], [0, 4000, 0, 0]]
    if door is None:
        walls.append([4000, 0, 4000, 4000])
    else:
        walls += [[4000, 0, 4000, int(2000 - door / 2)], [4000, int(2000 + door / 2), 4000, 4000]]
    walls += extra_lines or []
    return MapData(scans=(Scan.from_arrays(lines=walls, resolution=20),), objects=objects)


HOME = MapObject("RobotHome", 1000, 2000, name="Home")
GOAL = MapObject("Goal", 6000, 2000, name="G")


def only(report: mapkit.Report, code: IssueCode) -> list[mapkit.Issue]:
    return [i for i in report.issues if i.code is code]


def test_wide_door_is_clean() -> None:
    report = validate(two_rooms(1000, HOME, GOAL))
    assert report.issues == ()
    nav = report.checked["navigation"]
    assert (nav["targets"], nav["reachable"], nav["start"]) == (1, 1, 'RobotHome "Home"')


def test_tight_door_is_a_narrow_passage() -> None:
    report = validate(two_rooms(600, HOME, GOAL))
    assert report.codes() == [int(C.NARROW_PASSAGE)]
    issue = report.issues[0]
    assert issue.severity is Severity.WARNING and issue.location.object == "G"
    x, y = issue.location.xy  # type: ignore[misc]
    assert abs(x - 4000) <= 150 and abs(y - 2000) <= 150
    assert "gap about" in issue.message and 'RobotHome "Home"' in issue.message


def test_narrow_passage_groups_the_goals_behind_one_door() -> None:
    goals = [MapObject("Goal", 6000, y, name=f"G{y}") for y in (1000, 2000, 3000)]
    report = validate(two_rooms(600, HOME, *goals))
    found = only(report, C.NARROW_PASSAGE)
    assert len(found) == 1
    assert all(f'"G{y}"' in found[0].message for y in (1000, 2000, 3000))


def test_door_narrower_than_the_robot_is_unreachable_with_the_gap() -> None:
    report = validate(two_rooms(400, HOME, GOAL))
    found = only(report, C.UNREACHABLE)
    assert len(found) == 1 and found[0].location.object == "G"
    assert found[0].location.xy == (6000.0, 2000.0)
    assert "gap about" in found[0].message and "(4" in found[0].message  # near x = 4000
    assert report.checked["navigation"]["reachable"] == 0
    # A smaller robot gets through, with little room to spare.
    small = validate(two_rooms(400, HOME, GOAL), robot_radius=150)
    assert small.codes() == [int(C.NARROW_PASSAGE)]


def test_closed_room_is_unreachable() -> None:
    report = validate(two_rooms(None, HOME, GOAL))
    found = only(report, C.UNREACHABLE)
    assert len(found) == 1 and "close it off completely" in found[0].message


def test_forbidden_line_across_the_door_blocks_it() -> None:
    fl = MapObject("ForbiddenLine", 4000, 1000, from_to=(4000, 1000, 4000, 3000))
    report = validate(two_rooms(1000, HOME, GOAL, fl))
    assert [int(i.code) for i in report.issues] == [int(C.UNREACHABLE)]


def test_rotated_forbidden_area_blocks_where_aria_puts_it() -> None:
    # From/To (1500..2500, -4500..-3500) rotated by 90 degrees about the origin covers world
    # x 3500..4500, y 1500..2500: the door.
    fa = MapObject("ForbiddenArea", 0, 0, 90, from_to=(1500, -4500, 2500, -3500))
    report = validate(two_rooms(1000, HOME, GOAL, fa))
    assert int(C.UNREACHABLE) in report.codes()
    unrotated = MapObject("ForbiddenArea", 0, 0, 0, from_to=(1500, -4500, 2500, -3500))
    assert int(C.UNREACHABLE) not in validate(two_rooms(1000, HOME, GOAL, unrotated)).codes()


def test_without_home_goals_are_checked_against_each_other() -> None:
    a = MapObject("Goal", 1000, 1000, name="A")
    b = MapObject("Goal", 1000, 3000, name="B")
    dock = MapObject("Dock", 6000, 2000, 0, name="D")
    report = validate(two_rooms(None, a, b, dock))
    found = only(report, C.UNREACHABLE)
    assert [f.location.object for f in found] == ["D"]
    assert "from the other goals" in found[0].message
    assert report.checked["navigation"]["start"] == 'Goal "A" (no usable RobotHome)'


def test_goal_near_a_wall_still_counts_as_reached() -> None:
    near = MapObject("Goal", 6000, 150, name="N")
    report = validate(two_rooms(1000, HOME, near))
    assert report.codes() == [int(C.GOAL_NEAR_WALL)]


def test_goal_inside_forbidden_area_is_not_reported_twice() -> None:
    fa = MapObject("ForbiddenArea", 0, 0, 0, from_to=(5000, 1000, 7000, 3000))
    report = validate(two_rooms(1000, HOME, GOAL, fa))
    assert report.codes() == [int(C.GOAL_IN_FORBIDDEN_AREA)]
    assert report.checked["navigation"]["in_forbidden_areas"] == 1


def test_huge_map_skips_navigation_with_a_reason() -> None:
    m = two_rooms(1000, HOME, GOAL, extra_lines=[[600_000, 0, 600_100, 0]])
    report = validate(m)
    found = only(report, C.NAVIGATION_SKIPPED)
    assert len(found) == 1 and "too large" in found[0].message
    assert report.checked["navigation"]["skipped"] == "too large"
    assert int(C.NAVIGATION_SKIPPED) not in validate(m, robot_radius=0).codes()


def test_navigation_can_be_switched_off() -> None:
    report = validate(two_rooms(None, HOME, GOAL), navigation=False)
    assert int(C.UNREACHABLE) not in report.codes()
    assert "navigation" not in report.checked


def test_locations_in_file_view(tmp_path: Path) -> None:
    path = tmp_path / "rooms.map"
    mapkit.save(two_rooms(400, HOME, GOAL), path)
    report = validate(path)
    found = only(report, C.UNREACHABLE)
    assert len(found) == 1
    lines = path.read_text().splitlines()
    assert lines[found[0].location.line - 1].startswith("Cairn: Goal 6000 2000")  # type: ignore[operator]


@pytest.mark.parametrize("radius", [0.0, 120.0, 250.0, 333.0])
def test_free_space_is_the_rasterisers_inflation(radius: float) -> None:
    m = two_rooms(
        700, HOME, GOAL, MapObject("ForbiddenLine", 5000, 500, from_to=(5000, 500, 7000, 1500))
    )
    ctx = Context(m, file_view=False)
    cl = clearance_grid(ctx, ((-500, -500), (8500, 4500)), 50.0)
    walls = cl.dist == 0
    assert np.array_equal(cl.free(radius), ~inflate(walls, radius, cl.grid.resolution))
