"""mapkit build: the pipeline's parts and its quality on simulated logs of the sample maps."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

import mapkit
from mapkit.build import build_map, extract_lines
from mapkit.build._graph import PoseGraph, between, sigma_info, wrap
from mapkit.build._match import icp, scan_normals, scan_normals_many, transform
from mapkit.build.quality import distance_to_segments, trajectory_rms
from mapkit.errors import LogFormatError
from mapkit.formats.laser2d import write_log
from mapkit.formats.registry import convert_file
from mapkit.model.scan import LaserLog, LaserScan, LogHeader, Pose2D
from mapkit.samples import sample_path
from mapkit.simulate import simulate_log


@pytest.fixture(scope="module")
def office() -> mapkit.MapData:
    return mapkit.load(sample_path("office"))


@pytest.fixture(scope="module")
def office_sim(office):
    # Strong drift so that the raw odometry map is visibly wrong.
    return simulate_log(office, loop=True, seed=11, drift=0.15, rotation_error=0.03)


@pytest.fixture(scope="module")
def office_built(office_sim):
    return build_map(office_sim.log)


def test_quality_on_the_office_sample(office, office_sim, office_built) -> None:
    raw = build_map(office_sim.log, register=False)
    truth_lines = office.lines
    d_reg = np.median(distance_to_segments(office_built.map.points, truth_lines))
    d_raw = np.median(distance_to_segments(raw.map.points, truth_lines))
    assert d_reg <= office_built.map.scan.resolution
    assert d_raw > 60 and d_raw >= 5 * d_reg, (d_raw, d_reg)
    truth = office_sim.truth[np.searchsorted(office_sim.truth_ids, office_built.scan_ids)]
    rms_reg, _ = trajectory_rms(office_built.poses, truth)
    rms_raw, _ = trajectory_rms(raw.poses, truth)
    assert rms_reg < 60.0 and rms_raw > 3 * rms_reg, (rms_reg, rms_raw)
    loops = office_built.summary["loops"]
    assert loops["tags"] == 1 and loops["tags_matched"] == 1 and loops["revisits"] > 0


def test_built_map_is_an_aria_map(office, office_built) -> None:
    m = office_built.map
    assert m.scan.resolution == 20 and m.scan.points_sorted and m.scan.lines_sorted
    assert np.all(m.points % 20 == 0)
    pts = m.points
    assert np.all(np.diff(pts[:, 0]) >= 0)
    home = m.objects[0]
    assert home.type == "RobotHome" and math.hypot(home.x - 1500, home.y - 6000) < 1.0
    # Goals from cairn: events, at their corrected place: near the map's goals of the same name.
    built = {o.name: o for o in m.objects if o.type == "GoalWithHeading"}
    want = {o.name: o for o in office.objects if o.base_type == "Goal"}
    assert set(built) == set(want)
    for name, g in built.items():
        assert math.hypot(g.x - want[name].x, g.y - want[name].y) < 150.0, name
    # Lines lie on the true walls.
    ends = m.lines.reshape(-1, 2)
    assert len(m.lines) >= 10
    assert np.median(distance_to_segments(ends, office.lines)) < 40.0
    text = mapkit.dumps(m)
    assert mapkit.loads(text) == m


def test_summary_and_no_register(office_sim, office_built) -> None:
    s = office_built.summary
    assert s["scans_used"] == s["scans_in_log"] == len(office_sim.log.scans)
    assert s["registration"]["registered"] > 0.9 * s["scans_used"]
    assert 2.0 < s["registration"]["median_residual_mm"] < 20.0
    raw = build_map(office_sim.log, register=False, lines=False)
    assert np.allclose(raw.poses, raw.odometry)
    assert raw.summary["registration"]["registered"] == 0 and len(raw.map.lines) == 0


@pytest.mark.slow
def test_quality_on_the_building_sample() -> None:
    m = mapkit.load(sample_path("building"))
    sim = simulate_log(m, loop=True, seed=1)
    reg = build_map(sim.log, lines=False)
    raw = build_map(sim.log, register=False, lines=False)
    d_reg = np.median(distance_to_segments(reg.map.points, m.lines))
    d_raw = np.median(distance_to_segments(raw.map.points, m.lines))
    assert d_reg <= 20 and d_raw >= 5 * d_reg, (d_reg, d_raw)


def test_icp_recovers_a_known_motion() -> None:
    # An L-shaped corner seen from the origin, moved by a known pose.
    t = np.linspace(0, 3000, 151)
    corner = np.concatenate(
        [
            np.stack([t, np.full_like(t, 2000.0)], 1),
            np.stack([np.full_like(t, 3000.0), t - 1000], 1),
        ]
    )
    nrm = np.concatenate([np.tile([0.0, 1.0], (151, 1)), np.tile([1.0, 0.0], (151, 1))])
    from scipy.spatial import cKDTree

    true = np.array([120.0, -80.0, math.radians(3.0)])
    src = transform(corner, np.array([0.0, 0.0, 0.0]))
    # Source in the robot frame: world = true * src  =>  src = inverse(true) * world
    c, s = math.cos(true[2]), math.sin(true[2])
    local = (corner - true[:2]) @ np.array([[c, -s], [s, c]])
    r = icp(local, cKDTree(corner), corner, nrm, np.zeros(3))
    assert r.ok and np.allclose(r.pose[:2], true[:2], atol=1.0)
    assert abs(wrap(r.pose[2] - true[2])) < math.radians(0.05)
    assert r.weak_direction() is None
    assert src.shape == corner.shape


def test_scan_normals_of_a_wall() -> None:
    x = np.linspace(-2000, 2000, 81)
    n = scan_normals(np.stack([x, np.full_like(x, 1500.0)], 1))
    good = np.isfinite(n[:, 0])
    assert good.sum() >= 70 and np.allclose(np.abs(n[good, 1]), 1.0)


@settings(max_examples=40, deadline=None)
@given(
    st.lists(st.integers(min_value=0, max_value=60), min_size=1, max_size=6),
    st.integers(min_value=0, max_value=2**31),
)
def test_scan_normals_of_many_scans_equal_one_by_one(sizes: list[int], seed: int) -> None:
    """The batched normals (all scans in one pass) are each scan's own, scan borders included."""
    rng = np.random.default_rng(seed)
    scans = []
    for n in sizes:
        # Pieces of walls with noise, gaps and an occasional far point: every case of the test.
        t = np.sort(rng.uniform(-3000, 3000, n))
        p = np.stack([t, 2000.0 + rng.normal(0, 5, n)], 1) @ np.array(
            [[math.cos(seed), math.sin(seed)], [-math.sin(seed), math.cos(seed)]]
        )
        if n and rng.random() < 0.5:
            p[rng.integers(0, n)] += 800.0
        scans.append(p)
    many = scan_normals_many(scans)
    assert len(many) == len(scans)
    for p, got in zip(scans, many, strict=True):
        want = scan_normals_one(p)
        assert got.shape == want.shape
        assert np.array_equal(np.isnan(got), np.isnan(want))
        ok = np.isfinite(got[:, 0])
        # A normal's sign is arbitrary: compare up to it.
        assert np.allclose(np.abs(np.sum(got[ok] * want[ok], axis=1)), 1.0, atol=1e-6)


