"""mapkit build against the truth on small simulated logs: never worse than odometry, near the
floor.

The logs are short (a room and a corridor, a couple of hundred scans) so these run in seconds; the
full benchmark over noisier and longer logs is ``benchmarks/bench_build.py``.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from typing import Any

import numpy as np
import pytest

from mapkit.build import build_map
from mapkit.build.quality import distance_to_segments, trajectory_rms
from mapkit.model import MapData, MapObject, Scan
from mapkit.model.scan import LaserLog, LaserScan, Pose2D, compose
from mapkit.simulate import simulate_log

# An L-shaped flat: a room, a corridor and a second room, with a pillar.
WALLS = [
    [0, 0, 9000, 0],
    [9000, 0, 9000, 4000],
    [9000, 4000, 4000, 4000],
    [4000, 4000, 4000, 9000],
    [4000, 9000, 0, 9000],
    [0, 9000, 0, 0],
    [2000, 2000, 2600, 2000],
    [2600, 2000, 2600, 2600],
    [2600, 2600, 2000, 2600],
    [2000, 2600, 2000, 2000],
]
ROUTE = [(7500, 1200), (7500, 3000), (3000, 3200), (2000, 7500), (1200, 1200)]


def flat() -> MapData:
    return MapData(
        scans=(Scan.from_arrays(lines=WALLS),),
        objects=(MapObject("RobotHome", 1000, 1000, 0, name="Home"),),
    )


def tour(seed: int, **settings: Any):
    """A log of the flat's tour (``ROUTE``, back home) with these simulation settings."""
    return simulate_log(flat(), waypoints=ROUTE, loop=True, seed=seed, **settings)


def with_true_odometry(sim) -> LaserLog:
    at = {int(i): Pose2D(*map(float, p)) for i, p in zip(sim.truth_ids, sim.truth, strict=True)}
    recs = [
        dataclasses.replace(r, robot=at[r.scan_id], robot_global=at[r.scan_id])
        if isinstance(r, LaserScan)
        else r
        for r in sim.log.records
    ]
    return LaserLog(header=sim.log.header, records=tuple(recs))


def figures(result, sim) -> tuple[float, float, float]:
    d = distance_to_segments(result.map.points, np.array(WALLS, dtype=float))
    truth = sim.truth[np.searchsorted(sim.truth_ids, result.scan_ids)]
    rms, _ = trajectory_rms(result.poses, truth)
    return float(np.median(d)), float(np.percentile(d, 90)), rms


NOISE = {
    "perfect": {"translation_error": 0.0, "rotation_error": 0.0, "drift": 0.0},
    "good": {"translation_error": 0.003, "rotation_error": 0.005, "drift": 0.01},
    "drifting": {"drift": 0.2, "rotation_error": 0.03, "scale_error": 0.01, "turn_slip": 0.04},
    # A sparse laser (181 beams) on a robot that slips in turns: few points per scan to match
    # while turning on the spot.
    "sparse-slipping": {"readings": 181, "drift": -0.08, "scale_error": -0.015, "turn_slip": 0.05},
}


@pytest.mark.parametrize("noise", sorted(NOISE))
def test_never_worse_than_odometry_and_near_the_floor(noise: str) -> None:
    sim = tour(7, **NOISE[noise])
    built = figures(build_map(sim.log, lines=False), sim)
    raw = figures(build_map(sim.log, register=False, lines=False), sim)
    floor = figures(build_map(with_true_odometry(sim), register=False, lines=False), sim)
    med, p90, rms = built
    assert med <= floor[0] + 5.0 and p90 < 60.0, (built, floor)
    assert rms < 40.0 and rms <= raw[2] + 15.0, (built, raw)


def test_true_poses_as_odometry_stay_true() -> None:
    sim = tour(3, range_noise=15.0, translation_error=0.0, rotation_error=0.0, drift=0.0)
    res = build_map(with_true_odometry(sim), lines=False)
    rms, rms_deg = trajectory_rms(res.poses, sim.truth)
    assert rms < 5.0 and rms_deg < 0.1, (rms, rms_deg)
    assert res.summary["registration"]["odometry_noise_scale"] < 0.5


def test_outliers_and_people_stay_out_of_the_map() -> None:
    sim = tour(5, outliers=0.03, people=2, drift=0.1, turn_slip=0.03)
    med, p90, rms = figures(build_map(sim.log, lines=False), sim)
    assert med < 15.0 and p90 < 60.0 and rms < 40.0, (med, p90, rms)


