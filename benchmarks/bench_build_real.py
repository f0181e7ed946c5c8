"""Benchmark of ``mapkit build`` on logs simulated from real ARIA maps (given as a folder).

The maps of ``bench_build.py`` are ours; real sites look otherwise (clutter, long corridors that
look alike, a start in a dead end). This drives the simulated robot through real ARIA maps that
have goals (a tour of the goals and back home, as ``mapkit simulate --loop`` does) with nine
odometries and lasers, and checks the issue's targets on each log: map median within 5 mm of the
floor, p90 under 60 mm, trajectory RMS under 40 mm and within odometry's + 15 mm.

    python benchmarks/bench_build_real.py --maps ../shared/sample-data/real
    python benchmarks/bench_build_real.py --maps DIR --seeds 3 --tree OLD   # before/after
    python benchmarks/bench_build_real.py --maps DIR --first-seed 10   # fresh draws
    python benchmarks/bench_build_real.py --maps DIR --seeds 6 --jobs 2   # two logs at once
    python benchmarks/bench_build_real.py --maps DIR --second-laser   # a rear laser too
    python benchmarks/bench_build_real.py --maps DIR --second-laser apart   # ... matched apart
    python benchmarks/bench_build_real.py --maps DIR --held-out --seeds 2 --jobs 2
    # a laser on a slow line, its sweeps 120 ms old (any simulate_log argument, for every log):
    python benchmarks/bench_build_real.py --maps DIR --held-out --only lag --simulate scan_lag=0.12

Draws 1-6 are the ones the rounds so far were measured on (and so, in part, tuned on), draws
7-9 were fresh for round 11's check; draws from 10 on are logs no round has seen: a round
that only helps the logs it was measured on shows there. ``--held-out`` goes further: the
folder's other maps (a lab, an office, an older columbia, an LD's showroom, a triangle), which
rounds 1-20 were never measured on, each driven through six free places of its own.

Figures are per log (``turn / rest``: the turn, in degrees, that brings the built trajectory
best onto the truth about the start, and the RMS left after it); the last lines count the logs
that meet every target and give the mean and worst trajectory RMS per odometry, so two trees
compare on the same logs.
"""

from __future__ import annotations

import argparse
import functools
import json
import sys
import time
from collections.abc import Callable, Iterator
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

#: The maps used (those of ../shared/sample-data/real that have goals to tour).
MAPS = ("amrisim-AMROffice.map", "aria291-columbia.map", "aria294-columbia.map")

#: Maps no round was measured on (``--held-out``): those of the folder without goals to tour
#: (and the showroom, with one), driven through free places of their own (:func:`free_tour`).
HELD_OUT = (
    "aria-ActivMediaLab.map",
    "aria-office.map",
    "aria275-columbia.map",
    "omron-ld-showroom-ex4.map",
    "aria-triangle.map",
)

