"""Benchmark: validating the 1,000,000-point benchmark map with reachability at 300 mm radius.

Prints each figure as a ratio against reading the same map (``mapkit.load``) in the same run, so
the numbers compare across machines:

    python benchmarks/bench_validate.py [--repeat N]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from _timing import best  # noqa: E402
from bigmap import write_big_map  # noqa: E402

import mapkit  # noqa: E402
from mapkit.validate import validate  # noqa: E402

RADIUS = 300.0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        path = write_big_map(Path(tmp) / "bigmap.map")
        m = mapkit.load(path)
        report = validate(m, robot_radius=RADIUS)
        nav = report.checked["navigation"]
        print(
            f"map: {m.scan.num_points:,} points, {m.scan.num_lines:,} lines, "
            f"{len(m.objects)} objects; findings {report.counts()}; "
            f"navigation grid {nav['grid'][0]} x {nav['grid'][1]} cells "
            f"of {nav['cell_mm']:.0f} mm, {nav['reachable']} of {nav['targets']} goals reachable"
        )
        t_load = best(lambda: mapkit.load(path), args.repeat)
        rows = [
            ("read (mapkit.load), the baseline", t_load),
            (
                "validate(map) without navigation",
                best(lambda: validate(m, navigation=False), args.repeat),
            ),
            (
                f"validate(map), reachability at {RADIUS:.0f} mm",
                best(lambda: validate(m, robot_radius=RADIUS), args.repeat),
            ),
            (
                f"validate(path): read + all checks at {RADIUS:.0f} mm",
                best(lambda: validate(path, robot_radius=RADIUS), args.repeat),
            ),
        ]
    width = max(len(name) for name, _ in rows)
    for name, t in rows:
        print(f"{name:<{width}}  {t:6.2f} s  {t / t_load:5.2f} x read")


if __name__ == "__main__":
    main()
