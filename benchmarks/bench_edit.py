"""Edit benchmarks on the 1,000,000-point benchmark map, as ratios to reading + writing it.

The baseline is what every ``mapkit`` edit command pays anyway: parsing the map's bytes and
writing them back (``loads(dumpb(m))``), measured in the same run. Each edit is timed on the map
in memory (best of a few runs) and printed as seconds and as a multiple of the baseline.

    python benchmarks/bench_edit.py            # all edits
    python benchmarks/bench_edit.py --quick    # one run each
"""

from __future__ import annotations

import sys
from collections.abc import Callable
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from _timing import best  # noqa: E402
from bigmap import make_big_map  # noqa: E402

from mapkit import edit  # noqa: E402
from mapkit.edit.selection import points_inside  # noqa: E402
from mapkit.formats.map import dumpb, loads  # noqa: E402
from mapkit.model import MapData  # noqa: E402


def main() -> None:
    runs = 1 if "--quick" in sys.argv else 3
    m = make_big_map()
    data = dumpb(m)
    print(
        f"benchmark map: {m.scan.num_points} points, {m.scan.num_lines} lines, "
        f"{len(m.objects)} objects, {len(data) / 1e6:.1f} MB"
    )
    base = best(lambda: dumpb(loads(data)), runs)
    print(f"baseline  read + write the map: {base:.3f} s (= 1.00)")
    box = edit.Region.box(-20_000, -20_000, 20_000, 20_000)  # 16% of the building
    poly = edit.Region.polygon(
        [(-30_000, -30_000), (25_000, -20_000), (10_000, 30_000), (-20_000, 15_000), (-35_000, 0)]
    )
    erased = edit.erase(m, box)
    other = edit.transform(m, translate=(20, 0))
    cases: list[tuple[str, Callable[[], MapData | object]]] = [
        ("add-goal (objects only)", lambda: edit.add_goal(m, "New goal", 0, 0)),
        ("remove one object", lambda: edit.remove(m, "Goal room 0")),
        ("erase --box", lambda: edit.erase(m, box)),
        ("erase --polygon (5 vertices)", lambda: edit.erase(m, poly)),
        ("crop --box", lambda: edit.crop(m, box)),
        (
            "draw-line --as-points (10 m)",
            lambda: edit.draw_line(m, 0, 0, 10_000, 0, as_points=True),
        ),
        ("transform --rotate 90", lambda: edit.transform(m, rotate=90)),
        (
            "transform --rotate 30 --translate",
            lambda: edit.transform(m, rotate=30, translate=(5, 5)),
        ),
        ("transform --recenter", lambda: edit.transform(m, recenter=True)),
        ("merge --region (box)", lambda: edit.merge(m, other, region=box)),
        ("merge (no region, 1M new rows)", lambda: edit.merge(m, other)),
        ("diff A A", lambda: edit.diff(m, m)),
        ("diff A erase(A)", lambda: edit.diff(m, erased)),
        ("diff A transform(A)", lambda: edit.diff(m, other)),
    ]
    for label, fn in cases:
        t = best(fn, runs)
        print(f"{label:<36} {t:8.3f} s  {t / base:6.2f} x baseline")
    # The vectorised point test against a Python loop over the same points (a sample of 20,000).
    from matplotlib.path import Path as MplPath

    sample = m.points[:20_000]
    mpl = MplPath(poly.vertices)
    loop = best(lambda: [mpl.contains_point(tuple(p)) for p in sample.tolist()], 1)
    vec = best(lambda: points_inside(sample, poly), runs)
    print(
        f"points in polygon, 20,000 points: vectorised {vec * 1e3:.1f} ms, "
        f"Python loop {loop * 1e3:.1f} ms ({loop / max(vec, 1e-9):.0f}x)"
    )
    assert np.array_equal(edit.erase(m, box).points, erased.points)


if __name__ == "__main__":
    main()