def test_odometry_noise_scale_has_a_floor() -> None:
    """Steps that agree with their scans better than the scans' noise explains still leave
    odometry a noise: the scale stops at its floor, so good-but-not-perfect odometry cannot
    overrule the scans."""
    from mapkit.build import _odometry

    model = _odometry._OdometryModel()
    strong = np.diag([1.0, 1.0, 1e4])  # scan matches of 1 mm and 0.6 degrees
    for _ in range(200):
        model.observe(np.zeros(3), strong, 150.0, 0.0)
    model.settle()
    assert model.scale == pytest.approx(10**_odometry._MIN_LOG_SCALE)
    assert 0 < model.scale < 0.05
    # Steps that disagree with their scans raise it again.
    rng = np.random.default_rng(1)
    for _ in range(200):
        model.observe(np.array([*rng.normal(0, 20.0, 2), rng.normal(0, 0.01)]), strong, 150.0, 0.0)
    model.settle()
    assert model.scale > 0.05


def test_fusion_weighs_scan_and_odometry_and_distrusts_a_wild_match() -> None:
    from mapkit.build._loops import _fuse

    scan = np.diag([1 / 4.0**2, 1 / 4.0**2, 1 / np.radians(0.2) ** 2])
    odo = np.diag([1 / 4.0**2, 1 / 4.0**2, 1 / np.radians(0.2) ** 2])
    # Within the noises: the information-weighted mean (here halfway).
    near, near_info = _fuse(np.array([4.0, -2.0, np.radians(0.1)]), scan, odo)
    assert np.allclose(near, [1.9, -0.95, np.radians(0.0475)], rtol=0.1)
    # 50 mm off where both claim 4 mm: the match barely moves the pose.
    wild, wild_info = _fuse(np.array([50.0, 0.0, 0.0]), scan, odo)
    assert 0 < wild[0] < 5.0
    # ... and counts for little in the pose graph too.
    assert wild_info[0, 0] < 0.15 * near_info[0, 0]
    # A corridor: the match says nothing along x, odometry holds it.
    corridor = scan.copy()
    corridor[0, 0] = 0.0
    along, _ = _fuse(np.array([30.0, 3.0, 0.0]), corridor, odo)
    assert abs(along[0]) < 1e-3 and 1.0 < along[1] < 2.0


def test_distance_scale_learnt_from_small_steps() -> None:
    """A wrong wheel diameter is found even when scans are logged every 100 mm (each step's own
    0.5 mm of error is far below a scan match's noise: the scale is measured over a metre)."""
    sim = tour(2, laps=2, dist_step=100.0, scale_error=0.01)
    res = build_map(sim.log, lines=False)
    cal = res.summary["registration"]["odometry_calibration"]
    assert cal["distance_scale"] == pytest.approx(1 / 1.01, abs=0.002), cal
    _, _, rms = figures(res, sim)
    assert rms < 25.0, rms


@pytest.mark.parametrize("drift", [0.15, -0.1, 0.05])
def test_heading_drift_learnt_scan_to_scan(drift: float) -> None:
    """Unequal wheels (a steady heading drift per metre) are measured scan to scan over straight
    runs: against the local map, laid out with the drifting odometry itself, it would come out
    too small."""
    sim = tour(7, drift=drift)
    res = build_map(sim.log, lines=False)
    cal = res.summary["registration"]["odometry_calibration"]
    assert cal["drift_deg_per_m"] == pytest.approx(-drift, abs=0.015), cal


@pytest.mark.parametrize("seed", [2, 3])
def test_good_odometry_is_trusted_as_it_deserves(seed: int) -> None:
    """Odometry of a few tenths of a percent (a simulator's, or a well-kept robot's) against a
    sparse, noisy laser (181 beams, 15 mm): the scans' matches are worth less than the
    odometry, and the noise scale fitted against the matches' claims must say so (it sits at
    its floor). With matches claiming more than they are worth it came out 3 to 5 times higher,
    and the scans' noise went into the trajectory."""
    sim = tour(
        seed,
        translation_error=0.002,
        rotation_error=0.002,
        drift=0.0,
        range_noise=15.0,
        readings=181,
    )
    res = build_map(sim.log, lines=False)
    assert res.summary["registration"]["odometry_noise_scale"] <= 0.012
    _, _, rms = figures(res, sim)
    _, _, raw = figures(build_map(sim.log, register=False, lines=False), sim)
    assert rms < raw + 5.0, (rms, raw)


