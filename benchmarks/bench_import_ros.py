"""import-ros in row bands: time and peak memory against the whole-image path, and a warehouse.

    python benchmarks/bench_import_ros.py [--repeat N] [--width W --height H] [--skip-site]

A synthetic warehouse PGM (2 cm cells: outer walls, racks drawn as their faces, scattered
clutter, an unmapped corner) is written in row bands, then:

1. at ``--width`` x ``--height`` (default 8,000 x 5,000: 40 M cells, a size the whole-image path
   still handles), ``import_ros`` (streamed in row bands) against the whole-image path
   (``read_ros_map`` + ``grid_to_map``, the grid held whole): best time of ``--repeat`` runs
   and peak resident memory, each in a fresh process; the two maps must be identical;
2. the 415 x 270 m site at 2 cm (20,768 x 13,612 = 282 M cells; ROS 1 map_server runs out of
   memory on it): streamed import only, time and peak memory.

Peak memory is the child process's ``ru_maxrss``; an idle ``import mapkit, numpy`` process is
measured in the same run as the floor.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
SITE = (20_768, 13_612)  # 415 x 270 m at 2 cm

CHILD = r"""
import json, resource, sys, time
sys.path.insert(0, {root!r})
import numpy as np
from mapkit.raster.import_ros import grid_to_map, import_ros
from mapkit.raster.ros import read_ros_map
how, path = sys.argv[1], sys.argv[2]
t = time.perf_counter()
if how == "streamed":
    m = import_ros(path)
elif how == "whole":
    m = grid_to_map(read_ros_map(path))
else:
    m = None
dt = time.perf_counter() - t
if m is not None and len(sys.argv) > 3:
    np.savez(sys.argv[3], points=m.points, lines=m.lines)
rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
print(json.dumps({{"s": dt, "rss": rss,
                  "points": 0 if m is None else m.scan.num_points,
                  "lines": 0 if m is None else m.scan.num_lines}}))
"""


def write_warehouse(
    yaml_path: Path, width: int, height: int, *, res: float = 0.02, band: int = 512, seed: int = 7
) -> Path:
    """A warehouse-like map_server map, written in row bands (bounded memory)."""
    rng = np.random.default_rng(seed)
    pgm = yaml_path.with_suffix(".pgm")
    rack_pitch, rack_depth, aisle_every, aisle = 150, 55, 1200, 160  # cells (3 m, 1.1 m ...)
    with open(pgm, "wb") as fh:
        fh.write(f"P5\n# warehouse {width}x{height} at {res} m\n{width} {height}\n255\n".encode())
        cols = np.arange(width)
        in_aisle = (cols % aisle_every) < aisle
        for top in range(0, height, band):
            rows = np.arange(top, min(height, top + band))[:, None]
            img = np.full((len(rows), width), 254, dtype=np.uint8)
            y = rows % rack_pitch
            face = (y == 40) | (y == 41) | (y == 40 + rack_depth) | (y == 41 + rack_depth)
            ends = ((cols % aisle_every) == aisle) | ((cols % aisle_every) == aisle_every - 1)
            inside = (y > 41) & (y < 40 + rack_depth)
            img[(face & ~in_aisle) | (inside & ends & ~in_aisle)] = 0
            clutter = rng.random(img.shape) < 2e-4
            img[clutter] = 0
            wall = (rows < 12) | (rows >= height - 12) | (cols < 12) | (cols >= width - 12)
            img[wall] = 0
            corner = (rows < height // 6) & (cols > width - width // 5)  # unmapped
            img[corner] = 205
            fh.write(img.tobytes())
    yaml_path.write_text(
        f"image: {pgm.name}\nmode: trinary\nresolution: {res}\n"
        "origin: [-10.0, -5.0, 0.0]\nnegate: 0\noccupied_thresh: 0.65\n"
        "free_thresh: 0.196\n"
    )
    return yaml_path


def run(how: str, path: Path, save: Path | None = None) -> dict[str, float]:
    cmd = [sys.executable, "-c", CHILD.format(root=str(ROOT)), how, str(path)]
    if save is not None:
        cmd.append(str(save))
    out = subprocess.run(cmd, check=True, capture_output=True, text=True)
    return dict(json.loads(out.stdout.strip().splitlines()[-1]))


def best_of(how: str, path: Path, repeat: int, save: Path | None = None) -> dict[str, float]:
    runs = [run(how, path, save if i == 0 else None) for i in range(repeat)]
    return {
        "s": min(r["s"] for r in runs),
        "rss": max(r["rss"] for r in runs),
        "points": runs[0]["points"],
        "lines": runs[0]["lines"],
    }


def mb(n: float) -> str:
    return f"{n / 2**20:,.0f} MB"


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--width", type=int, default=8_000)
    ap.add_argument("--height", type=int, default=5_000)
    ap.add_argument("--skip-site", action="store_true", help="skip the 282 M-cell site")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        floor = run("none", folder)
        print(f"idle process (import mapkit, numpy): {mb(floor['rss'])}")
        y = write_warehouse(folder / "mid.yaml", args.width, args.height)
        cells = args.width * args.height
        whole = best_of("whole", y, args.repeat, folder / "whole.npz")
        streamed = best_of("streamed", y, args.repeat, folder / "streamed.npz")
        a, b = np.load(folder / "whole.npz"), np.load(folder / "streamed.npz")
        same = all(np.array_equal(a[k], b[k]) for k in ("points", "lines"))
        print(
            f"{args.width} x {args.height} ({cells / 1e6:.0f} M cells): "
            f"{int(streamed['points']):,} points, {int(streamed['lines']):,} lines; "
            f"identical to the whole-image path: {same}"
        )
        print(f"  whole image : {whole['s']:7.2f} s  peak {mb(whole['rss'])}")
        print(f"  row bands   : {streamed['s']:7.2f} s  peak {mb(streamed['rss'])}")
        print(
            f"  ratio bands/whole: time {streamed['s'] / whole['s']:.2f}x, peak memory "
            f"{streamed['rss'] / whole['rss']:.2f}x (above the idle floor: "
            f"{(streamed['rss'] - floor['rss']) / (whole['rss'] - floor['rss']):.2f}x)"
        )
        if not same:
            raise SystemExit("streamed and whole-image imports differ")
        (folder / "mid.pgm").unlink()
        if args.skip_site:
            return
        w, h = SITE
        y = write_warehouse(folder / "site.yaml", w, h)
        site = run("streamed", y)
        print(
            f"site {w:,} x {h:,} ({w * h / 1e6:.0f} M cells, 415 x 270 m at 2 cm): "
            f"{int(site['points']):,} points, {int(site['lines']):,} lines"
        )
        print(
            f"  row bands   : {site['s']:7.2f} s  peak {mb(site['rss'])} "
            f"({site['s'] / streamed['s']:.1f}x the time of the {cells / 1e6:.0f} M-cell map "
            f"for {w * h / cells:.1f}x the cells)"
        )


if __name__ == "__main__":
    main()
