"""Benchmark of ``.2d`` parsing and ``mapkit build``: map quality on simulated logs, and speed.

Quality: the bundled office and building maps are driven by the simulator (loop back home, odometry
drift); the log is built with registration and as raw odometry. Printed: the median distance from
each built point to the nearest true wall line (must be <= the 20 mm resolution and >= 5x smaller
than the raw odometry map's), the 90th percentile, and the trajectory RMS error against the true
poses.

Speed: a log of 10,000 scans of 361 readings (the office driven lap after lap) is parsed and built.
Baselines measured in the same run: parsing is compared with splitting the file's bytes into lines
(the least any reader does); building with registration is compared with the raw odometry build.
Wall and CPU times are printed: on a machine shared with other jobs the CPU time is the fair one
(the pipeline is single-threaded).

    python benchmarks/bench_build.py            # everything (several minutes on 2 cores)
    python benchmarks/bench_build.py --quick    # quality on the office only, 2,000-scan speed log
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import mapkit  # noqa: E402
from mapkit.build import build_map  # noqa: E402
from mapkit.build.quality import distance_to_segments, trajectory_rms  # noqa: E402
from mapkit.formats.laser2d import read_log, write_log  # noqa: E402
from mapkit.model.scan import LaserLog, LaserScan  # noqa: E402
from mapkit.samples import sample_path  # noqa: E402
from mapkit.simulate import simulate_log  # noqa: E402


def quality(name: str, **sim_args: object) -> dict[str, float]:
    m = mapkit.load(sample_path(name))
    t = time.perf_counter()
    sim = simulate_log(m, **sim_args)  # type: ignore[arg-type]
    t_sim = time.perf_counter() - t
    out: dict[str, float] = {"scans": len(sim.log.scans), "path_m": sim.distance / 1000,
                             "odo_end_err_mm": sim.odometry_error[0], "sim_s": t_sim}
    for register in (False, True):
        t = time.perf_counter()
        res = build_map(sim.log, register=register)
        dt = time.perf_counter() - t
        d = distance_to_segments(res.map.points, m.lines)
        truth = sim.truth[np.searchsorted(sim.truth_ids, res.scan_ids)]
        rms, rms_deg = trajectory_rms(res.poses, truth)
        key = "reg" if register else "raw"
        out.update({f"{key}_median_mm": float(np.median(d)), f"{key}_p90_mm": float(np.percentile(d, 90)),
                    f"{key}_traj_rms_mm": rms, f"{key}_traj_rms_deg": rms_deg, f"{key}_s": dt,
                    f"{key}_points": res.map.scan.num_points, f"{key}_lines": res.map.scan.num_lines})
        if register:
            out["loops"] = res.summary["loops"]  # type: ignore[assignment]
    return out


def speed(n_scans: int, folder: Path) -> None:
    m = mapkit.load(sample_path("office"))
    laps = n_scans // 350 + 1
    t = time.perf_counter()
    sim = simulate_log(m, loop=True, laps=laps, seed=5)
    t_sim = time.perf_counter() - t
    records = []
    count = 0
    for rec in sim.log.records:
        if isinstance(rec, LaserScan):
            if count == n_scans:
                break
            count += 1
        records.append(rec)
    log = LaserLog(header=sim.log.header, records=records)
    path = folder / "bench.2d"
    write_log(log, path)
    size = path.stat().st_size
    print(f"\nspeed log: {count} scans of {sim.log.header.laser(1).count} readings, "
          f"{size / 1e6:.1f} MB (simulated in {t_sim:.1f} s)")
    t = time.perf_counter()
    lines = path.read_bytes().split(b"\n")
    t_base = time.perf_counter() - t
    del lines
    t, c = time.perf_counter(), time.process_time()
    back = read_log(path)
    t_parse, c_parse = time.perf_counter() - t, time.process_time() - c
    assert len(back.scans) == count
    print(f"  parse: {t_parse:.2f} s wall, {c_parse:.2f} s CPU ({t_parse / t_base:.1f}x the time to "
          f"split the file into lines, {t_base:.2f} s; target < 2 s)")
    t = time.perf_counter()
    build_map(path, register=False, lines=False)
    t_raw = time.perf_counter() - t
    t, c = time.perf_counter(), time.process_time()
    res = build_map(path)
    t_reg, c_reg = time.perf_counter() - t, time.process_time() - c
    s = res.summary
    print(f"  build with registration: {t_reg:.1f} s wall, {c_reg:.1f} s CPU ({t_reg / t_raw:.1f}x "
          f"the raw odometry build, {t_raw:.1f} s; target < 60 s)")
    print(f"    stages: {s['seconds']}; registered {s['registration']['registered']}, "
          f"loops {s['loops']}")
    truth = sim.truth[np.searchsorted(sim.truth_ids, res.scan_ids)]
    rms, _ = trajectory_rms(res.poses, truth)
    d = distance_to_segments(res.map.points, m.lines)
    print(f"    quality: median {np.median(d):.1f} mm to the true walls, trajectory RMS {rms:.0f} mm")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="office quality, 2,000-scan speed log")
    ap.add_argument("--scans", type=int, default=None, help="scans in the speed log (10000)")
    args = ap.parse_args()
    cases = [("office", {"loop": True, "seed": 11, "drift": 0.15, "rotation_error": 0.03})]
    if not args.quick:
        cases.append(("building", {"loop": True, "seed": 1}))
    print("quality (distances from built points to the true wall lines, mm):")
    for name, kw in cases:
        q = quality(name, **kw)
        ratio = q["raw_median_mm"] / max(q["reg_median_mm"], 1.0)
        print(f"  {name}: {q['scans']} scans, {q['path_m']:.0f} m, odometry {q['odo_end_err_mm']:.0f} mm "
              f"off at the end")
        print(f"    registered: median {q['reg_median_mm']:.1f} (p90 {q['reg_p90_mm']:.0f}), trajectory "
              f"RMS {q['reg_traj_rms_mm']:.0f} mm / {q['reg_traj_rms_deg']:.2f} deg, "
              f"{q['reg_points']} points, {q['reg_lines']} lines, {q['reg_s']:.1f} s")
        print(f"    raw odometry: median {q['raw_median_mm']:.1f} (p90 {q['raw_p90_mm']:.0f}), trajectory "
              f"RMS {q['raw_traj_rms_mm']:.0f} mm / {q['raw_traj_rms_deg']:.2f} deg, {q['raw_s']:.1f} s")
        print(f"    raw / registered median: {ratio:.0f}x (at least 5x wanted); loops {q['loops']}")
    n = args.scans or (2000 if args.quick else 10_000)
    with tempfile.TemporaryDirectory() as tmp:
        speed(n, Path(tmp))
    return 0


if __name__ == "__main__":
    sys.exit(main())