#: name -> simulate_log arguments.
ODOMETRIES: dict[str, dict[str, Any]] = {
    # A simulator's odometry as MobileSim's is (0.05 %: a few mm over a tour), a dense laser and
    # a logger that writes often (ARIA's logs are denser than every 300 mm): the class.
    "good": {
        "readings": 361,
        "translation_error": 0.0005,
        "rotation_error": 0.0005,
        "drift": 0.0,
        "range_noise": 12.0,
        "dist_step": 150.0,
    },
    "good181": {
        "readings": 181,
        "translation_error": 0.001,
        "rotation_error": 0.001,
        "drift": 0.0,
        "range_noise": 15.0,
        "dist_step": 150.0,
    },
    # A simulator's odometry (0.2 %), a noisy laser: odometry is better than any scan match.
    "sim": {
        "readings": 181,
        "translation_error": 0.002,
        "rotation_error": 0.002,
        "drift": 0.0,
        "range_noise": 15.0,
    },
    "sim361": {
        "readings": 361,
        "translation_error": 0.002,
        "rotation_error": 0.002,
        "drift": 0.0,
        "range_noise": 15.0,
    },
    # A small drift, a scan every half metre.
    "drift": {
        "readings": 181,
        "translation_error": 0.002,
        "rotation_error": 0.005,
        "drift": 0.02,
        "range_noise": 10.0,
        "dist_step": 500.0,
    },
    # A short-range wide laser (a Hokuyo URG-04LX: 683 beams over 240 degrees, 5.6 m) on a
    # robot that drifts a little: few walls in reach, so the scans hold the heading less.
    "urg": {
        "readings": 683,
        "fov": 240.0,
        "max_range": 5600.0,
        "translation_error": 0.002,
        "rotation_error": 0.005,
        "drift": 0.02,
        "range_noise": 15.0,
    },
    # The true poses as odometry (the issue's own check): nothing to correct, so whatever the
    # build moves is its own error (target: within 15 mm of odometry's, which is under 1 mm).
    "exact": {
        "readings": 181,
        "translation_error": 0.0,
        "rotation_error": 0.0,
        "drift": 0.0,
        "range_noise": 15.0,
        "dist_step": 150.0,
    },
    # A robot that slips in its turns, drifts, misjudges distance; a few spurious readings.
    "rough": {
        "readings": 361,
        "translation_error": 0.01,
        "rotation_error": 0.02,
        "drift": 0.05,
        "range_noise": 10.0,
        "turn_slip": 0.02,
        "scale_error": 0.005,
        "outliers": 0.02,
    },
}
# The "good181" robot with sweeps 40 ms older than the poses logged with them (ARIA stamps a
# simulated laser's sweep with the pose of when its packet arrived): while turning, every sweep
# is turned 1.6 degrees against its pose.
ODOMETRIES["lag"] = {**ODOMETRIES["good181"], "scan_lag": 0.04}
# The same lag, varying from sweep to sweep by up to 40 ms either way (packets that arrive early
# or late in the robot's cycle): each sweep is off its pose by a part of its own.
ODOMETRIES["jitter"] = {**ODOMETRIES["lag"], "scan_lag_jitter": 0.04}


def draws(
    seeds: int, only: list[str] | None, first_seed: int = 1, maps: tuple[str, ...] = MAPS
) -> list[tuple[str, str, int]]:
    """Each log's ``(map file name, odometry name, draw)``: maps by odometries by draws."""
    return [
        (name, odo_name, seed)
        for name in maps
        for odo_name in ODOMETRIES
        if not only or odo_name in only
        for seed in range(first_seed, first_seed + seeds)
    ]


@functools.cache
def world_map(maps: str, name: str) -> Any:
    """A real map, read once per process (every odometry and draw on it is simulated from it)."""
    import mapkit

    return mapkit.load(Path(maps) / name)


def free_tour(
    world: Any, seed: int, stops: int = 6
) -> tuple[tuple[float, float, float], list[tuple[float, float]]]:
    """A tour of a map without goals: ``(start pose, waypoints)``, ``stops`` places in the
    largest free space inside the walls (700 mm from any), each after the first drawn among the
    tenth of the space farthest from those before it, and a random heading at the start."""
    import numpy as np
    from scipy import ndimage

    from mapkit.simulate.route import _grid

    grid = _grid(world, 100.0)
    labels, count = ndimage.label(grid.clearance > 700.0)
    edge = np.concatenate([labels[0], labels[-1], labels[:, 0], labels[:, -1]])
    inside = [c for c in range(1, count + 1) if c not in set(edge.tolist())]
    if not inside:
        raise ValueError("no free space inside the walls to tour")
    biggest = max(inside, key=lambda c: int(np.count_nonzero(labels == c)))
    ii, jj = np.nonzero(labels == biggest)
    free = np.column_stack([grid.origin[0] + jj * grid.cell, grid.origin[1] + ii * grid.cell])
    rng = np.random.default_rng(1000 + seed)
    chosen = [free[rng.integers(len(free))]]
    for _ in range(stops - 1):
        far = np.min(np.hypot(*(free[:, None, :] - np.array(chosen)[None]).transpose(2, 0, 1)), 1)
        chosen.append(free[rng.choice(np.flatnonzero(far >= np.quantile(far, 0.9)))])
    start = (float(chosen[0][0]), float(chosen[0][1]), float(rng.uniform(-180.0, 180.0)))
    return start, [(float(x), float(y)) for x, y in chosen[1:]]