@functools.cache
def _bench() -> Any:
    """``benchmarks/bench_build_real.py``, loaded as a module."""
    import importlib.util
    from pathlib import Path

    path = Path(__file__).resolve().parents[2] / "benchmarks" / "bench_build_real.py"
    spec = importlib.util.spec_from_file_location("bench_build_real", path)
    assert spec is not None and spec.loader is not None
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    return bench


def bench_odometry(name: str) -> dict[str, Any]:
    """The simulation settings of one odometry class of ``benchmarks/bench_build_real.py``."""
    return dict(_bench().ODOMETRIES[name])


def bench_sim(shared_dir: Any, site: str, odometry: str, seed: int, **more: Any) -> Any:
    """One log of ``benchmarks/bench_build_real.py`` (a real ARIA map, an odometry class, a draw;
    a map of its ``--held-out`` ones toured through free places as it tours them), simulated
    (``more``: ``simulate_log`` arguments that differ from the class's)."""
    import mapkit

    world = mapkit.load(shared_dir / "real" / site)
    settings = {**_bench().simulation(world, site, odometry, seed), **more}
    return simulate_log(world, loop=True, seed=seed, odometry_origin="zero", **settings)


def bench_log(
    shared_dir: Any,
    site: str,
    odometry: str,
    seed: int,
    simulate: dict[str, Any] | None = None,
    **build: Any,
) -> tuple[Any, float]:
    """One log of :func:`bench_sim` built (``simulate``: its further arguments; ``build``: further
    arguments of ``build_map``): the result and its trajectory RMS against the truth (mm)."""
    sim = bench_sim(shared_dir, site, odometry, seed, **(simulate or {}))
    res = build_map(sim.log, lines=False, **build)
    truth = sim.truth[np.searchsorted(sim.truth_ids, res.scan_ids)]
    # The odometry starts at 0 0 0 (as on a robot): the poses go in the world through the truth's
    # start.
    rms, _ = trajectory_rms(compose(sim.truth[0], np.asarray(res.poses)), truth)
    return res, rms


def turns_fitted_alone(monkeypatch: Any) -> None:
    """Builds from now on fit the robot's turn error from each log alone, as before round 27
    presumed 0.1 % (for the tests whose story was told of builds that fitted it)."""
    from mapkit.build import _odometry

    monkeypatch.setattr(_odometry, "_PRESUMED_TURN_ERROR", None)


def mobilesim() -> dict[str, Any]:
    """A simulator's odometry and laser as ARIA's logger records them from MobileSim: the
    "good" class of ``benchmarks/bench_build_real.py`` (the issue's)."""
    return bench_odometry("good")


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_a_simulators_odometry_on_a_real_site_is_not_made_worse(seed: int, shared_dir) -> None:
    """A simulator's odometry (0.05 %: a few mm over the whole tour, as MobileSim's is) and a
    dense 12 mm laser on a real ARIA map. A turn on the spot is right to a thousandth of a degree
    by odometry and to a tenth by a scan match: with the turns trusted no more than the straight
    steps, the first turn turned the map by 0.15-0.25 degrees about the start, and the tour came
    out 40 mm RMS where odometry was 5-8 mm. With a scan every 150 mm, the global refinement
    counted each scan's match as independent of its neighbours': they outvoted the odometry,
    and seed 1 came out 11.6 mm RMS where odometry was 1.3."""
    import mapkit

    world = mapkit.load(shared_dir / "real" / "amrisim-AMROffice.map")
    sim = simulate_log(world, loop=True, seed=seed, **mobilesim())
    res = build_map(sim.log, lines=False)
    raw = build_map(sim.log, register=False, lines=False)
    at = sim.truth[np.searchsorted(sim.truth_ids, res.scan_ids)]
    rms, _ = trajectory_rms(res.poses, at)
    raw_rms, _ = trajectory_rms(raw.poses, sim.truth[np.searchsorted(sim.truth_ids, raw.scan_ids)])
    assert rms <= raw_rms + 8.0, (rms, raw_rms)
    # The map is not turned about the start: the heading after the first turn is the truth's.
    turned = (np.asarray(res.poses)[10, 2] - at[10, 2] + 180.0) % 360.0 - 180.0
    assert abs(turned) < 0.1, turned


