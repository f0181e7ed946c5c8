"""The bundled samples: up to date with their generator, canonical (as ARIA writes them),
complete."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

import mapkit
from mapkit.samples import list_samples, sample_path

ROOT = Path(__file__).resolve().parents[2]


def test_samples_match_their_generator() -> None:
    result = subprocess.run(
        [sys.executable, str(ROOT / "scripts" / "make_samples.py"), "--check"],
        capture_output=True,
        text=True,
    )
    assert result.returncode == 0, result.stdout + result.stderr


@pytest.mark.parametrize("name", [n for n in list_samples() if n.endswith(".map")])
def test_sample_is_canonical_and_clean(name: str) -> None:
    path = sample_path(name)
    m, issues = mapkit.recover(path)
    assert issues == []
    assert mapkit.dumpb(m) == path.read_bytes()  # a fixed point of ARIA's writer


def test_office_has_what_the_issue_asks_for() -> None:
    m = mapkit.load(sample_path("office"))
    types = [o.type for o in m.objects]
    assert m.scan.num_points > 1000 and m.scan.num_lines > 10
    assert {
        "Goal",
        "GoalWithHeading",
        "RobotHome",
        "Dock",
        "ForbiddenArea",
        "ForbiddenLine",
    } <= set(types)
    assert any(o.type == "ForbiddenArea" and o.theta not in (0.0, 180.0) for o in m.objects)


def test_building_is_larger_and_multi_room() -> None:
    office, building = mapkit.load(sample_path("office")), mapkit.load(sample_path("building"))
    assert building.scan.num_points > 3 * office.scan.num_points
    assert len(building.objects) > 20
    assert "SectorType" in building.declared_types().values()
