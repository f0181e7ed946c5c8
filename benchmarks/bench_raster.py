"""Rasteriser and ROS import benchmark: figures as ratios against reading the same map.

    python benchmarks/bench_raster.py [--repeat N]

1. The 1,000,000-point benchmark map (``benchmarks/bigmap.py``): read it (baseline), then
   rasterise it at 0.05 m and write the PGM + YAML (``export_ros``).
2. A 4000 x 4000 ROS map (the benchmark map rasterised at 0.025 m, cropped): import it
   (``import_ros``: read the PGM, points, wall lines) and compare with reading the .map the
   import produces.

Each figure is the best of ``--repeat`` runs (the machine is shared).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from bigmap import write_big_map  # noqa: E402

import mapkit  # noqa: E402
from mapkit.raster import OccupancyGrid, rasterize  # noqa: E402
from mapkit.raster.export import export_ros  # noqa: E402
from mapkit.raster.import_ros import import_ros  # noqa: E402
from mapkit.raster.ros import read_ros_map, write_ros_map  # noqa: E402


def best(fn, repeat: int) -> tuple[float, object]:
    out, times = None, []
    for _ in range(repeat):
        t = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t)
    return min(times), out


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        big = write_big_map(folder / "bigmap.map")
        t_read, m = best(lambda: mapkit.load(big), args.repeat)
        rasterize(m, 0.05)  # warm up (scipy imports)
        t_ras, g = best(lambda: rasterize(m, 0.05), args.repeat)
        t_exp, _res = best(lambda: export_ros(m, folder / "big.yaml"), args.repeat)
        print(
            f"read bigmap.map ({m.scan.num_points:,} points, {m.scan.num_lines:,} lines): "
            f"{t_read:.3f} s (baseline)"
        )
        print(
            f"rasterise at 0.05 m ({g.width} x {g.height}):            {t_ras:.3f} s = "
            f"{t_ras / t_read:.2f} x read"
        )
        print(
            f"rasterise + write PGM + YAML:                     {t_exp:.3f} s = "
            f"{t_exp / t_read:.2f} x read"
        )

        fine = rasterize(m, 0.025, margin_m=0)
        crop = OccupancyGrid(fine.data[:4000, :4000], fine.resolution, fine.origin)
        files = write_ros_map(crop, folder / "ros4000.yaml")
        t_rosread, _ = best(lambda: read_ros_map(files.yaml), args.repeat)
        t_imp, back = best(lambda: import_ros(files.yaml), args.repeat)
        mapkit.save(back, folder / "imported.map")
        t_mread, _ = best(lambda: mapkit.load(folder / "imported.map"), args.repeat)
        print(
            f"read imported.map ({back.scan.num_points:,} points, {back.scan.num_lines:,} lines): "
            f"{t_mread:.3f} s (baseline)"
        )
        print(
            f"read the {crop.width} x {crop.height} ROS map as a grid:         {t_rosread:.3f} s = "
            f"{t_rosread / t_mread:.2f} x read"
        )
        print(
            f"import-ros of it (points + wall lines):            {t_imp:.3f} s = "
            f"{t_imp / t_mread:.2f} x read"
        )


if __name__ == "__main__":
    main()