def test_a_drift_the_calibration_misses_is_taken_out(shared_dir) -> None:
    """A 0.02 deg/m heading drift with a scan every 0.5 m (the benchmark's "drift" class) on a
    real ARIA map: scan to scan over 2 m the drift is lost in the matches' noise, and the
    calibration does not take it. Registered with it, the passes came out apart and the
    refinement, leaning on the odometry, could not bring them together: 54 mm RMS. The
    refinement finds it over the whole log, and the log is registered again without it."""
    res, rms = bench_log(shared_dir, "aria294-columbia.map", "drift", seed=2)
    assert rms < 20.0, rms
    learnt = res.summary["registration"]["odometry_calibration"]["drift_deg_per_m"]
    assert learnt == pytest.approx(-0.02, abs=0.005), learnt


@pytest.mark.parametrize(
    ("site", "scale_error", "within"),
    [("aria291-columbia.map", 0.01, 0.0012), ("aria294-columbia.map", 0.005, 0.0004)],
)
def test_a_wrong_wheel_diameter_is_measured_without_the_local_maps_lean(
    site: str, scale_error: float, within: float, shared_dir
) -> None:
    """Distances 1 % or 0.5 % too long on a real ARIA map (a tour of 800-900 scans). Measured
    between local-map matches, the distance scale leaned towards the odometry being calibrated
    (the local map is laid out with it): +0.0026 and +0.0009 off. Matched scan to scan, the
    runs the drift is measured on give +0.0007 and -0.00001."""
    import mapkit

    world = mapkit.load(shared_dir / "real" / site)
    sim = simulate_log(
        world,
        loop=True,
        seed=1,
        odometry_origin="zero",
        readings=361,
        range_noise=10.0,
        scale_error=scale_error,
    )
    res = build_map(sim.log, lines=False)
    learnt = res.summary["registration"]["odometry_calibration"]["distance_scale"]
    assert learnt == pytest.approx(1.0 / (1.0 + scale_error), abs=within), learnt


@pytest.mark.parametrize("seed", [1, 5])
def test_exact_odometry_on_a_real_site_stays_within_the_issues_bar(shared_dir, seed: int) -> None:
    """The true poses as odometry (the benchmark's "exact" class, the issue's own check: it
    drifted to 60-86 mm) on a real ARIA map, 1,560 scans: the trajectory stays within odometry's
    + 15 mm. Draw 5 (one no round was tuned on): 6.5 mm (12.5 before round 13 matched the first
    scan against the other passes' planes). Draw 1: 8.8 mm, where it was 18.7 until round 22 took
    no match's residual as less than the laser's own scatter (its turns' matches had claimed
    more than they were worth, and outvoted the odometry's turns)."""
    _, rms = bench_log(shared_dir, "aria291-columbia.map", "exact", seed=seed)
    assert rms <= 0.4 + 15.0, rms  # odometry's own 0.4 mm is the log's rounding of the poses


@pytest.mark.parametrize("noise", [20.0, 30.0])
def test_a_noisy_lasers_matches_do_not_outweigh_exact_odometry(shared_dir, noise: float) -> None:
    """The true poses as odometry, a laser whose ranges scatter 20 or 30 mm (the "exact" class
    has 15). Each point was paired with the nearest of the local map's points, themselves noisy,
    within 40 mm: the residuals read 13-15 mm whatever the noise, the matches claimed up to four
    times their worth, the odometry was fitted as 60-270 times worse than it is, and the scans
    took the trajectory 33.5 and 76.3 mm from the truth. A match's residual is now taken as no
    less than the laser's own scatter about the walls, read off the scans (draw 1 on AMROffice;
    docs/logs.md, round 22)."""
    res, rms = bench_log(
        shared_dir, "amrisim-AMROffice.map", "exact", seed=1, simulate={"range_noise": noise}
    )
    reg = res.summary["registration"]
    assert 0.6 * noise < reg["laser_noise_mm"] < noise, reg
    assert rms <= 0.4 + 15.0, rms