def simulation(world: Any, name: str, odo_name: str, seed: int) -> dict[str, Any]:
    """The ``simulate_log`` arguments of one log on ``world`` (the map ``name``) besides its
    draw: its odometry's, and on a map without goals to tour (not in ``MAPS``) the
    :func:`free_tour` of that draw."""
    settings = dict(ODOMETRIES[odo_name])
    if name not in MAPS:
        start, stops = free_tour(world, seed)
        settings.update(start=start, waypoints=stops)
    return settings


#: Where ``--second-laser`` mounts a rear laser (mm, mm, degrees).
REAR_LASER = (-200.0, 0.0, 180.0)


def one_log(
    maps: str,
    name: str,
    odo_name: str,
    seed: int,
    second_laser: str | None = None,
    more: dict[str, Any] | None = None,
) -> tuple[Any, ...]:
    """One log: ``(label, odometry name, world map, simulated log, floor figures, odometry
    figures)`` (figures of ``bench_build.measure``). ``second_laser``: with a rear laser
    (``REAR_LASER``) too, its sweeps in the front one's cycles (``"cycle"``, as ARIA logs
    them) or each in a cycle of its own (``"apart"``: the build then matches every sweep as a
    scan of its own, as it did before it merged a cycle's sweeps). ``more``: ``simulate_log``
    arguments that differ from the odometry's (``--simulate``)."""
    from bench_build import _with_poses, measure

    from mapkit.build import build_map
    from mapkit.simulate import simulate_log

    world = world_map(maps, name)
    settings = {**simulation(world, name, odo_name, seed), **(more or {})}
    if second_laser:
        settings["second_laser"] = REAR_LASER
    sim = simulate_log(world, loop=True, seed=seed, odometry_origin="zero", **settings)
    if second_laser == "apart":
        import dataclasses

        from mapkit.model.scan import LaserScan

        records = tuple(
            dataclasses.replace(r, time=r.time + 0.001)
            if isinstance(r, LaserScan) and r.laser == 2 and r.time is not None
            else r
            for r in sim.log.records
        )
        sim = dataclasses.replace(sim, log=dataclasses.replace(sim.log, records=records))
    log, ids, truth = sim.log, sim.truth_ids, sim.truth
    floor = measure(
        build_map(_with_poses(log, ids, truth), register=False, lines=False), world, ids, truth
    )
    raw = measure(build_map(log, register=False, lines=False), world, ids, truth)
    label = f"{name.removesuffix('.map')} {odo_name} {seed}"
    return label, odo_name, world, sim, floor, raw


def logs(
    maps: str, seeds: int, only: list[str] | None, first_seed: int = 1
) -> Iterator[tuple[Any, ...]]:
    """Each log of :func:`draws`, as :func:`one_log` gives it."""
    for name, odo_name, seed in draws(seeds, only, first_seed):
        yield one_log(maps, name, odo_name, seed)


def built(
    maps: str,
    name: str,
    odo_name: str,
    seed: int,
    second_laser: str | None = None,
    more: dict[str, Any] | None = None,
) -> tuple[str, float, bool]:
    """One log simulated and built: ``(its line of figures, its trajectory RMS, whether it met
    every target)``. The CPU time is the build's own, in the process that built it."""
    from bench_build import measure, targets

    from mapkit.build import build_map

    label, _, world, sim, floor, raw = one_log(maps, name, odo_name, seed, second_laser, more)
    log, ids, truth = sim.log, sim.truth_ids, sim.truth
    t = time.process_time()
    res = build_map(log)
    cpu = time.process_time() - t
    b = measure(res, world, ids, truth)
    ok = all(targets(floor, raw, b).values())
    line = (
        f"{label:28} {len(log.scans):5d} | {floor['median']:5.1f} / {floor['p90']:5.1f}"
        f" | {raw['median']:6.1f} / {raw['p90']:5.0f} {raw['rms']:6.1f} | "
        f"{b['median']:5.1f} / {b['p90']:4.0f} {b['rms']:5.1f} | "
        f"{b['turn_deg']:+6.3f} {b['rest']:6.1f} | {cpu:5.1f} | "
        f"{'ok' if ok else 'MISS'}"
    )
    return line, float(b["rms"]), ok


def _on_path(paths: list[str]) -> None:
    """``paths`` first on ``sys.path`` (the tree that builds, and the benchmarks), in this process
    or a worker."""
    for p in reversed(paths):
        sys.path.insert(0, p)


