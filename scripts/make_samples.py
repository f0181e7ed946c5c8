#!/usr/bin/env python3
"""Make the maps bundled in ``mapkit/sample_maps/`` (deterministic: same bytes every run).

    python scripts/make_samples.py            # rewrite every sample
    python scripts/make_samples.py --check    # exit 1 if a sample differs from what this makes

* ``office.map`` — a small office floor (20 x 12 m): walls as LINES and as scanned points on
  ARIA's 20 mm lattice, goals with and without heading, RobotHome, a Dock, a rotated forbidden area
  and a forbidden line.
* ``building.map`` — a larger multi-room floor (60 x 40 m, ``2D-Map-Ex2``): corridors and rooms,
  many goals, docks, forbidden areas and lines, and a speed-limit sector type with a parameter.

* ``office-loop.2d`` — a laser log (version 4, 361 readings) simulated by driving the office from
  home past every goal and back home, with drifting odometry and ``loop: start 1`` /
  ``loop: stop 1`` tags: input for ``mapkit build`` with a loop to close.
  ``office-loop.truth.tsv`` beside it holds the true pose of every scan.
* ``building-labs.2d`` — a version 3 log (181 readings) of the building from home through the
  corridors and six labs (no loop), with ``building-labs.truth.tsv``.

The maps are written by mapkit's canonical writer, i.e. exactly as ARIA's ``ArMap::writeFile`` would
write them, so they load in ARIA as they load in mapkit.
"""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Callable
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from mapkit import MapData, MapObject, Scan, dumpb  # noqa: E402
from mapkit._atomic import atomic_write  # noqa: E402

OUT = ROOT / "mapkit" / "sample_maps"
RES = 20  # mm, the lattice of scanned ARIA maps

Wall = tuple[float, float, float, float]


def rect_walls(x1: float, y1: float, x2: float, y2: float) -> list[Wall]:
    """The four walls of an axis-aligned room."""
    return [(x1, y1, x2, y1), (x2, y1, x2, y2), (x2, y2, x1, y2), (x1, y2, x1, y1)]


def cut_door(walls: list[Wall], x: float, y: float, width: float) -> list[Wall]:
    """Cut a door of ``width`` centred on (x, y) out of whichever axis-aligned wall passes there."""
    out: list[Wall] = []
    for w in walls:
        x1, y1, x2, y2 = w
        if y1 == y2 == y and min(x1, x2) < x < max(x1, x2):
            lo, hi = sorted((x1, x2))
            out += [(lo, y, x - width / 2, y), (x + width / 2, y, hi, y)]
        elif x1 == x2 == x and min(y1, y2) < y < max(y1, y2):
            lo, hi = sorted((y1, y2))
            out += [(x, lo, x, y - width / 2), (x, y + width / 2, x, hi)]
        else:
            out.append(w)
    return out


def scan_points(walls: list[Wall], rng: np.random.Generator, thickness: int = 1) -> np.ndarray:
    """Points as a laser scan would leave them: wall cells on the 20 mm lattice, de-duplicated."""
    chunks = []
    for x1, y1, x2, y2 in walls:
        n = max(2, int(math.hypot(x2 - x1, y2 - y1) / (RES / 2)))
        t = np.linspace(0.0, 1.0, n)
        xy = np.stack([x1 + t * (x2 - x1), y1 + t * (y2 - y1)], axis=1)
        xy += rng.normal(0.0, 6.0, xy.shape)  # range noise of a real scan
        chunks.append(xy)
        for k in range(1, thickness):
            chunks.append(xy + rng.normal(0.0, 10.0 * k, xy.shape))
    pts = np.rint(np.concatenate(chunks) / RES).astype(np.int64) * RES
    pts = np.unique(pts, axis=0)
    keep = rng.random(len(pts)) > 0.06  # a scan misses some cells
    return pts[keep]


