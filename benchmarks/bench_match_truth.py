"""How far the refinement's scan matches err when every scan sits at its true pose.

``mapkit build``'s refinement (``mapkit/build/_refine.py``) matches each scan against the other
passes' scans. Here every scan is placed at its true pose and matched from there, twice with the
refinement's settings: against the other passes' scans (what the refinement has), and against
the map's true walls (its lines, sampled every 5 mm with their exact normals); the first scan
against the other passes as the refinement matches it, against their local planes. What each match
moves the scan is its error; the difference between the two is what the other passes, being
scans themselves (noisy, seen from elsewhere), add to it. The logs are those of
``bench_build_real.py`` (real ARIA maps, its odometry classes and draws).

    python benchmarks/bench_match_truth.py --maps ../shared/sample-data/real --only good exact
    python benchmarks/bench_match_truth.py --maps DIR --seeds 2 --jobs 2

Per log, for the scans of the start (the first ``--start``, which place the map about it) and
for every ``--stride``-th scan after: the matches' heading error, mean and RMS (degrees), and
their position RMS (mm). The map's points that are not on a line (clutter) are walls too for the
simulated laser but not for the true-walls reference: scans that see mostly clutter match fewer
points there.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_build_real import ODOMETRIES, each_log, on_path, options, world_map


def _wall_samples(lines: Any, step: float = 5.0) -> tuple[Any, Any]:
    """Points every ``step`` mm along each line, and the line's unit normal at each."""
    from mapkit.simulate.rays import segment_samples

    seg = np.asarray(lines, dtype=np.float64).reshape(-1, 4)
    length = np.hypot(seg[:, 2] - seg[:, 0], seg[:, 3] - seg[:, 1])
    seg, length = seg[length > 0], length[length > 0]
    pts, idx = segment_samples(seg, step)
    d = (seg[:, 2:] - seg[:, :2]) / length[:, None]
    return pts, np.column_stack([-d[idx, 1], d[idx, 0]])


def errors(maps: str, name: str, odo_name: str, seed: int, start: int, stride: int) -> str:
    """One log's line of figures."""
    from scipy.spatial import cKDTree

    from mapkit.build._common import _world
    from mapkit.build._graph import wrap
    from mapkit.build._refine import _OtherPasses, anchor_match, match
    from mapkit.build._register import _sides
    from mapkit.build.builder import _scan_arrays
    from mapkit.simulate import simulate_log

    world = world_map(maps, name)
    sim = simulate_log(world, loop=True, seed=seed, odometry_origin="zero", **ODOMETRIES[odo_name])
    scans, _, all_pts = _scan_arrays(sim.log, "robot", 16000.0)
    ids = np.asarray(sim.truth_ids)
    truth = np.asarray(sim.truth, dtype=np.float64)[
        np.searchsorted(ids, [s.scan_id for s in scans])
    ]
    x = np.column_stack([truth[:, :2], np.radians(truth[:, 2])])
    src, pts, nrm = _sides(all_pts)
    parts = [_world(p, q, e) for p, q, e in zip(pts, nrm, x, strict=True)]
    tgt = np.concatenate([a for a, _ in parts])
    tn = np.concatenate([b for _, b in parts])
    owner = np.repeat(np.arange(len(x)), [len(a) for a, _ in parts])
    path = np.concatenate(([0.0], np.cumsum(np.hypot(*np.diff(x[:, :2], axis=0).T))))
    others = _OtherPasses(tgt, owner, path)
    walls, wall_nrm = _wall_samples(world.lines)
    wall_tree = cKDTree(walls)

    def error(i: int, tree: Any, t_pts: Any, t_nrm: Any) -> tuple[float, float] | None:
        if i == 0 and tree is others:
            r = anchor_match(all_pts[0], others, t_pts, t_nrm, x[0])
        else:
            r = match(all_pts[0] if i == 0 else src[i], tree, t_pts, t_nrm, x[i])
        if r is None:
            return None
        return math.degrees(wrap(r.pose[2] - x[i, 2])), math.hypot(*(r.pose[:2] - x[i, :2]))

    groups = {
        "start": range(min(start, len(x))),
        "tour": range(min(start, len(x)), len(x), max(1, stride)),
    }
    cells = []
    for scans_of in groups.values():
        for tree, t_pts, t_nrm in ((others, tgt, tn), (wall_tree, walls, wall_nrm)):
            got = []
            for i in scans_of:
                others.at = float(path[i])
                m = error(i, tree, t_pts, t_nrm)
                if m is not None:
                    got.append(m)
            e = np.array(got).reshape(-1, 2)
            cells.append(
                f"{len(e):4d} {np.mean(e[:, 0]) if len(e) else math.nan:+6.3f} "
                f"{np.sqrt(np.mean(e[:, 0] ** 2)) if len(e) else math.nan:5.3f} "
                f"{np.sqrt(np.mean(e[:, 1] ** 2)) if len(e) else math.nan:4.1f}"
            )
    label = f"{name.removesuffix('.map')} {odo_name} {seed}"
    return f"{label:28} | " + " | ".join(cells)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    options(ap, seeds=1)
    ap.add_argument("--start", type=int, default=40, help="scans of the start (default 40)")
    ap.add_argument("--stride", type=int, default=10, help="every Nth scan after (default 10)")
    args = ap.parse_args()
    paths = on_path(args)

    import mapkit

    print(f"mapkit from {Path(mapkit.__file__).parent.parent}")
    titles = ("start: other passes", "start: true walls", "tour: other passes", "tour: true walls")
    print(f"{'':28} | " + " | ".join(f"{t:^22}" for t in titles))
    print(
        f"{'log':28} | " + " | ".join(f"{'n':>4} {'mean':>6} {'RMS':>5} {'pos':>4}" for _ in titles)
    )
    print(f"{'':28} | " + " | ".join(f"{'':4} {'heading, deg':>12} {'mm':>4}" for _ in titles))
    for _, line in each_log(args, paths, errors, args.start, args.stride):
        print(line, flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
