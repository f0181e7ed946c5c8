"""Data commands, merge, diff and edit --script through click's runner."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from mapkit import edit
from mapkit.edit import Region
from mapkit.edit.selection import lines_overlapping, points_inside
from mapkit.formats.map import dumpb, load, save
from tests.cli.edit_helpers import COLUMBIA, copy, copy_sample, run

__all__ = ["copy"]  # the fixture, used by name


@pytest.fixture
def columbia(shared_dir: Path, tmp_path: Path) -> Path:
    return copy_sample(shared_dir, tmp_path, COLUMBIA)


def _middle_box(path: Path) -> tuple[int, int, int, int]:
    b = load(path).scan.data_bounds()
    assert b is not None
    (x0, y0), (x1, y1) = b
    return x0 + (x1 - x0) // 4, y0 + (y1 - y0) // 4, x1 - (x1 - x0) // 4, y1 - (y1 - y0) // 4


# -- on every real sample --


def test_erase_then_diff(runner: CliRunner, copy: Path, tmp_path: Path) -> None:
    box = _middle_box(copy)
    erased = tmp_path / "erased.map"
    r = run(runner, "erase", copy, "--box", *box, "-o", erased)
    assert r.exit_code == 0, r.output
    m = load(erased)
    region = Region.box(*box)
    assert (
        not points_inside(m.points, region).any() and not lines_overlapping(m.lines, region).any()
    )
    r = run(runner, "diff", copy, erased)
    assert r.exit_code == 1 and "objects: 0 added, 0 removed, 0 moved, 0 changed" in r.stdout


def test_transform_and_back(runner: CliRunner, columbia: Path, tmp_path: Path) -> None:
    canonical = dumpb(load(columbia))
    turned = tmp_path / "turned.map"
    assert (
        run(
            runner, "transform", columbia, "--rotate", 90, "--translate", -20, 40, "-o", turned
        ).exit_code
        == 0
    )
    assert run(runner, "transform", turned, "--translate", 20, -40).exit_code == 0
    assert run(runner, "transform", turned, "--rotate", -90).exit_code == 0
    assert turned.read_bytes() == canonical
    r = run(runner, "diff", columbia, turned, "--json")
    assert r.exit_code == 0 and json.loads(r.stdout)["equal"] is True


# -- each command --


def test_erase_polygon_and_errors(runner: CliRunner, columbia: Path) -> None:
    before = columbia.read_bytes()
    assert run(runner, "erase", columbia).exit_code == 2
    r = run(runner, "erase", columbia, "--polygon", "0,0 10,10")
    assert r.exit_code == 1 and "at least 3 vertices" in r.stderr
    assert run(runner, "erase", columbia, "--polygon", "0,0 10").exit_code == 2
    assert run(runner, "erase", columbia, "--polygon", "a,b c,d e,f").exit_code == 2
    assert (
        run(runner, "erase", columbia, "--box", 0, 0, 1, 1, "--polygon", "0,0 1,0 0,1").exit_code
        == 2
    )
    r = run(runner, "erase", columbia, "--box", 0, 0, 1000, 1000, "--source", "Sonar")
    assert r.exit_code == 1 and "no scan source 'Sonar'" in r.stderr
    assert columbia.read_bytes() == before
    poly = "-4000,-20000 2000,-20000 2000,-10000"
    r = run(runner, "erase", columbia, "--polygon", poly, "--backup")
    assert r.exit_code == 0 and "points:" in r.stdout and "removed" in r.stdout
    assert Path(str(columbia) + ".bak").read_bytes() == before
    region = Region.polygon([(-4000, -20000), (2000, -20000), (2000, -10000)])
    assert not points_inside(load(columbia).points, region).any()


def test_draw_line_and_crop(runner: CliRunner, columbia: Path, tmp_path: Path) -> None:
    n = load(columbia).scan.num_lines
    r = run(runner, "draw-line", columbia, -1000, -1000, 1000, -1000)
    assert r.exit_code == 0 and "lines: 1 added in (-1000, -1000)-(1000, -1000)" in r.stdout
    assert load(columbia).scan.num_lines == n + 1
    before = load(columbia).scan.num_points
    r = run(runner, "draw-line", columbia, -1000, -2000, 1000, -2000, "--as-points")
    added = load(columbia).scan.num_points - before
    assert 0 < added <= 101  # one point every 20 mm, less those already there
    assert r.exit_code == 0 and f"points: {added} added in (-1000, -2000)-(1000, -2000)" in r.stdout
    assert run(runner, "draw-line", columbia, 5, 5, 5, 5).exit_code == 1
    out = tmp_path / "south.map"
    r = run(runner, "crop", columbia, "--box", -6000, -28000, 21000, 0, "-o", out)
    assert r.exit_code == 0, r.output
    m = load(out)
    assert (m.points[:, 1] <= 0).all() and (m.lines[:, [1, 3]] <= 0).all()
    assert all(o.y <= 0 for o in m.objects if o.from_to is None)
    assert "removed Goal 'Hallway 1'" in r.stdout
    r = run(
        runner,
        "crop",
        columbia,
        "--box",
        -6000,
        -28000,
        21000,
        0,
        "--keep-objects",
        "-o",
        out,
        "--force",
    )
    assert r.exit_code == 0 and len(load(out).objects) == len(load(columbia).objects)
    assert run(runner, "crop", columbia).exit_code == 2


def test_transform_options_and_notes(runner: CliRunner, columbia: Path, tmp_path: Path) -> None:
    assert run(runner, "transform", columbia).exit_code == 2
    out = tmp_path / "c.map"
    r = run(runner, "transform", columbia, "--recenter", "-o", out)
    assert r.exit_code == 0
    assert "OriginLatLongAlt" in r.stderr and "motion: turn 0 degrees" in r.stderr
    b = load(out).scan.data_bounds()
    assert b is not None and abs(b[0][0] + b[1][0]) <= 40 and abs(b[0][1] + b[1][1]) <= 40
    r = run(
        runner, "transform", columbia, "--rotate", 12.5, "--about", 1000, 2000, "-o", out, "--force"
    )
    assert r.exit_code == 0 and "off their 20 mm grid" in r.stderr
    assert "more changes (mapkit diff shows them all)" in r.stdout
    r = run(runner, "transform", columbia, "--translate", 3_000_000, 0)
    assert r.exit_code == 1 and "outside ARIA's range" in r.stderr


def test_merge_commands(runner: CliRunner, shared_dir: Path, tmp_path: Path) -> None:
    base = copy_sample(shared_dir, tmp_path, "aria-office.map")
    other = tmp_path / "other.map"
    m = load(base)

    save(
        edit.add_goal(edit.add_goal(m, "Home", 10, 10, allow_duplicate=True), "Extra", 0, 0), other
    )
    before = base.read_bytes()
    r = run(runner, "merge", base, other, "--on-clash", "error")
    assert r.exit_code == 1 and "name clash" in r.stderr and base.read_bytes() == before
    r = run(runner, "merge", base, other, "--on-clash", "rename", "--dry-run")
    assert r.exit_code == 0 and "added Goal 'Home 2'" in r.stdout and "name clash" in r.stderr
    out = tmp_path / "merged.map"
    r = run(runner, "merge", base, other, "--region", -5000, -5000, 5000, 5000, "-o", out)
    assert r.exit_code == 0, r.output
    assert [o.name for o in load(out).objects] == ["Home", "Home", "Extra"]
    assert (
        run(
            runner, "merge", base, other, "--region", 0, 0, 1, 1, "--polygon", "0,0 1,0 0,1"
        ).exit_code
        == 2
    )


def test_diff_exit_codes(runner: CliRunner, columbia: Path, tmp_path: Path) -> None:
    assert run(runner, "diff", columbia, columbia).exit_code == 0
    r = run(runner, "diff", columbia, tmp_path / "missing.map")
    assert r.exit_code == 2 and "missing.map" in r.stderr
    bad = tmp_path / "bad.map"
    bad.write_bytes(b"not a map\n")
    r = run(runner, "diff", columbia, bad)
    assert r.exit_code == 2 and "not an ARIA map" in r.stderr
    other = tmp_path / "o.map"
    run(runner, "add-goal", columbia, "New", 1, 2, "-o", other)
    r = run(runner, "diff", columbia, other, "--json")
    doc = json.loads(r.stdout)
    assert r.exit_code == 1 and doc["counts"] == {
        "added": 1,
        "removed": 0,
        "moved": 0,
        "changed": 0,
    }
    assert doc["objects"][0]["after"]["name"] == "New"


def test_edit_script(runner: CliRunner, columbia: Path, tmp_path: Path) -> None:
    script = tmp_path / "edits.yaml"
    script.write_text(
        "edits:\n"
        "  - add-goal: {name: Kitchen, x: 1000, y: 2000, heading: 90}\n"
        "  - rename: {name: Goal 2, new-name: Reception}\n"
        "  - erase: {box: [-500, -500, 500, 500]}\n"
    )
    r = run(runner, "edit", columbia, "--script", script)
    assert r.exit_code == 0, r.output
    assert "3 edits" in r.stderr and "added GoalWithHeading 'Kitchen'" in r.stdout
    assert "changed Goal 'Goal 2': name 'Goal 2' -> 'Reception'" in r.stdout
    m = load(columbia)
    assert (
        m.find("Reception") and not points_inside(m.points, Region.box(-500, -500, 500, 500)).any()
    )
    before = columbia.read_bytes()
    script.write_text("- add-goal: {name: Second, x: 0, y: 0}\n- remove: [Nobody]\n")
    r = run(runner, "edit", columbia, "--script", script)
    assert r.exit_code == 1 and "edit 2 (remove, line 2): no object named 'Nobody'" in r.stderr
    assert columbia.read_bytes() == before  # the first edit of the batch did not land either
    assert run(runner, "edit", columbia).exit_code == 2
    assert np.array_equal(load(columbia).points, m.points)