def clutter(rng: np.random.Generator, boxes: list[Wall], per_box: int) -> np.ndarray:
    """Furniture: a few points scattered on the outline of small boxes."""
    pts = []
    for x1, y1, x2, y2 in boxes:
        for w in rect_walls(x1, y1, x2, y2):
            n = per_box // 4
            t = rng.random(n)
            pts.append(np.stack([w[0] + t * (w[2] - w[0]), w[1] + t * (w[3] - w[1])], axis=1))
    if not pts:
        return np.zeros((0, 2), np.int64)
    return np.rint(np.concatenate(pts) / RES).astype(np.int64) * RES


def rotated_area(
    name: str, cx: float, cy: float, width: float, height: float, angle: float
) -> MapObject:
    """A ForbiddenArea that covers the rectangle centred at (cx, cy) turned by ``angle``.

    ARIA stores the corners in a frame rotated by theta about the map origin, so the stored centre
    is the world centre turned back by theta.
    """
    c, s = math.cos(math.radians(angle)), math.sin(math.radians(angle))
    sx, sy = c * cx + s * cy, -s * cx + c * cy
    return MapObject(
        "ForbiddenArea",
        0,
        0,
        angle,
        name=name,
        from_to=(
            round(sx - width / 2),
            round(sy - height / 2),
            round(sx + width / 2),
            round(sy + height / 2),
        ),
    )


def office() -> MapData:
    """The small office floor."""
    rng = np.random.default_rng(20261121)
    walls = rect_walls(0, 0, 20000, 12000)
    # corridor along y = 5000..7000; four offices north, kitchen and meeting room south
    walls += [(0, 7000, 20000, 7000), (0, 5000, 14000, 5000)]
    walls += [(5000, 7000, 5000, 12000), (10000, 7000, 10000, 12000), (15000, 7000, 15000, 12000)]
    walls += [(7000, 0, 7000, 5000), (14000, 0, 14000, 5000)]
    for x in (2500, 7500, 12500, 17500):
        walls = cut_door(walls, x, 7000, 900)
    walls = cut_door(walls, 3500, 5000, 1200)
    walls = cut_door(walls, 10500, 5000, 1200)
    walls = cut_door(walls, 0, 6000, 1600)  # entrance (west)
    lines = np.rint(np.array(walls)).astype(np.int64)
    furniture = [
        (1000, 8500, 3000, 9300),
        (6000, 10500, 8000, 11300),
        (11000, 8200, 12600, 9000),
        (16000, 10000, 18500, 11000),
        (2000, 1500, 5000, 3000),
        (9000, 1500, 12000, 3500),
    ]
    points = np.concatenate([scan_points(walls, rng), clutter(rng, furniture, 160)])
    scan = Scan.from_arrays(points, lines, resolution=RES, sort=True)
    objects = (
        MapObject("RobotHome", 1500, 6000, 0, name="Home"),
        MapObject("Dock", 19000, 6000, 180, name="Charger"),
        MapObject("Goal", 4000, 6000, 0, name="Corridor west"),
        MapObject("GoalWithHeading", 2500, 9800, 90, name="Office 1"),
        MapObject("GoalWithHeading", 7500, 9800, 90, name="Office 2"),
        MapObject("GoalWithHeading", 12500, 9800, 90, name="Office 3"),
        MapObject("GoalWithHeading", 17500, 9800, 90, name="Office 4"),
        MapObject("GoalWithHeading", 3500, 3800, -90, name="Kitchen"),
        MapObject("Goal", 10500, 3800, 0, name="Meeting room"),
        rotated_area("Printer corner", 17000, 2500, 1600, 1000, 30),
        MapObject("ForbiddenLine", 14000, 5600, 0, from_to=(14000, 5000, 14000, 7000)),
    )
    info = {
        "MapInfo": [
            ("GoalType", "Name=Goal", '"Label=Goal"'),
            ("GoalType", "Name=GoalWithHeading", '"Label=Goal with heading"', "Heading=Required"),
            ("DockType", "Name=Dock", '"Label=Dock"', "Heading=Required"),
        ]
    }
    return MapData(category="2D-Map", scans=(scan,), objects=objects, info=info)


