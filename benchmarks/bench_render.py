"""Benchmark: pictures and meshes of the 1,000,000-point benchmark map, against reading it.

Prints each step's wall time and its ratio to reading the same map with ``mapkit.load`` (the
baseline, measured in the same run). Each step is timed as the best of ``--repeat`` runs.

    python benchmarks/bench_render.py [--repeat N] [--keep DIR]
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
from mapkit.mesh import export_mesh, wall_mesh  # noqa: E402
from mapkit.render import render  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--keep", type=Path, help="Write the outputs here (default: a temp folder).")
    args = ap.parse_args()
    out = args.keep or Path(tempfile.mkdtemp(prefix="mapkit-bench-"))
    out.mkdir(parents=True, exist_ok=True)
    src = write_big_map(out / "bigmap.map")
    m = mapkit.load(src)
    # Warm up the lazy imports (matplotlib, trimesh, shapely) so they are not timed.
    render(mapkit.MapData(), out / "warm.png", width=300)
    wall_mesh(mapkit.MapData(scans=(mapkit.Scan.from_arrays(lines=[[0, 0, 1, 0]]),)))

    base = best(lambda: mapkit.load(src), args.repeat)
    steps = {
        "render PNG 1600 px": lambda: render(m, out / "big.png"),
        "render PNG 4000 px": lambda: render(m, out / "big4k.png", width=4000),
        "render SVG 1600 px": lambda: render(m, out / "big.svg"),
        "render PDF 1600 px": lambda: render(m, out / "big.pdf"),
        "thumbnail PNG 320 px": lambda: render(m, out / "thumb.png", width=320, thumbnail=True),
        "mesh from 20,000 lines (in memory)": lambda: wall_mesh(m),
        "mesh STL + SDF world": lambda: export_mesh(m, out / "big.stl", world=out / "big.sdf"),
        "mesh GLB": lambda: export_mesh(m, out / "big.glb"),
    }
    print(
        f"map: {src.name}, {m.scan.num_points:,} points, {m.scan.num_lines:,} lines, "
        f"{len(m.objects)} objects ({src.stat().st_size / 1e6:.1f} MB)"
    )
    print(f"{'step':38s} {'seconds':>8s} {'x read':>7s}")
    print(f"{'read (mapkit.load), the baseline':38s} {base:8.3f} {1.0:7.2f}")
    for name, fn in steps.items():
        t = best(fn, args.repeat)
        print(f"{name:38s} {t:8.3f} {t / base:7.2f}")
    print(f"outputs in {out}")


if __name__ == "__main__":
    main()