@pytest.mark.parametrize(
    ("site", "seed", "before"),
    [("amrisim-AMROffice.map", 2, 109.8), ("omron-ld-showroom-ex4.map", 2, 160.2)],
)
def test_a_noisy_lasers_matches_allow_for_its_noise_everywhere(
    shared_dir, site: str, seed: int, before: float
) -> None:
    """A slipping robot (the benchmark's "rough" class) with a 30 mm laser (23-25 mm about the
    walls). Round 22 widened registration's reach alone; the refinement's matches (20 mm reach,
    residual under 30 mm, each claimed as 10 mm points), the calibration's and the loop
    closures' stayed set for a 15 mm laser, and the maps came out turned 0.5 and 1.4 degrees,
    109.8 and 160.2 mm RMS from the truth. Beyond 16 mm of scatter every match now allows,
    claims and (but for the loop closures) reaches in proportion (docs/logs.md, round 23)."""
    res, rms = bench_log(shared_dir, site, "rough", seed=seed, simulate={"range_noise": 30.0})
    reg = res.summary["registration"]
    assert reg["laser_noise_mm"] > 20.0, reg
    assert reg["refined"] > 0, reg
    assert rms < 40.0 < before, rms


def test_exact_odometry_built_with_what_the_robots_other_logs_taught(shared_dir) -> None:
    """Draw 11 of the test above, which misses the bar on its own (34.7 mm: its turns were
    fitted at 0.35 %, and the turns' matches outvoted true odometry). Three other logs of the
    same robot, on another site (AMROffice draws 1-3), teach its turns' error as 0.03 %
    (robot_turn_error); built with it, the log stays within odometry's + 15 mm (12.3 mm;
    docs/logs.md, rounds 20 and 22)."""
    from mapkit.build import robot_turn_error

    taught = robot_turn_error(
        bench_log(shared_dir, "amrisim-AMROffice.map", "exact", seed=seed)[0] for seed in (1, 2, 3)
    )
    assert taught is not None and taught < 0.001, taught
    res, rms = bench_log(shared_dir, "aria291-columbia.map", "exact", seed=11, turn_error=taught)
    assert res.summary["registration"]["odometry_turn_error_stated"]
    assert rms <= 0.4 + 15.0, rms


def test_the_scans_of_a_turn_on_the_spot_hold_the_map(shared_dir, monkeypatch) -> None:
    """A robot that slips in its turns (the benchmark's "rough" class) on a real ARIA map, draw
    6: it starts by turning 140 degrees on the spot, and on that leg its turns, calibrated,
    still read 1 % short (the slip differs from leg to leg; the calibration takes the mean).
    The global refinement counted the matches of those scans for the path they covered, none,
    and the odometry alone set how the map sits about the start: turned 0.3 degrees, 66.7 mm
    RMS. Counted for the turn too, the matches hold it (13.5 mm; since round 12 registers the
    start with all its points, 21.8 mm, and 75.1 without the turn counted)."""
    import mapkit.build._refine as refine_module

    _, rms = bench_log(shared_dir, "amrisim-AMROffice.map", "rough", seed=6)
    assert rms < 40.0, rms  # the issue's bar (odometry is metres off)
    monkeypatch.setattr(refine_module, "_TURN_SHARE", 0.0)
    _, unheard = bench_log(shared_dir, "amrisim-AMROffice.map", "rough", seed=6)
    assert unheard > 40.0, unheard


def test_the_start_is_registered_with_all_its_points(shared_dir, monkeypatch) -> None:
    """The "rough" class on a real ARIA map, draw 6: the robot starts by turning on the spot, and
    those first steps set how the whole map sits about the start. Registered with the scan side's
    120 points, a 361-beam scan there was matched 0.11 degrees RMS off from its true pose, and
    the map came out turned 0.25 degrees about the start, 69.7 mm RMS. Registered with all its
    map-side points over the first metre, it is 32.8 mm."""
    import mapkit.build._register as register_module

    _, rms = bench_log(shared_dir, "aria291-columbia.map", "rough", seed=6)
    assert rms < 40.0, rms  # the issue's bar (odometry is metres off)
    monkeypatch.setattr(register_module, "_START_PATH", 0.0)
    _, few = bench_log(shared_dir, "aria291-columbia.map", "rough", seed=6)
    assert few > 40.0, few