def scan_normals_one(pts: np.ndarray, window: int = 3) -> np.ndarray:
    """The normals of one scan, written out plainly (the reference for the batched version)."""
    n = len(pts)
    out = np.full((n, 2), np.nan)
    for c in range(window, n - window):
        nb = pts[c - window : c + window + 1]
        mean = nb.mean(axis=0)
        w, v = np.linalg.eigh(np.cov((nb - mean).T, bias=True))
        gaps = np.hypot(*np.diff(nb, axis=0).T).max()
        span = float(np.hypot(*(nb[-1] - nb[0])))
        rng_ = float(np.hypot(*mean))
        if w[0] < 0.05 * max(w[1], 1e-9) and gaps < 0.08 * rng_ + 60.0 and span > 20.0:
            d = v[:, 1]
            ang = math.atan2(d[1], d[0])
            out[c] = [-math.sin(ang), math.cos(ang)]
    return out


def test_pose_graph_rejects_a_wrong_closure() -> None:
    """A closure that disagrees with everything else (caught on the wrong wall) is switched off
    by the consistency check; the right one stays and the square closes."""
    true, est, g = _square_graph(np.random.default_rng(3), turn_sigma=0.002)
    n = len(true)
    g.add(0, n - 1, between(true[0], true[-1]), sigma_info(5, 5, 0.005), robust=True)
    wrong = true[n // 2].copy()
    wrong[:2] += [1500.0, -900.0]
    g.add(5, n // 2, between(true[5], wrong), sigma_info(5, 5, 0.005), robust=True)
    plain = g.optimize(est)  # the Huber weight alone lets the wrong closure bend the square
    checked = g.optimize(est, reject=5.0)
    assert g.rejected == {len(g) - 1}
    err = lambda x: float(np.sqrt(np.mean(np.sum((x[:, :2] - true[:, :2]) ** 2, 1))))  # noqa: E731
    assert err(checked) < 0.5 * err(plain), (err(checked), err(plain))
    assert err(checked) < 40.0


def _square_graph(
    rng: np.random.Generator, turn_sigma: float
) -> tuple[np.ndarray, np.ndarray, PoseGraph]:
    true = [np.zeros(3)]
    for k in range(1, 40):
        step = np.array([0.0, 0.0, math.pi / 2]) if k % 10 == 0 else np.array([500.0, 0.0, 0.0])
        p = true[-1]
        c, s = math.cos(p[2]), math.sin(p[2])
        true.append(
            np.array(
                [
                    p[0] + c * step[0] - s * step[1],
                    p[1] + s * step[0] + c * step[1],
                    wrap(p[2] + step[2]),
                ]
            )
        )
    T = np.array(true)
    g = PoseGraph()
    est = [T[0]]
    for k in range(1, len(T)):
        z = between(T[k - 1], T[k]) + np.array(
            [rng.normal(0, 10), rng.normal(0, 10), rng.normal(0, turn_sigma)]
        )
        g.add(k - 1, k, z, sigma_info(10, 10, turn_sigma))
        p = est[-1]
        c, s = math.cos(p[2]), math.sin(p[2])
        est.append(
            np.array([p[0] + c * z[0] - s * z[1], p[1] + s * z[0] + c * z[1], wrap(p[2] + z[2])])
        )
    return T, np.array(est), g


def test_pose_graph_closes_a_square() -> None:
    T, E, g = _square_graph(np.random.default_rng(0), turn_sigma=0.02)
    g.add(0, len(T) - 1, between(T[0], T[-1]), sigma_info(5, 5, 0.005), robust=True)
    before = np.sqrt(np.mean(np.sum((E[:, :2] - T[:, :2]) ** 2, 1)))
    after_x = g.optimize(E)
    after = np.sqrt(np.mean(np.sum((after_x[:, :2] - T[:, :2]) ** 2, 1)))
    assert after < before / 3, (before, after)
    assert np.allclose(after_x[0], E[0])


def test_extract_lines_of_a_room() -> None:
    walls = np.array(
        [[0, 0, 4000, 0], [4000, 0, 4000, 3000], [4000, 3000, 0, 3000], [0, 3000, 0, 0]],
        dtype=float,
    )
    rng = np.random.default_rng(1)
    pts = []
    for x1, y1, x2, y2 in walls:
        t = np.linspace(0, 1, 200)
        pts.append(
            np.stack([x1 + t * (x2 - x1), y1 + t * (y2 - y1)], 1) + rng.normal(0, 4, (200, 2))
        )
    p = np.rint(np.concatenate(pts) / 20) * 20
    segs = extract_lines(p)
    assert 4 <= len(segs) <= 8
    assert distance_to_segments(segs.reshape(-1, 2), walls).max() < 40
    covered = sum(np.hypot(s[2] - s[0], s[3] - s[1]) for s in segs)
    assert covered > 0.85 * 14000


def test_no_usable_scan_and_convert(tmp_path, office_sim) -> None:
    empty = LaserLog(header=LogHeader(), records=[LaserScan(scan_id=0, xy=np.zeros((5, 2)))])
    with pytest.raises(LogFormatError, match="no scan with enough valid readings"):
        build_map(empty)
    with pytest.raises(ValueError, match="resolution"):
        build_map(empty, resolution=0)
    log_path = tmp_path / "o.2d"
    write_log(office_sim.log, log_path)
    out = tmp_path / "o.map"
    assert "wrote" in convert_file(log_path, out)
    assert mapkit.load(out).scan.num_points > 1000


def test_tolerant_build_skips_bad_records(tmp_path, office_sim) -> None:
    path = tmp_path / "bad.2d"
    write_log(office_sim.log, path)
    lines = path.read_bytes().split(b"\n")
    k = next(i for i, ln in enumerate(lines) if ln.startswith(b"scan1:") and i > 100)
    lines[k] = lines[k][:40] + b" nan"
    path.write_bytes(b"\n".join(lines))
    with pytest.raises(LogFormatError, match=rf"bad\.2d:{k + 1}: "):
        build_map(path)
    res = build_map(path, strict=False, lines=False)
    assert res.summary["scans_used"] == len(office_sim.log.scans) - 1
    assert any(i.location.line == k + 1 for i in res.issues)


def test_goal_pose_follows_the_corrected_scan() -> None:
    # Two scans of a wall; a goal logged between them with an odometry pose.
    x = np.linspace(-2000, 2000, 181)
    xy = np.stack([np.full_like(x, 2000.0), x], 1)
    from mapkit.formats.laser2d import goal_event

    laser_log = LaserLog(
        header=LogHeader(lasers=(mapkit.model.LaserConfig(count=181, start=-45, end=45),)),
        records=[
            LaserScan(scan_id=0, robot=Pose2D(0, 0, 0), xy=xy),
            goal_event("g", Pose2D(100, 0, 0)),
        ],
    )
    res = build_map(laser_log, register=False, lines=False)
    g = next(o for o in res.map.objects if o.name == "g")
    assert (g.type, g.x, g.y) == ("GoalWithHeading", 100.0, 0.0)


def _two_laser_log(world: mapkit.MapData, seed: int):
    """A tour of ``world`` by a robot with a front laser and a rear one (200 mm behind the
    centre, turned 180 degrees), each cycle a sweep of each under one ``logTime:``; the same log
    with each rear sweep given a time of its own (as if logged in a cycle of its own); and the
    true pose of each scan id."""
    sim = simulate_log(world, loop=True, seed=seed, second_laser=(-200.0, 0.0, 180.0))
    apart = tuple(
        dataclasses.replace(r, time=r.time + 0.001)
        if isinstance(r, LaserScan) and r.laser == 2 and r.time is not None
        else r
        for r in sim.log.records
    )
    truth = dict(zip(sim.truth_ids.tolist(), sim.truth, strict=True))
    return sim.log, dataclasses.replace(sim.log, records=apart), truth


def test_the_sweeps_of_one_cycle_are_one_scan(office, tmp_path) -> None:
    """A front and a rear laser, through a file: each cycle's two sweeps are matched as one scan
    that sees all round, placed as the robot was. Matched as scans of their own, each met a
    local map half of the other laser's view (30 logs of real ARIA maps: 10.9 mm RMS on average
    against 9.0 merged, docs/logs.md round 16), and the lag measurement found no pairs to match
    (a front sweep against the rear one before it)."""
    log, apart, truth = _two_laser_log(office, seed=4)
    assert [s.laser for s in log.scans[:4]] == [1, 2, 1, 2]
    path = tmp_path / "two-lasers.2d"
    write_log(log, path)
    res = build_map(path, lines=False)
    s = res.summary
    assert s["scans_in_log"] == 2 * s["scans_used"] and s["sweeps_merged"] == s["scans_used"]
    front = {r.scan_id for r in log.scans if r.laser == 1}
    assert set(res.scan_ids.tolist()) == front
    assert s["registration"]["scan_lag_fitted_ms"] is not None
    rms, _ = trajectory_rms(res.poses, np.array([truth[i] for i in res.scan_ids]))
    assert rms < 10.0, rms
    assert np.median(distance_to_segments(res.map.points, office.lines)) <= 20.0
    # Both lasers' walls are in the map: behind the robot too (the rear laser's alone).
    only_front = build_map(
        dataclasses.replace(
            log,
            header=dataclasses.replace(log.header, lasers=log.header.lasers[:1]),
            records=tuple(
                r for r in log.records if not (isinstance(r, LaserScan) and r.laser == 2)
            ),
        ),
        lines=False,
    )
    assert len(res.map.points) > len(only_front.map.points)
    separate = build_map(apart, lines=False)
    assert separate.summary["scans_used"] == s["scans_in_log"]
    assert separate.summary["registration"]["scan_lag_fitted_ms"] is None


def test_a_cycles_later_sweep_is_put_in_the_first_ones_frame() -> None:
    """The second sweep of a cycle, taken a little later from where the robot had moved on: its
    points (and its laser's place, where the beams start) go into the first sweep's frame
    through the two poses, and land in the world where they were seen."""
    from mapkit.build.builder import _cycles
    from mapkit.model.scan import LaserConfig

    rng = np.random.default_rng(4)
    lasers = (
        LaserConfig(number=1, pose=Pose2D(160.0, 0.0, 0.0)),
        LaserConfig(number=2, pose=Pose2D(-200.0, 30.0, 180.0)),
    )
    poses = [Pose2D(1000.0, 500.0, 30.0), Pose2D(1040.0, 520.0, 31.5)]
    sweeps = [
        LaserScan(
            scan_id=k, laser=k + 1, robot=poses[k], time=12.5, xy=rng.uniform(500, 3000, (40, 2))
        )
        for k in range(2)
    ]
    sweeps.append(  # the next cycle: a scan of its own
        LaserScan(scan_id=2, laser=1, robot=poses[1], time=12.6, xy=rng.uniform(500, 3000, (40, 2)))
    )
    log = LaserLog(header=LogHeader(lasers=lasers), records=tuple(sweeps))
    scans, odo, pts, origins, merged = _cycles(log, "robot", 16000.0)
    assert [s.scan_id for s in scans] == [0, 2] and merged == 1
    assert len(pts[0]) == 80 and origins[0].shape == (80, 2)
    world = transform(pts[0], odo[0])
    for k, s in enumerate(sweeps[:2]):
        at = np.array([poses[k].x, poses[k].y, math.radians(poses[k].th)])
        seen = transform(s.robot_points(lasers[k]), at)
        np.testing.assert_allclose(world[40 * k : 40 * (k + 1)], seen, atol=1e-6)
        mount = transform(np.array([lasers[k].pose[:2]]), at)
        np.testing.assert_allclose(transform(origins[0][40 * k : 40 * k + 1], odo[0]), mount)
