"""The object-editing commands through click's runner, on copies of the real samples."""

from __future__ import annotations

import json
from pathlib import Path
from shlex import split

import pytest
from click.testing import CliRunner

from mapkit.formats.map import dumpb, load
from tests.cli.edit_helpers import COLUMBIA, OMRON, copy, copy_sample, light_sample, run

__all__ = ["copy"]  # the fixture, used by name


@pytest.fixture
def columbia(shared_dir: Path, tmp_path: Path) -> Path:
    return light_sample(shared_dir, tmp_path, COLUMBIA)


@pytest.fixture
def omron(shared_dir: Path, tmp_path: Path) -> Path:
    return light_sample(shared_dir, tmp_path, OMRON)


# -- on every real sample -------------------------------------------------------------------------


def test_add_goal_then_remove_gives_the_canonical_bytes(runner: CliRunner, copy: Path) -> None:
    canonical = dumpb(load(copy))
    r = run(
        runner,
        "add-goal",
        copy,
        "CLI goal",
        -1500,
        -250.5,
        "--heading",
        -90,
        "--description",
        "near the lab",
    )
    assert r.exit_code == 0, r.output
    # Stored as ARIA writes it: whole millimetres, halves to even (%.0f).
    assert "added GoalWithHeading 'CLI goal' at (-1500, -250) heading -90" in r.stdout
    assert f"wrote {copy}" in r.stdout
    assert load(copy).find("CLI goal")[0].description == "near the lab"
    r = run(runner, "remove", copy, "cli GOAL")
    assert r.exit_code == 0, r.output
    assert copy.read_bytes() == canonical


def test_a_refused_edit_leaves_the_file_byte_for_byte(runner: CliRunner, copy: Path) -> None:
    before = copy.read_bytes()
    for args in (
        ("add-goal", copy, 'bad "name"', 0, 0),
        ("forbid", copy, "--area", 0, 0, 0, 100),
        ("remove", copy, "no such object anywhere"),
    ):
        r = run(runner, *args)
        assert r.exit_code == 1, (args, r.output)
        assert r.stderr.startswith("Error: ") and r.stderr.count("\n") == 1
        assert copy.read_bytes() == before


def test_objects_lists_every_object(runner: CliRunner, copy: Path) -> None:
    m = load(copy)
    r = run(runner, "objects", copy, "--json")
    assert r.exit_code == 0
    rows = json.loads(r.stdout)
    assert [row["name"] for row in rows] == [o.name for o in m.objects]
    assert [row["index"] for row in rows] == list(range(1, len(m.objects) + 1))
    text = run(runner, "objects", copy).stdout.splitlines()
    assert len(text) == len(m.objects) + 1 and text[0].split()[:3] == ["#", "type", "name"]


def test_backup_output_and_dry_run(runner: CliRunner, columbia: Path, tmp_path: Path) -> None:
    copy = columbia
    before = copy.read_bytes()
    out = tmp_path / "out.map"
    r = run(runner, "add-home", copy, 100, 200, "--name", "H2", "-o", out)
    assert r.exit_code == 0 and copy.read_bytes() == before
    assert load(out).find("H2")[0].type == "RobotHome"
    r = run(runner, "add-home", copy, 100, 200, "--name", "H2", "-o", out)
    assert r.exit_code == 2 and "--force" in r.stderr
    r = run(runner, "add-home", copy, 100, 200, "--name", "H3", "--dry-run")
    assert r.exit_code == 0 and "dry run" in r.stdout and copy.read_bytes() == before
    r = run(runner, "add-home", copy, 100, 200, "--name", "H4", "--backup")
    assert r.exit_code == 0 and "kept as" in r.stdout
    assert Path(str(copy) + ".bak").read_bytes() == before
    assert load(copy).find("H4")


# -- each command on a chosen sample --------------------------------------------------------------


