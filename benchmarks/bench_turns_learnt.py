"""Benchmark of a robot's turn error learnt from several of its logs (``robot_turn_error``,
``mapkit turn-error``) against each log's own, on logs simulated from real ARIA maps.

Each log is built as ``mapkit build`` does (its turns' error presumed 0.1 % unless its turns rule
that out, then fitted from itself: the baseline, measured in the same run), then again with the
turn error ``robot_turn_error`` learns from the *other* logs of the same robot (the same odometry
class; never the log itself), as a user who ran ``mapkit turn-error`` over the robot's other logs
would build it.

    python benchmarks/bench_turns_learnt.py --maps ../shared/sample-data/real --seeds 6 --jobs 2
    python benchmarks/bench_turns_learnt.py --maps DIR --seeds 6 --same-map 3   # 3 logs, one site
    python benchmarks/bench_turns_learnt.py --maps DIR --first-seed 10 --learn-seeds 6
        # draws 10-12 built with what draws 1-6 taught

The last lines count the logs that meet every target both ways and give the mean trajectory RMS
and the geometric mean of the learnt build's RMS over the fitted one's (a ratio: below 1 is
better), overall and per odometry class.
"""

from __future__ import annotations

import argparse
import math
import statistics
import sys
from typing import Any

from bench_build_real import chosen, each_log, on_path, options

Key = tuple[str, str, int]


def built(
    maps: str, name: str, odo_name: str, seed: int, turn_errors: dict[Key, float | None]
) -> tuple[str, float, bool, Any, float | None]:
    """One log built with the turn error ``turn_errors`` gives it (absent: fitted from the log):
    ``(label, trajectory RMS, whether it met every target, its turns' evidence, the turn error
    used)``."""
    from bench_build import measure, targets
    from bench_build_real import one_log

    from mapkit.build import build_map

    label, _, world, sim, floor, raw = one_log(maps, name, odo_name, seed)
    res = build_map(sim.log, turn_error=turn_errors.get((name, odo_name, seed)))
    b = measure(res, world, sim.truth_ids, sim.truth)
    ok = all(targets(floor, raw, b).values())
    used = res.summary["registration"]["odometry_turn_error"]
    return label, float(b["rms"]), ok, res.turns, used


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    options(ap, seeds=6)
    ap.add_argument(
        "--same-map",
        type=int,
        metavar="K",
        help="learn from K other logs of the same robot on the same map (default: all the "
        "robot's other logs, on every map)",
    )
    ap.add_argument(
        "--learn-seeds",
        type=int,
        metavar="M",
        help="learn from draws 1..M of each robot (built first) instead of the other logs "
        "built here",
    )
    args = ap.parse_args()
    paths = on_path(args)
    from mapkit.build import robot_turn_error

    def evidence(a: argparse.Namespace) -> dict[Key, Any]:
        """Each log's turns, from its build with the turn error fitted."""
        out: dict[Key, Any] = {}
        for key, (_, (_, _, _, turns, _)) in zip(
            chosen(a), each_log(a, paths, built, {}), strict=True
        ):
            out[key] = turns
        return out

    keys = chosen(args)
    teachers = None
    if args.learn_seeds:
        teach = argparse.Namespace(**{**vars(args), "seeds": args.learn_seeds, "first_seed": 1})
        teachers = evidence(teach)
    fitted: dict[Key, tuple[str, float, bool, Any, float | None]] = {}
    for key, (_, row) in zip(keys, each_log(args, paths, built, {}), strict=True):
        fitted[key] = row
    pool = teachers if teachers is not None else {k: v[3] for k, v in fitted.items()}
    plan: dict[Key, float | None] = {}
    for key in keys:
        name, odo, _ = key
        others = [k for k in pool if k[1] == odo and k != key]
        if args.same_map:
            others = [k for k in others if k[0] == name][: args.same_map]
        plan[key] = robot_turn_error(pool[k] for k in others)
    print(
        f"{'log':28} | {'fitted: error  rms':>18} | {'learnt: error  rms':>18} | {'ratio':>5} | "
        "targets"
    )
    per: dict[str, list[tuple[float, bool, float, bool]]] = {}
    for key, (_, row) in zip(keys, each_log(args, paths, built, plan), strict=True):
        label, rms, ok, _, used = row
        _, rms0, ok0, _, used0 = fitted[key]
        per.setdefault(key[1], []).append((rms0, ok0, rms, ok))
        print(
            f"{label:28} | {used0 or 0.0:7.4f} {rms0:9.1f} | {used or 0.0:7.4f} {rms:9.1f} | "
            f"{rms / rms0:5.2f} | {'ok' if ok0 else 'MISS'} -> {'ok' if ok else 'MISS'}",
            flush=True,
        )

    def line(what: str, runs: list[tuple[float, bool, float, bool]]) -> str:
        ratio = math.exp(statistics.mean(math.log(r / r0) for r0, _, r, _ in runs))
        return (
            f"{what:8} {sum(o0 for _, o0, _, _ in runs)} -> {sum(o for _, _, _, o in runs)} of "
            f"{len(runs)} meet every target; RMS mean {statistics.mean(r for r, *_ in runs):.2f}"
            f" -> {statistics.mean(r for _, _, r, _ in runs):.2f} mm; learnt/fitted "
            f"{ratio:.3f} (geometric mean)"
        )

    print(line("all", [r for runs in per.values() for r in runs]))
    for odo, runs in per.items():
        print("  " + line(odo, runs))
    return 0


if __name__ == "__main__":
    sys.exit(main())