def building() -> MapData:
    """The larger multi-room floor: two corridors, 18 rooms, a hall and a speed-limit sector."""
    rng = np.random.default_rng(4242)
    w, h = 60000, 40000
    walls = rect_walls(0, 0, w, h)
    walls += [(0, 12000, w, 12000), (0, 15000, 45000, 15000)]  # south corridor 12..15 m
    walls += [(0, 25000, 45000, 25000), (0, 28000, w, 28000)]  # north corridor 25..28 m
    walls += [(45000, 15000, 45000, 25000)]  # east hall x 45..60 m between corridors
    rooms_south = [(x, 0, x + 7500, 12000) for x in range(0, w, 7500)]
    rooms_north = [(x, 28000, x + 10000, h) for x in range(0, w, 10000)]
    for x1, _y1, _x2, _y2 in rooms_south[1:]:
        walls.append((x1, 0, x1, 12000))
    for x1, _y1, _x2, _y2 in rooms_north[1:]:
        walls.append((x1, 28000, x1, h))
    walls += [(x, 15000, x, 25000) for x in (15000, 30000)]  # three inner rooms
    goals = []
    for i, (x1, _y1, x2, _y2) in enumerate(rooms_south):
        cx = (x1 + x2) / 2
        walls = cut_door(walls, cx, 12000, 1000)
        goals.append(MapObject("GoalWithHeading", cx, 9000, -90, name=f"Lab S{i + 1}"))
    for i, (x1, _y1, x2, _y2) in enumerate(rooms_north):
        cx = (x1 + x2) / 2
        walls = cut_door(walls, cx, 28000, 1000)
        goals.append(MapObject("GoalWithHeading", cx, 31500, 90, name=f"Office N{i + 1}"))
    for i, cx in enumerate((7500, 22500, 37500)):
        walls = cut_door(walls, cx, 15000, 1200)
        walls = cut_door(walls, cx - 3000, 25000, 1200)
        goals.append(MapObject("Goal", cx, 20000, 0, name=f"Room C{i + 1}"))
    walls = cut_door(walls, 45000, 13500 + 6000, 2500)  # hall opening
    walls = cut_door(walls, 52000, 12000, 2000)
    walls = cut_door(walls, 52000, 28000, 2000)
    lines = np.rint(np.array(walls)).astype(np.int64)
    furniture = [(x + 1500, 2000, x + 4500, 3500) for x in range(0, w, 7500)]
    furniture += [(x + 2000, 36000, x + 6000, 38000) for x in range(0, w, 10000)]
    furniture += [(48000, 17000, 50000, 19000), (55000, 21000, 57500, 23500)]
    points = np.concatenate([scan_points(walls, rng, thickness=2), clutter(rng, furniture, 240)])
    scan = Scan.from_arrays(points, lines, resolution=RES, sort=True)
    objects = [
        MapObject("RobotHome", 2000, 13500, 0, name="Home"),
        MapObject("Dock", 59000, 13500, 180, name="Dock east"),
        MapObject("Dock", 1000, 26500, 0, name="Dock west"),
        MapObject("Goal", 30000, 13500, 0, name="Corridor south"),
        MapObject("Goal", 30000, 26500, 0, name="Corridor north"),
        MapObject("GoalWithHeading", 52500, 20000, 45, name="Hall"),
        *goals,
        rotated_area("Loading bay", 53000, 36000, 4000, 2500, -20),
        rotated_area("Server racks", 25500, 6000, 3000, 1500, 0),
        MapObject("ForbiddenLine", 45000, 12000, 0, from_to=(45000, 12000, 45000, 15000)),
        MapObject("ForbiddenLine", 15000, 25000, 0, from_to=(15000, 25000, 15000, 28000)),
        MapObject(
            "SpeedLimitSector", 0, 0, 0, name="Hall slow zone", from_to=(46000, 16000, 59000, 24000)
        ),
        MapObject(
            "SpeedLimitSector",
            0,
            0,
            0,
            name="Corridor crossing",
            from_to=(43000, 12000, 47000, 15000),
        ),
    ]
    info = {
        "MapInfo": [
            ("GoalType", "Name=Goal", '"Label=Goal"'),
            ("GoalType", "Name=GoalWithHeading", '"Label=Goal with heading"', "Heading=Required"),
            ("DockType", "Name=Dock", '"Label=Dock"', "Heading=Required"),
            (
                "SectorType",
                "Name=SpeedLimitSector",
                '"Label=Speed limit"',
                "Shape=Plain",
                "Color0=0xffa000",
                "Vis=AlwaysOn",
            ),
            (
                "ArgDesc",
                "Name=MaxSpeed",
                "Parent=SpeedLimitSector",
                "Priority=Important",
                "Type=int",
                "Value=500",
                "Min=0",
                "Max=2000",
                '"Desc=Maximum speed in mm/s"',
            ),
        ],
        "CairnInfo": [
            ("Params", '"Corridor crossing"', "300"),
            ("Params", '"Hall slow zone"', "250"),
        ],
    }
    return MapData(category="2D-Map-Ex2", scans=(scan,), objects=tuple(objects), info=info)