def options(ap: argparse.ArgumentParser, seeds: int = 3) -> None:
    """The options that choose the logs and how they run (``--maps``, ``--tree``, ``--seeds``,
    ``--only``, ``--first-seed``, ``--jobs``)."""
    ap.add_argument("--maps", required=True, help="folder with the real ARIA maps")
    ap.add_argument("--tree", help="checkout whose mapkit builds")
    ap.add_argument("--seeds", type=int, default=seeds, help="random draws per map and odometry")
    ap.add_argument("--only", nargs="*", help="odometries to run (names)")
    ap.add_argument("--first-seed", type=int, default=1, help="the first draw (default 1)")
    ap.add_argument(
        "--jobs", type=int, default=1, help="logs at once, each in a process of its own"
    )
    ap.add_argument(
        "--held-out",
        action="store_true",
        help="the maps no round was measured on, toured through free places of their own",
    )


def chosen(args: argparse.Namespace) -> list[tuple[str, str, int]]:
    """The logs the options choose (:func:`draws` of ``--held-out``'s maps or ``MAPS``)."""
    return draws(args.seeds, args.only, args.first_seed, HELD_OUT if args.held_out else MAPS)


def on_path(args: argparse.Namespace) -> list[str]:
    """``--tree``'s mapkit (if given) and the benchmarks first on ``sys.path``; the paths put."""
    paths = [str(Path(__file__).resolve().parent)]
    if args.tree:
        paths.insert(0, str(Path(args.tree).resolve()))
    _on_path(paths)
    return paths


def each_log(
    args: argparse.Namespace, paths: list[str], fn: Callable[..., Any], *more: Any
) -> Iterator[tuple[str, Any]]:
    """``(odometry name, fn(maps, map name, odometry name, draw, *more))`` for each log the
    options choose, in order, in ``--jobs`` processes with ``paths`` (:func:`on_path`) first."""
    todo = chosen(args)
    n = len(todo)
    columns = [list(c) for c in zip(*todo, strict=True)] if todo else [[], [], []]
    call = (fn, [args.maps] * n, *columns, *([m] * n for m in more))
    if args.jobs > 1:
        with ProcessPoolExecutor(args.jobs, initializer=_on_path, initargs=(paths,)) as pool:
            # In order: each as soon as it and those before it are done.
            yield from zip(columns[1], pool.map(*call), strict=True)
    else:
        yield from zip(columns[1], map(*call), strict=True)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    options(ap)
    ap.add_argument(
        "--second-laser",
        nargs="?",
        const="cycle",
        choices=("cycle", "apart"),
        help="a rear laser too: its sweeps in the front one's cycles (as ARIA logs them), or "
        "'apart' (each in a cycle of its own: each sweep matched as a scan of its own)",
    )
    ap.add_argument(
        "--simulate",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="a simulate_log argument for every log, over its odometry's (e.g. scan_lag=0.12 "
        "with --only lag jitter, or people=8); may be given more than once",
    )
    args = ap.parse_args()
    paths = on_path(args)
    more = {k: json.loads(v) for k, _, v in (a.partition("=") for a in args.simulate)}

    import mapkit

    print(f"mapkit from {Path(mapkit.__file__).parent.parent}")
    print(
        f"{'log':28} {'scans':>5} | {'floor med/p90':>13} | {'odometry med/p90 rms':>21} | "
        f"{'built med/p90 rms':>18} | {'turn / rest':>13} | {'cpu s':>5} | targets"
    )
    per: dict[str, list[tuple[float, bool]]] = {}
    for odo_name, (line, rms, ok) in each_log(args, paths, built, args.second_laser, more):
        per.setdefault(odo_name, []).append((rms, ok))
        print(line, flush=True)
    total = sum(ok for runs in per.values() for _, ok in runs)
    print(f"{total} of {sum(len(r) for r in per.values())} logs meet every target")
    for odo_name, runs in per.items():
        rms = [r for r, _ in runs]
        print(
            f"  {odo_name:7} {sum(ok for _, ok in runs)} of {len(runs)} ok, "
            f"trajectory RMS mean {sum(rms) / len(rms):.1f} mm, worst {max(rms):.1f} mm"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
