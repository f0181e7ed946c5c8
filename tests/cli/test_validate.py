"""``mapkit validate`` and ``mapkit codes``: output, JSON, exit codes."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from click.testing import CliRunner

from mapkit.cli.main import cli
from mapkit.cli.validate import TEXT_LIMIT_PER_CODE
from mapkit.diagnostics import IssueCode
from mapkit.validate.codes import codes_markdown
from tests.validate.maps import CLEAN, LINE, edit, insert_after, write

ROOT = Path(__file__).resolve().parent.parent.parent
GOAL_A = 'Cairn: Goal 3000 2000 0.000000 "" ICON "A"'


def run(runner: CliRunner, *args: str) -> tuple[int, str, str]:
    result = runner.invoke(cli, list(args))
    return result.exit_code, result.stdout, result.stderr


def test_clean_map_exits_0(runner: CliRunner, tmp_path: Path) -> None:
    path = write(tmp_path, CLEAN)
    code, out, _ = run(runner, "validate", str(path))
    assert code == 0
    assert out == f"{path}: no problems found (robot radius 250 mm, 3 of 3 goals/docks reachable)\n"


def test_errors_exit_1_grouped_by_severity(runner: CliRunner, tmp_path: Path) -> None:
    text = edit(
        CLEAN,
        (GOAL_A, 'Cairn: Goal 4300 700 0.000000 "" ICON "A"'),
        ("PointsAreSorted: true", "PointsAreSorted: false"),
        ("Resolution: 20", "Resolution: 5000"),
    )
    path = write(tmp_path, text)
    code, out, _ = run(runner, "validate", str(path))
    assert code == 1
    lines = out.splitlines()
    assert lines[0] == "errors (1):"
    assert lines[1].startswith(f'  {path}:{LINE["A"]}: MK411 Goal "A" at (4300, 700) is inside')
    assert lines[2] == "warnings (1):"
    assert lines[3].startswith(f"  {path}:{LINE['Resolution']}: MK207 Resolution: 5000")
    assert lines[4] == "info (1):"
    assert lines[5].startswith(f"  {path}:{LINE['PointsAreSorted']}: MK208")
    assert (
        lines[6]
        == f"{path}: 1 error, 1 warning, 1 info (robot radius 250 mm, 2 of 3 goals/docks reachable)"
    )


def test_warnings_exit_0_or_1_with_strict(runner: CliRunner, tmp_path: Path) -> None:
    path = write(tmp_path, edit(CLEAN, ("NumPoints: 4", "NumPoints: 9")))
    assert run(runner, "validate", str(path))[0] == 0
    code, out, _ = run(runner, "validate", "--strict", str(path))
    assert code == 1 and "MK201" in out


def test_info_only_passes_strict(runner: CliRunner, tmp_path: Path) -> None:
    path = write(tmp_path, edit(CLEAN, ("PointsAreSorted: true", "PointsAreSorted: false")))
    assert run(runner, "validate", "--strict", str(path))[0] == 0


@pytest.mark.parametrize(
    "content, why",
    [
        (None, "no such file"),
        (b"", "empty"),
        (b"hello\nworld\n", "not an ARIA map"),
        (b"\xef\xbb\xbf2D-Map\nDATA\n", "byte-order mark"),
    ],
)
def test_unreadable_exits_2(
    runner: CliRunner, tmp_path: Path, content: bytes | None, why: str
) -> None:
    path = tmp_path / "x.map"
    if content is not None:
        path.write_bytes(content)
    code, out, err = run(runner, "validate", str(path))
    assert code == 2 and out == ""
    assert why in err and str(path) in err
    code, out, _ = run(runner, "validate", "--json", str(path))
    data = json.loads(out)
    assert code == 2 and data["readable"] is False and why in data["error"]


def test_directory_is_a_usage_error(runner: CliRunner, tmp_path: Path) -> None:
    code, _, err = run(runner, "validate", str(tmp_path))
    assert code == 2 and "it is a folder" in err


def test_json_report(runner: CliRunner, tmp_path: Path) -> None:
    path = write(tmp_path, edit(CLEAN, (GOAL_A, 'Cairn: Goal 0 2000 0.000000 "" ICON "A"')))
    code, out, _ = run(runner, "validate", "--json", "--robot-radius", "300", str(path))
    data = json.loads(out)
    assert code == 1 and data["exit_code"] == 1 and data["strict"] is False
    assert data["file"] == str(path) and data["robot_radius"] == 300
    assert data["summary"] == {"error": 1, "warning": 0, "info": 0}
    (issue,) = data["issues"]
    assert issue["code"] == int(IssueCode.GOAL_IN_WALL) and issue["name"] == "GOAL_IN_WALL"
    assert issue["location"] == {
        "source": str(path),
        "line": LINE["A"],
        "object": "A",
        "xy": [0.0, 2000.0],
    }
    assert data["checked"]["navigation"]["cell_mm"] == 75


def test_robot_radius_changes_the_checks(runner: CliRunner, tmp_path: Path) -> None:
    path = write(tmp_path, CLEAN)
    code, out, _ = run(runner, "validate", "--robot-radius", "1100", str(path))
    assert code == 0 and "MK410" in out and "robot radius 1100 mm" in out
    code, _, err = run(runner, "validate", "--robot-radius", "-5", str(path))
    assert code == 2 and "robot-radius" in err


def test_no_navigation(runner: CliRunner, tmp_path: Path) -> None:
    closed = insert_after(CLEAN, LINE["LINES"], "2500 0 2500 4000")
    closed = edit(
        closed, ("NumLines: 4", "NumLines: 5"), ("LinesAreSorted: true", "LinesAreSorted: false")
    )
    path = write(tmp_path, closed)
    code, out, _ = run(runner, "validate", str(path))
    assert code == 1 and "MK501" in out
    code, out, _ = run(runner, "validate", "--no-navigation", str(path))
    assert code == 0 and "MK501" not in out and "reachable" not in out


def test_text_output_caps_each_code(runner: CliRunner, tmp_path: Path) -> None:
    n = TEXT_LIMIT_PER_CODE + 7
    goals = [f'Cairn: Goal {100 + 200 * k} 0 0.000000 "" ICON "W{k}"' for k in range(n)]
    path = write(tmp_path, insert_after(CLEAN, LINE["D"], *goals))
    code, out, _ = run(runner, "validate", "--no-navigation", str(path))
    assert code == 1
    assert out.count(": MK409 ") == TEXT_LIMIT_PER_CODE
    assert "  ... 7 more MK409 findings (--json lists them all)" in out
    data = json.loads(run(runner, "validate", "--no-navigation", "--json", str(path))[1])
    assert sum(1 for i in data["issues"] if i["code"] == 409) == n


def test_codes_table(runner: CliRunner) -> None:
    code, out, _ = run(runner, "codes")
    assert code == 0
    rows = out.splitlines()
    assert len(rows) == len(IssueCode)
    assert rows[0].split()[:3] == ["MK101", "JUNK_BEFORE_INTRO", "warning"]
    data = json.loads(run(runner, "codes", "--json")[1])
    assert {r["number"] for r in data} == {int(c) for c in IssueCode}
    assert run(runner, "codes", "--markdown", "--json")[0] == 2


def test_docs_codes_md_is_up_to_date(runner: CliRunner) -> None:
    """docs/codes.md is generated: `mapkit codes --markdown > docs/codes.md` after adding codes."""
    out = run(runner, "codes", "--markdown")[1]
    assert out == codes_markdown()
    assert (ROOT / "docs" / "codes.md").read_text(encoding="utf-8") == out, (
        "docs/codes.md is stale: run `mapkit codes --markdown > docs/codes.md`"
    )


def test_every_real_sample(runner: CliRunner, real_sample: Path) -> None:
    code, out, _ = run(runner, "validate", "--json", str(real_sample))
    data = json.loads(out)
    assert code == (1 if data["summary"]["error"] else 0)
    lines = real_sample.read_bytes().count(b"\n") + 1
    per_code: dict[int, int] = {}
    for issue in data["issues"]:
        assert 0 < issue["location"].get("line", 1) <= lines
        per_code[issue["code"]] = per_code.get(issue["code"], 0) + 1
    # No noise: a real map never gets a pile of identical findings.
    assert max(per_code.values(), default=0) <= 3, per_code
    name = real_sample.name
    codes = [i["code"] for i in data["issues"]]
    if name in (
        "aria-office.map",
        "aria-triangle.map",
        "aria-ActivMediaLab.map",
        "aria275-columbia.map",
    ):
        assert codes == []  # hand-drawn, lines only: nothing abnormal for such maps
    if "columbia" in name and name != "aria275-columbia.map":
        objs = {(i["code"], i["location"].get("object")) for i in data["issues"]}
        assert (411, "Inside Forbidden Area") in objs and (501, "Impossible Goal") in objs
    if name == "aria291-columbia.map":
        assert 214 in codes and 102 not in codes  # OriginLatLonAlt: typo
    if name == "omron-ld-showroom-ex4.map":
        assert codes == [212, 412]
