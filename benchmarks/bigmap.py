"""The benchmark map: 1,000,000 points, 20,000 lines and 200 objects, made deterministically.

Used by every benchmark that needs "the 1,000,000-point benchmark map". Points lie on a 20 mm
lattice along the walls of a grid of rooms (like a scanned building), lines are the walls'
segments, objects are goals (names with spaces), goals with heading, forbidden areas (some
rotated), forbidden lines, a dock and a home.

    python benchmarks/bigmap.py OUT.map      # writes the map and prints its size
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from mapkit import MapData, MapObject, Scan, save  # noqa: E402

N_POINTS = 1_000_000
N_LINES = 20_000
N_OBJECTS = 200


def make_big_map(seed: int = 1) -> MapData:
    """The benchmark map as a :class:`MapData` (same every call)."""
    rng = np.random.default_rng(seed)
    # A 100 x 100 m building of 5 m rooms: walls every 5000 mm in x and y, doors left out.
    side, room = 100_000, 5_000
    n_walls = 2 * (side // room + 1)
    per_wall = N_POINTS // n_walls + 1
    pts = []
    for k in range(side // room + 1):
        c = k * room
        t = rng.integers(0, side // 20, per_wall) * 20
        jitter = rng.integers(-2, 3, per_wall) * 20
        pts.append(np.stack([np.full(per_wall, c) + jitter, t], axis=1))
        pts.append(np.stack([t, np.full(per_wall, c) + jitter], axis=1))
    points = np.concatenate(pts)[:N_POINTS] - side // 2
    # Lines: short wall segments along the same walls.
    starts = rng.integers(0, side // 20, N_LINES) * 20 - side // 2
    walls = rng.integers(0, side // room + 1, N_LINES) * room - side // 2
    length = rng.integers(5, 100, N_LINES) * 20
    horizontal = rng.random(N_LINES) < 0.5
    x1 = np.where(horizontal, starts, walls)
    y1 = np.where(horizontal, walls, starts)
    x2 = np.where(horizontal, starts + length, walls)
    y2 = np.where(horizontal, walls, starts + length)
    lines = np.stack([x1, y1, x2, y2], axis=1)
    objects = [
        MapObject("RobotHome", -47500, -47500, 0, name="Home"),
        MapObject("Dock", -47500, -45000, 90, name="Dock 1"),
    ]
    centres = [
        ((i % 19) * room - side // 2 + room // 2, (i // 19) * room - side // 2 + room // 2)
        for i in range(N_OBJECTS - 2)
    ]
    return _with_objects(points, lines, objects, centres, turn_back=False)


def _with_objects(
    points: np.ndarray,
    lines: np.ndarray,
    objects: list[MapObject],
    centres: list[tuple[int, int]],
    *,
    turn_back: bool,
) -> MapData:
    """The map of these points and lines, with ``objects`` and one object per room centre.

    Goals, goals with heading, forbidden areas (some turned 30 degrees) and forbidden lines in
    turn. ARIA turns a rectangle about the map origin: with ``turn_back`` the area's corners are
    given turned back, so the turned area lands in its room.
    """
    for i, (cx, cy) in enumerate(centres):
        kind = i % 4
        if kind == 0:
            objects.append(MapObject("Goal", cx, cy, 0, name=f"Goal room {i}"))
        elif kind == 1:
            objects.append(
                MapObject("GoalWithHeading", cx, cy, (i * 37) % 360 - 179, name=f"Station {i} west")
            )
        elif kind == 2:
            angle = 0.0 if i % 8 == 2 else 30.0
            ux, uy = cx, cy
            if turn_back:
                th = np.radians(angle)
                ux = round(cx * np.cos(th) + cy * np.sin(th))
                uy = round(-cx * np.sin(th) + cy * np.cos(th))
            objects.append(
                MapObject(
                    "ForbiddenArea",
                    0,
                    0,
                    angle,
                    name=f"Keep out {i}",
                    from_to=(ux - 600, uy - 400, ux + 600, uy + 400),
                )
            )
        else:
            objects.append(
                MapObject(
                    "ForbiddenLine",
                    cx - 1000,
                    cy + 1500,
                    0,
                    from_to=(cx - 1000, cy + 1500, cx + 1000, cy + 1500),
                )
            )
    scan = Scan.from_arrays(points, lines, resolution=20)
    return MapData(
        scans=(scan,),
        objects=tuple(objects),
        info={
            "MapInfo": [
                ("GoalType", "Name=Goal"),
                ("GoalType", "Name=GoalWithHeading"),
                ("DockType", "Name=Dock"),
            ]
        },
    )


#: The big site of issue 16: a 415 x 270 m warehouse (at 2 cm: a 20,768 x 13,612 grid).
SITE_MM = (415_000, 270_000)


def make_site_map(size_mm: tuple[int, int] = SITE_MM, seed: int = 1) -> MapData:
    """The benchmark map scaled out to a site of ``size_mm``, at the same density.

    The same building of 5 m rooms, with as many points and lines per metre of wall and as many
    objects per square metre as :func:`make_big_map` (the 415 x 270 m site has 10.8 M points,
    216,000 lines and 2,241 objects). The site's lower-left corner is at (0, 0).
    """
    rng = np.random.default_rng(seed)
    room = 5_000
    sx, sy = size_mm
    nx, ny = sx // room + 1, sy // room + 1  # walls across x (vertical) and across y
    wall_mm = nx * sy + ny * sx
    per_mm = N_POINTS / (2 * (100_000 // room + 1) * 100_000)  # the 1M map's density
    pts = []
    for k in range(nx):  # vertical walls at x = k * room
        n = int(per_mm * sy)
        t = rng.integers(0, sy // 20, n) * 20
        pts.append(np.stack([k * room + rng.integers(-2, 3, n) * 20, t], axis=1))
    for k in range(ny):  # horizontal walls at y = k * room
        n = int(per_mm * sx)
        t = rng.integers(0, sx // 20, n) * 20
        pts.append(np.stack([t, k * room + rng.integers(-2, 3, n) * 20], axis=1))
    points = np.concatenate(pts)
    n_lines = int(N_LINES * wall_mm / (2 * 21 * 100_000))
    horizontal = rng.random(n_lines) < 0.5
    starts = (
        np.where(horizontal, rng.integers(0, sx // 20, n_lines), rng.integers(0, sy // 20, n_lines))
        * 20
    )
    walls = np.where(horizontal, rng.integers(0, ny, n_lines), rng.integers(0, nx, n_lines)) * room
    length = rng.integers(5, 100, n_lines) * 20
    x1 = np.where(horizontal, starts, walls)
    y1 = np.where(horizontal, walls, starts)
    x2 = np.where(horizontal, np.minimum(starts + length, sx), walls)
    y2 = np.where(horizontal, walls, np.minimum(starts + length, sy))
    lines = np.stack([x1, y1, x2, y2], axis=1)
    objects = [
        MapObject("RobotHome", 2500, 2500, 0, name="Home"),
        MapObject("Dock", 2500, 5000 + 2500, 90, name="Dock 1"),
    ]
    rooms_x, rooms_y = sx // room, sy // room
    n_obj = int((N_OBJECTS - 2) * (sx * sy) / (100_000 * 100_000))
    centres = [
        ((i % rooms_x) * room + room // 2, (i // rooms_x) % rooms_y * room + room // 2)
        for i in range(n_obj)
    ]
    return _with_objects(points, lines, objects, centres, turn_back=True)


def write_site_map(path: Path) -> Path:
    """Write the site map to ``path`` (if it is not there already) and return the path."""
    if not path.exists():
        save(make_site_map(), path)
    return path


def write_big_map(path: Path) -> Path:
    """Write the benchmark map to ``path`` (if it is not there already) and return the path."""
    if not path.exists():
        save(make_big_map(), path)
    return path


if __name__ == "__main__":
    out = Path(sys.argv[1] if len(sys.argv) > 1 else "bigmap.map")
    if out.exists():
        out.unlink()
    write_big_map(out)
    print(f"{out}: {out.stat().st_size / 1e6:.1f} MB")
