"""``--angle`` turns a drawn area about its own centre; reports and diff give world corners."""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import pytest
from click.testing import CliRunner

from mapkit import edit, load
from mapkit.model import MapData
from mapkit.samples import sample_path
from tests.cli.edit_helpers import run

CORNER = re.compile(r"\((-?\d+), (-?\d+)\)")


def corners_of(text: str) -> list[tuple[int, int]]:
    return [(int(x), int(y)) for x, y in CORNER.findall(text)]


@pytest.fixture
def office(tmp_path: Path) -> Path:
    dst = tmp_path / "office.map"
    shutil.copyfile(sample_path("office"), dst)
    return dst


@pytest.mark.parametrize("command", ["forbid", "add-home", "add-object"])
@pytest.mark.parametrize("angle", ["20", "-70", "135"])
def test_an_angle_keeps_the_box_where_it_was_drawn(
    runner: CliRunner, office: Path, command: str, angle: str
) -> None:
    head = {
        "forbid": ["forbid"],
        "add-home": ["add-home"],
        "add-object": ["add-object", str(office), "ForbiddenArea"],
    }[command]
    args = [
        *head,
        *([] if command == "add-object" else [str(office)]),
        "--area",
        "6000",
        "3000",
        "8000",
        "4000",
        "--angle",
        angle,
        "--name",
        "Box",
    ]
    r = run(runner, *args)
    assert r.exit_code == 0, r.output
    obj = load(office).objects[-1]
    cx = sum(c[0] for c in obj.corners()) / 4
    cy = sum(c[1] for c in obj.corners()) / 4
    assert (cx, cy) == pytest.approx((7000, 3500), abs=1)  # 7.8 m from the origin, as drawn
    # the report gives the corners in the world, the same as `mapkit objects`
    reported = corners_of(r.stdout.splitlines()[0])
    listed = corners_of(run(runner, "objects", office).stdout.splitlines()[-1].split("area")[1])
    assert reported == listed and len(reported) == 4
    assert reported == [(round(x), round(y)) for x, y in obj.corners()]


def test_rotate_about_origin_keeps_arias_rule(runner: CliRunner, office: Path) -> None:
    r = run(
        runner,
        "forbid",
        office,
        "--area",
        "6000",
        "3000",
        "8000",
        "4000",
        "--angle",
        "90",
        "--rotate-about",
        "origin",
    )
    assert r.exit_code == 0, r.output
    want = edit.forbid_area(MapData(), 6000, 3000, 8000, 4000, angle=90, rotate_about="origin")
    assert load(office).objects[-1].from_to == want.objects[0].from_to
    assert sorted(corners_of(r.stdout.splitlines()[0])) == [
        (-4000, 6000),
        (-4000, 8000),
        (-3000, 6000),
        (-3000, 8000),
    ]


def test_old_flag_still_runs_and_conflicts_are_refused(runner: CliRunner, office: Path) -> None:
    area = ["--area", "0", "0", "1000", "1000", "--angle", "10"]
    assert run(runner, "forbid", office, *area, "--rotate-about-centre").exit_code == 0
    r = run(runner, "forbid", office, *area, "--rotate-about-centre", "--rotate-about", "origin")
    assert r.exit_code == 2 and "not both" in r.stderr


def test_diff_shows_world_corners_of_a_turned_area(
    runner: CliRunner, office: Path, tmp_path: Path
) -> None:
    before = tmp_path / "before.map"
    shutil.copyfile(office, before)
    assert (
        run(
            runner,
            "forbid",
            office,
            "--area",
            "16000",
            "1500",
            "18000",
            "3500",
            "--angle",
            "20",
            "--name",
            "Printer",
        ).exit_code
        == 0
    )
    r = run(runner, "diff", before, office)
    line = next(x for x in r.stdout.splitlines() if "Printer" in x)
    got = corners_of(line)
    assert got == [(round(x), round(y)) for x, y in load(office).find("Printer")[0].corners()]
    assert all(15000 < x < 19000 and 1000 < y < 4000 for x, y in got)  # where it was drawn
