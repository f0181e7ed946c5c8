"""Crafted maps for the validator's tests: one clean map and helpers to break it."""

from __future__ import annotations

from pathlib import Path

#: A clean map: a 6 x 4 m room, a home, two goals, a dock, a forbidden area and line, and a
#: custom sector with a parameter. ARIA's canonical form (a fixed point of the writer), so it is
#: clean in both the file view and the model view. Line numbers are used by the tests.
CLEAN = """\
2D-Map-Ex2
MinPos: 0 0
MaxPos: 6000 4000
NumPoints: 4
PointsAreSorted: true
Resolution: 20
LineMinPos: 0 0
LineMaxPos: 6000 4000
NumLines: 4
LinesAreSorted: true
CairnInfo: Params "Zone1" 500
MapInfo: GoalType Name=Goal
MapInfo: DockType Name=Dock
MapInfo: SectorType Name=SpeedZone
MapInfo: ArgDesc Name=MaxSpeed Parent=SpeedZone Type=int Value=300 Min=0 Max=2000
Cairn: RobotHome 1000 1000 0.000000 "" ICON "Home"
Cairn: Goal 3000 2000 0.000000 "" ICON "A"
Cairn: GoalWithHeading 5000 3000 90.000000 "" ICON "B"
Cairn: Dock 1000 3000 180.000000 "" ICON "D"
Cairn: ForbiddenArea 0 0 0.000000 "" ICON "" 4000 500 4600 1000
Cairn: ForbiddenLine 2000 3500 0.000000 "" ICON "" 2000 3500 2000 3900
Cairn: SpeedZone 0 0 0.000000 "" ICON "Zone1" 300 300 800 800
LINES
0 0 0 4000
0 0 6000 0
0 4000 6000 4000
6000 0 6000 4000
DATA
0 0
0 4000
6000 0
6000 4000
"""

#: Line numbers of the clean map's lines, by a short name.
LINE = {
    "intro": 1,
    "MinPos": 2,
    "MaxPos": 3,
    "NumPoints": 4,
    "PointsAreSorted": 5,
    "Resolution": 6,
    "LineMinPos": 7,
    "LineMaxPos": 8,
    "NumLines": 9,
    "LinesAreSorted": 10,
    "Params": 11,
    "GoalType": 12,
    "DockType": 13,
    "SectorType": 14,
    "ArgDesc": 15,
    "Home": 16,
    "A": 17,
    "B": 18,
    "D": 19,
    "FA": 20,
    "FL": 21,
    "Zone1": 22,
    "LINES": 23,
    "DATA": 28,
}


def edit(text: str = CLEAN, *pairs: tuple[str, str]) -> str:
    """``text`` with each ``old`` (which must occur exactly once) replaced by ``new``."""
    for old, new in pairs:
        assert text.count(old) == 1, f"{old!r} occurs {text.count(old)} times"
        text = text.replace(old, new)
    return text


def insert_after(text: str, lineno: int, *lines: str) -> str:
    """``text`` with ``lines`` inserted after line ``lineno`` (1-based)."""
    rows = text.split("\n")
    return "\n".join(rows[:lineno] + list(lines) + rows[lineno:])


def write(tmp_path: Path, text: str | bytes, name: str = "t.map") -> Path:
    """Write a crafted map and return its path."""
    p = tmp_path / name
    p.write_bytes(text.encode() if isinstance(text, str) else text)
    return p