def test_the_first_scan_is_matched_against_the_other_passes_planes(shared_dir, monkeypatch) -> None:
    """Exact odometry on a real ARIA map, draw 1: the first scan alone places the map about the
    start, and the refinement matches it against the other passes, scans seen from elsewhere.
    Matched against their points (a 181-beam laser's, 15 mm of range noise) it came out 0.14
    degrees off and turned the map, 23.9 mm RMS; against those points smoothed into local planes
    it is 18.7 mm. (Both as registration weighed the matches before round 22: since it takes no
    match's residual as less than the laser's scatter, the log is 8.8 mm either way; and with
    its turns fitted from the log alone: presumed 0.1 % since round 27, its odometry holds the
    start, and it is 13.9 mm against the points too.)"""
    import mapkit.build._refine as refine_module
    import mapkit.build.builder as builder_module

    turns_fitted_alone(monkeypatch)
    monkeypatch.setattr(builder_module, "surface_noise", lambda scans: 0.0)
    _, rms = bench_log(shared_dir, "aria291-columbia.map", "exact", seed=1)
    assert rms < 21.0, rms
    monkeypatch.setattr(
        refine_module,
        "anchor_match",
        lambda first, others, tgt, tn, pose, widen: refine_module.match(
            first, others, tgt, tn, pose, widen
        ),
    )
    _, points = bench_log(shared_dir, "aria291-columbia.map", "exact", seed=1)
    assert points > 21.0, points


def test_a_start_turned_wrong_by_odometry_is_turned_back_by_the_first_scan(
    shared_dir, monkeypatch
) -> None:
    """The benchmark's "drift" class on a real ARIA map, draw 4: the robot's turns err 0.5 %, and
    its first turn on the spot (140 degrees in five steps) came out 0.22 degrees wrong by
    odometry, where each scan-to-scan match of the turn errs 0.2 degrees. The first scan's match
    against the way home showed the map turned by 0.27-0.44 degrees, and the refinement refused
    it beyond 0.15: the whole map stayed turned 0.2 degrees about the start, 40.9 mm RMS against
    the issue's 40. Taken up to 0.5 degrees, it is 33.9. (As registration weighed the matches
    before round 22; since it takes no match's residual as less than the laser's scatter the
    log is 34.2 mm, and the first scan's match is within 0.15 degrees.) The turns are fitted
    from the log alone here: presumed 0.1 %, which its turns cannot rule out, the odometry's
    0.22 degrees hold the start and the log misses the bar, 46.9 mm (docs/logs.md, round 27).

    On round 27's machine the matches weighed as before round 22 come out otherwise by a hair
    (at the previous commit too), and the first scan's match is within 0.15 degrees there too
    (34.9 mm with the bar at 0.15): the log no longer shows the bar, which the office's slipping
    start below does. What it still shows: fitted alone, its turns and first scan hold the map
    within the issue's bar, whether or not a match's residual is floored at the laser's scatter."""
    import mapkit.build.builder as builder_module

    turns_fitted_alone(monkeypatch)
    _, rms = bench_log(shared_dir, "amrisim-AMROffice.map", "drift", seed=4)
    assert rms < 37.0, rms
    monkeypatch.setattr(builder_module, "surface_noise", lambda scans: 0.0)
    _, rms = bench_log(shared_dir, "amrisim-AMROffice.map", "drift", seed=4)
    assert rms < 37.0, rms


def test_a_start_that_slipped_is_turned_back_by_the_first_scan(shared_dir, monkeypatch) -> None:
    """The benchmark's "rough" class (turns that slip 2 %, give or take 1 % a leg) on a map no
    round was measured on (an office, toured through free places), draw 3. Its first turn on
    the spot slipped, and the map came out turned 0.6 degrees about the start. The first scan's
    match against the way home showed it (-0.54 degrees) and was refused beyond 0.5: 74.4 mm
    RMS. The bar widens by what the odometry over the start's first metre may have turned the
    map by (three of its standard deviations), and the first scan turns it back."""
    import mapkit.build._refine as refine_module

    _, rms = bench_log(shared_dir, "aria-office.map", "rough", seed=3)
    assert rms < 25.0, rms
    monkeypatch.setattr(refine_module, "_anchor_turn", lambda *_: refine_module._ANCHOR_TURN)
    _, refused = bench_log(shared_dir, "aria-office.map", "rough", seed=3)
    assert refused > 40.0, refused