def test_add_commands(runner: CliRunner, columbia: Path) -> None:
    before = columbia.read_bytes()
    for args in (
        ("add-goal", columbia, "far", 3_000_000, 0),
        ("move", columbia, "#999", 0, 0),
        ("add-object", columbia, "NotAType", "--at", 0, 0, "--name", "x"),
        ("add-goal", columbia, "Goal 1", 0, 0),
    ):
        r = run(runner, *args)
        assert r.exit_code == 1 and r.stderr.startswith("Error: ")
    assert columbia.read_bytes() == before
    r = run(runner, "add-goal", columbia, "Goal 1", 0, 0, "--allow-duplicate")
    assert r.exit_code == 0
    r = run(runner, "add-dock", columbia, "Dock A", -100, -200, "--heading", 180)
    assert r.exit_code == 0 and load(columbia).find("Dock A")[0].theta == 180
    r = run(
        runner,
        "add-home",
        columbia,
        "--area",
        -500,
        -500,
        500,
        500,
        "--angle",
        45,
        "--rotate-about-centre",
        "--name",
        "Start",
    )
    assert r.exit_code == 0, r.output
    home = load(columbia).find("Start")[0]
    assert (
        home.theta == 45 and round(home.corners()[0][0] ** 2 + home.corners()[0][1] ** 2) == 500_000
    )
    assert run(runner, "add-home", columbia, 1, 2, "--area", 0, 0, 1, 1).exit_code == 1
    r = run(runner, "forbid", columbia, "--line", -5000, 100, 5000, 100, "--name", "No pass")
    assert r.exit_code == 0 and load(columbia).find("No pass")[0].from_to == (-5000, 100, 5000, 100)
    for bad in (
        ("forbid", columbia),
        ("forbid", columbia, "--area", 0, 0, 1, 1, "--line", 0, 0, 1, 1),
        ("forbid", columbia, "--line", 0, 0, 1, 1, "--angle", 3),
    ):
        r = run(runner, *bad)
        assert r.exit_code == 2 and "Usage" in r.stderr
    r = run(
        runner,
        "add-object",
        columbia,
        "BadGPSSector",
        "--area",
        0,
        0,
        1000,
        1000,
        "--name",
        "No GPS",
    )
    assert r.exit_code == 0 and load(columbia).find("No GPS")[0].type == "BadGPSSector"
    r = run(runner, "add-object", columbia, "Measure", "--line", 0, 0, 5000, 0)
    assert r.exit_code == 0
    r = run(runner, "add-object", columbia, "Sim.BoxObstacle", "--area", 0, 0, 500, 500)
    assert r.exit_code == 1 and "--allow-undeclared" in r.stderr
    r = run(
        runner,
        "add-object",
        columbia,
        "Sim.BoxObstacle",
        "--area",
        0,
        0,
        500,
        500,
        "--allow-undeclared",
    )
    assert r.exit_code == 0


def test_add_object_with_params(runner: CliRunner, omron: Path) -> None:
    sector = ["add-object", omron, "MovementParametersSector", "--area"]
    r = run(
        runner,
        *sector,
        *split("0 0 4000 2000 --name Slow --param TransVelMax=300 --angle 30"),
        "--rotate-about-centre",
    )
    assert r.exit_code == 0, r.output
    assert '+ CairnInfo: Params "Slow" "Normal" 300' in r.stdout
    listed = run(runner, "objects", omron, "--type", "MovementParametersSector", "--json")
    rows = json.loads(listed.stdout)
    assert rows[0]["params"]["TransVelMax"] == "300" and rows[0]["theta"] == 30
    r = run(runner, *sector, *split("0 0 1 1 --name S2 --param nonsense"))
    assert r.exit_code == 2 and "NAME=VALUE" in r.stderr
    r = run(runner, *sector, *split("0 0 1 1 --name S2 --param TransVelMax=-5"))
    assert r.exit_code == 1 and "below its minimum" in r.stderr
    r = run(runner, "objects", omron, "--all")
    assert "ChildDoorForEnter101" in r.stdout


def test_remove_rename_move(runner: CliRunner, columbia: Path, omron: Path) -> None:
    r = run(runner, "remove", columbia, "Goal 7")
    assert r.exit_code == 1 and "did you mean 'Goal 3', 'Goal 2', 'Goal 1'?" in r.stderr
    r = run(runner, "remove", columbia, "")
    assert r.exit_code == 1 and "objects are named ''" in r.stderr
    n = len(load(columbia).objects)
    r = run(runner, "remove", columbia, "#1", "#2")
    assert r.exit_code == 0 and len(load(columbia).objects) == n - 2
    r = run(runner, "remove", columbia, "", "--type", "ForbiddenArea", "--all")
    assert r.exit_code == 0 and not load(columbia).find("", type="ForbiddenArea")
    r = run(runner, "rename", columbia, "Goal 1", "Reception")
    assert r.exit_code == 0 and "changed Goal 'Goal 1': name 'Goal 1' -> 'Reception'" in r.stdout
    assert run(runner, "rename", columbia, "Reception", "goal 2").exit_code == 1
    r = run(runner, "rename", omron, "Goal1", "Start")
    assert r.exit_code == 0 and "RouteInfo: GoalAfter \"Goal1\" still names 'Goal1'" in r.stderr
    r = run(runner, "move", columbia, "Reception", -100, -200, "--heading", 90)
    assert r.exit_code == 0
    moved = load(columbia).find("Reception")[0]
    assert (moved.x, moved.y, moved.theta, moved.type) == (-100, -200, 90, "GoalWithHeading")
    r = run(runner, "move", columbia, "Reception", "--by", 10, -10)
    assert r.exit_code == 0 and (load(columbia).find("Reception")[0].x) == -90
    r = run(runner, "move", columbia, "Reception", 1, 2, "--by", 1, 1)
    assert r.exit_code == 1 and "not both" in r.stderr
    r = run(runner, "move", columbia, "Reception")
    assert r.exit_code == 1 and "nothing to do" in r.stderr


def test_nothing_changed_leaves_the_file(
    runner: CliRunner, shared_dir: Path, tmp_path: Path
) -> None:
    # aria-office.map is not ARIA-canonical: any rewrite would change it.
    p = copy_sample(shared_dir, tmp_path, "aria-office.map")
    before = p.read_bytes()
    r = run(runner, "erase", p, "--box", 900000, 900000, 900100, 900100)
    assert r.exit_code == 0 and "nothing changed" in r.stdout
    assert p.read_bytes() == before