SAMPLES: dict[str, Callable[[], MapData]] = {"office.map": office, "building.map": building}


def office_loop() -> tuple[bytes, bytes]:
    """The office log with a loop: (.2d bytes, truth sidecar bytes)."""
    from mapkit.formats.laser2d import dumps_log
    from mapkit.simulate import simulate_log

    sim = simulate_log(office(), loop=True, seed=1, version=4)
    return dumps_log(sim.log).encode(), sim.truth_text("office-loop.2d").encode()


def building_labs() -> tuple[bytes, bytes]:
    """The building log through six labs, version 3."""
    from mapkit.formats.laser2d import dumps_log
    from mapkit.simulate import simulate_log

    b = building()
    goals = [o for o in b.objects if o.is_point and o.base_type == "Goal"][:6]
    home = [o for o in b.objects if o.type == "RobotHome"]
    sim = simulate_log(b.replace(objects=tuple(home + goals)), seed=2, version=3, readings=181)
    return dumps_log(sim.log).encode(), sim.truth_text("building-labs.2d").encode()


#: Laser logs simulated from the sample maps: name -> (.2d bytes, truth bytes).
LOG_SAMPLES: dict[str, Callable[[], tuple[bytes, bytes]]] = {
    "office-loop.2d": office_loop,
    "building-labs.2d": building_labs,
}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--check", action="store_true", help="only compare, write nothing")
    args = parser.parse_args()
    OUT.mkdir(parents=True, exist_ok=True)
    stale = []
    outputs: list[tuple[str, Callable[[], bytes]]] = [
        (name, lambda make=make: dumpb(make())) for name, make in SAMPLES.items()
    ]
    for name, make_log in LOG_SAMPLES.items():
        made: dict[str, bytes] = {}

        def part(
            k: int,
            make_log: Callable[[], tuple[bytes, bytes]] = make_log,
            made: dict[str, bytes] = made,
        ) -> bytes:
            if not made:
                made["log"], made["truth"] = make_log()
            return made["log" if k == 0 else "truth"]

        outputs.append((name, lambda part=part: part(0)))
        outputs.append((name[:-3] + ".truth.tsv", lambda part=part: part(1)))
    for name, produce in outputs:
        data = produce()
        path = OUT / name
        if args.check:
            if not path.exists() or path.read_bytes() != data:
                stale.append(name)
            continue
        atomic_write(path, data)
        print(f"{path.relative_to(ROOT)}: {len(data)} bytes")
    if stale:
        print("stale samples (run scripts/make_samples.py):", ", ".join(stale))
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