def test_sweeps_whose_lag_varies_do_not_turn_the_map(shared_dir, monkeypatch) -> None:
    """The benchmark's "jitter" class on a real ARIA map: each sweep's lag varies by up to 40 ms,
    a degree and a half at a turn on the spot's 40 deg/s. Registration leaves those sweeps up to
    1.6 degrees off, their matches in the global refinement stop in minima 0.3-1.0 degrees off
    and claim a tenth, and the odometry holds them only as loosely as their lag. On draw 3 they
    turned the whole map 0.4 degrees about the start, 83.8 mm RMS; left out of the refinement
    (neither matched nor matched against), 13.4 (docs/logs.md, round 18). Since the lag is
    measured on more pairs (round 21) draw 3 no longer shows it; draw 2 does: 0.25 degrees and
    54.6 mm with them, 0.09 and 23.8 without (as registration weighed the matches before round
    22; since it takes no match's residual as less than the laser's scatter, 42.1 and 18.9).
    Both with the turns fitted from the log alone (0.38 %): presumed 0.1 % (round 27), the
    odometry holds the turning sweeps too, 16.0 mm, and 21.2 with them matched."""
    import mapkit.build._refine as refine_module
    import mapkit.build.builder as builder_module

    turns_fitted_alone(monkeypatch)
    _, rms = bench_log(shared_dir, "amrisim-AMROffice.map", "jitter", seed=2)
    assert rms < 30.0, rms
    monkeypatch.setattr(builder_module, "surface_noise", lambda scans: 0.0)
    _, rms = bench_log(shared_dir, "amrisim-AMROffice.map", "jitter", seed=2)
    assert rms < 30.0, rms
    monkeypatch.setattr(refine_module, "_calm", lambda odometry_from, n: np.ones(n, dtype=bool))
    _, with_them = bench_log(shared_dir, "amrisim-AMROffice.map", "jitter", seed=2)
    assert with_them > 45.0, with_them


def test_a_robots_turn_error_stated_holds_its_turns(shared_dir, monkeypatch) -> None:
    """The benchmark's "jitter" class on a real ARIA map, draw 2: a simulator's turns (0.1 %,
    stated as such). Fitted from the log, the turns' error came out 0.38 %, each turn's own
    scan match outvoted its odometry, and the turn into a dead-end corridor driven out and back
    turned it 0.26 degrees: 40.8 mm RMS. Stated, 18.6 (docs/logs.md, round 19); 16.0 now, as
    with none stated (0.1 % is presumed, round 27)."""
    res, rms = bench_log(shared_dir, "amrisim-AMROffice.map", "jitter", seed=2, turn_error=0.001)
    assert res.summary["registration"]["odometry_turn_error_stated"]
    assert rms < 25.0, rms
    turns_fitted_alone(monkeypatch)
    _, fitted = bench_log(shared_dir, "amrisim-AMROffice.map", "jitter", seed=2)
    assert fitted > rms, fitted


def test_a_robots_turns_are_presumed_good_unless_its_log_rules_it_out(
    shared_dir, monkeypatch
) -> None:
    """The benchmark's "jitter" class (a simulator's turns, right to a few hundredths of a
    percent) on a real ARIA map, draw 20, which no round was measured on before round 27.
    Fitted from the log alone, its turns came out 0.45 %: the odometry of its first turn on the
    spot (216 degrees) was held to 1 degree, and the first scan's match, 0.2 degrees off even
    against the true walls, turned the whole map 0.19 degrees about the start: 39.9 mm RMS.
    Presumed 0.1 % (its turns do not rule that out), 13.3. A robot that slips 2 % in its turns
    (the "rough" class, draw 21) rules the presumption out in registration's warm-up, and is
    built exactly as with its turns fitted alone (docs/logs.md, round 27)."""
    res, rms = bench_log(shared_dir, "amrisim-AMROffice.map", "jitter", seed=20)
    reg = res.summary["registration"]
    assert reg["odometry_turn_error_presumed"] and reg["odometry_turn_error"] == 0.001, reg
    assert rms < 20.0, rms
    slipping, _ = bench_log(shared_dir, "amrisim-AMROffice.map", "rough", seed=21)
    reg = slipping.summary["registration"]
    assert not reg["odometry_turn_error_presumed"] and reg["odometry_turn_error"] > 0.005, reg
    turns_fitted_alone(monkeypatch)
    _, fitted = bench_log(shared_dir, "amrisim-AMROffice.map", "jitter", seed=20)
    assert fitted > 30.0, fitted
    alone, _ = bench_log(shared_dir, "amrisim-AMROffice.map", "rough", seed=21)
    np.testing.assert_array_equal(alone.poses, slipping.poses)


