"""``mapkit build`` beside KISS-ICP (an open LiDAR odometry pipeline) on the same simulated logs.

The issue measured KISS-ICP, given the robot's odometry as its motion guess, at 30-49 mm of
trajectory RMS on ARIA's own logs of a simulated robot. This runs both on the logs of
``bench_build_real.py`` (real ARIA maps, given as a folder) and prints, per log, the map's median /
p90 distance to the true walls and the trajectory RMS of raw odometry, KISS-ICP and mapkit.

KISS-ICP is not a dependency of mapkit; install it beside it to run this
(``pip install kiss-icp``). Each scan goes in as a planar cloud (z = 0, metres, robot frame) with
the odometry step as KISS-ICP's motion guess (its constant-velocity guess replaced), no deskew
(a scan is one instant here); the poses it gives are written back into the log as odometry, and
the map is built from them without registration, as for raw odometry. Its voxel size is 0.02 m
(``--voxel``): on these logs 0.01 and 0.03 m gave it 1.6-3.6 times the trajectory error, and its
default (a hundredth of the range, 0.3 m) more still.

    python benchmarks/bench_kiss.py --maps ../shared/sample-data/real --only good sim
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any


def kiss_poses(log: Any, voxel: float) -> Any:
    """The log's scan ids, and KISS-ICP's poses of them (mm, mm, degrees; odometry's frame)."""
    import numpy as np
    from kiss_icp.config import KISSConfig
    from kiss_icp.kiss_icp import KissICP

    from mapkit.build.builder import _scan_arrays

    scans, odo, pts = _scan_arrays(log, "robot", 30000.0)
    config = KISSConfig()
    config.data.max_range = 30.0
    config.data.min_range = 0.05
    config.data.deskew = False
    config.mapping.voxel_size = voxel
    kiss = KissICP(config)

    def matrix(p: Any) -> Any:
        c, s = np.cos(p[2]), np.sin(p[2])
        m = np.eye(4)
        m[:2, :2] = [[c, -s], [s, c]]
        m[:2, 3] = p[:2] / 1000.0
        return m

    kiss.last_pose = matrix(odo[0])
    out = []
    for k, p in enumerate(pts):
        if k:
            # The odometry step as the motion guess (KISS-ICP's own is the last step again).
            kiss.last_delta = np.linalg.inv(matrix(odo[k - 1])) @ matrix(odo[k])
        frame = np.column_stack([p / 1000.0, np.zeros(len(p))])
        kiss.register_frame(frame, np.zeros(len(p)))
        m = kiss.last_pose
        out.append((m[0, 3] * 1000.0, m[1, 3] * 1000.0, np.degrees(np.arctan2(m[1, 0], m[0, 0]))))
    return [s.scan_id for s in scans], np.array(out)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--maps", required=True, help="folder with the real ARIA maps")
    ap.add_argument("--seeds", type=int, default=3, help="random draws per map and odometry")
    ap.add_argument("--only", nargs="*", help="odometries to run (names of bench_build_real)")
    ap.add_argument("--voxel", type=float, default=0.02, help="KISS-ICP's voxel size (m)")
    args = ap.parse_args()
    try:
        import kiss_icp  # noqa: F401
    except ImportError:
        print("KISS-ICP is not installed: pip install kiss-icp", file=sys.stderr)
        return 2
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from bench_build import _with_odometry, measure
    from bench_build_real import logs

    from mapkit.build import build_map

    print(
        f"{'log':28} {'scans':>5} | {'floor':>5} | {'odometry med/p90 rms':>20} | "
        f"{'KISS-ICP med/p90 rms':>20} | {'mapkit med/p90 rms':>18} | cpu s KISS / mapkit"
    )
    rows: dict[str, list[tuple[float, float, float]]] = {}
    for label, odo_name, world, sim, floor, raw in logs(args.maps, args.seeds, args.only):
        log, ids, truth = sim.log, sim.truth_ids, sim.truth
        t = time.process_time()
        k_ids, k_poses = kiss_poses(log, args.voxel)
        t_kiss = time.process_time() - t
        kiss = measure(
            build_map(_with_odometry(log, k_ids, k_poses), register=False, lines=False),
            world,
            ids,
            truth,
        )
        t = time.process_time()
        ours = measure(build_map(log), world, ids, truth)
        t_ours = time.process_time() - t
        rows.setdefault(odo_name, []).append((raw["rms"], kiss["rms"], ours["rms"]))
        print(
            f"{label:28} {len(log.scans):5d} | {floor['median']:5.1f} | "
            f"{raw['median']:6.1f} / {raw['p90']:4.0f} {raw['rms']:6.1f} | "
            f"{kiss['median']:6.1f} / {kiss['p90']:4.0f} {kiss['rms']:6.1f} | "
            f"{ours['median']:5.1f} / {ours['p90']:4.0f} {ours['rms']:5.1f} | "
            f"{t_kiss:5.1f} / {t_ours:5.1f}",
            flush=True,
        )
    for odo_name, r in rows.items():
        n = len(r)
        raw_m, kiss_m, ours_m = (sum(x[i] for x in r) / n for i in range(3))
        ahead = sum(x[2] < x[1] for x in r)
        print(
            f"  {odo_name:7} trajectory RMS mean: odometry {raw_m:.1f}, KISS-ICP {kiss_m:.1f}, "
            f"mapkit {ours_m:.1f} mm; mapkit ahead on {ahead} of {n}"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