def test_a_noisy_lasers_robot_has_its_turns_fitted_not_presumed(shared_dir, monkeypatch) -> None:
    """The benchmark's "jitter" class (turns that err 0.1 %, sweeps whose lag varies) with a
    30 mm laser (20 mm about the walls), columbia-2.9.1 draw 2. With its turns held at the
    presumed 0.1 % (which is what they err), a loop closure matched against its first turns'
    sweeps turned the map 0.9 degrees about the start: 205.1 mm from the truth; fitted from the
    log (0.4 %), 23.6.
    The presumption was measured under the benchmark's 10-15 mm lasers and holds only under a
    laser that scatters 16 mm or less (docs/logs.md, round 28)."""
    from mapkit.build import _odometry

    noisy = {"range_noise": 30.0}
    res, rms = bench_log(shared_dir, "aria291-columbia.map", "jitter", seed=2, simulate=noisy)
    reg = res.summary["registration"]
    assert reg["laser_noise_mm"] > 16.0 and not reg["odometry_turn_error_presumed"], reg
    assert rms < 40.0, rms
    monkeypatch.setattr(_odometry, "_PRESUMED_UP_TO_NOISE", math.inf)
    res, held = bench_log(shared_dir, "aria291-columbia.map", "jitter", seed=2, simulate=noisy)
    assert res.summary["registration"]["odometry_turn_error_presumed"]
    assert held > 100.0, held


def test_sweeps_older_than_their_poses_are_placed_where_they_were_taken(
    shared_dir, monkeypatch
) -> None:
    """The benchmark's "lag" class on a real ARIA map, draw 1: a simulator's odometry (0.1 %) with
    every sweep 40 ms older than the pose logged with it, as ARIA stamps a simulated laser's
    sweep. While turning (40 deg/s) each sweep is turned 1.6 degrees against its pose, and the
    steps into and out of every turn disagreed with the odometry by that much: 76.4 mm RMS where
    odometry is 21.5. The lag is measured from those steps and each sweep placed where the robot
    was: 4.6 mm."""
    import mapkit.build.builder as builder_module
    from mapkit.build._lag import Lag

    res, rms = bench_log(shared_dir, "amrisim-AMROffice.map", "lag", seed=1)
    assert res.summary["registration"]["scan_lag_ms"] == pytest.approx(40.0, abs=3.0)
    assert rms < 15.0, rms
    monkeypatch.setattr(builder_module, "measure_lag", lambda *a: Lag(0.0, 0.0, 0.0, 0))
    _, lagging = bench_log(shared_dir, "amrisim-AMROffice.map", "lag", seed=1)
    assert lagging > 40.0, lagging


def test_sweeps_whose_lag_varies_are_not_chained_through_their_turns(
    shared_dir, monkeypatch
) -> None:
    """The benchmark's "jitter" class on a real ARIA map, draw 4: the "lag" class's 40 ms, varying
    by up to 40 ms either way from sweep to sweep. Each sweep taken while turning is then up to
    1.6 degrees off its pose by a part of its own, which no one lag takes out. Built with the lag
    alone, 72.9 mm RMS (odometry: 22.5); with the spread measured too, the odometry taken from
    the calm sweeps on either side of each turn and the turning sweeps left to their matches (and
    out of the local map), 11.4 mm. The spread is 40 / sqrt(3) = 23.1 ms; fitted on more pairs
    since round 21, it is 36.8 here (19-37 on the benchmark's 27 logs of the class)."""
    import mapkit.build.builder as builder_module

    res, rms = bench_log(shared_dir, "amrisim-AMROffice.map", "jitter", seed=4)
    reg = res.summary["registration"]
    assert 12.0 < reg["scan_lag_jitter_ms"] < 40.0, reg  # taken, and within the lag's swing
    assert rms < 30.0, rms
    measure = builder_module.measure_lag
    monkeypatch.setattr(builder_module, "measure_lag", lambda *a: measure(*a)._replace(jitter=0.0))
    _, chained = bench_log(shared_dir, "amrisim-AMROffice.map", "jitter", seed=4)
    assert chained > 60.0, chained
