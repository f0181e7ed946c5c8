"""The log simulator: ray casting, routes, odometry drift, truth sidecar."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mapkit.errors import MapkitError
from mapkit.formats.laser2d import read_log
from mapkit.model import MapData, MapObject, Scan
from mapkit.simulate import ray_cast, read_truth, simulate_log, truth_path_for

ROOM = [[0, 0, 8000, 0], [8000, 0, 8000, 5000], [8000, 5000, 0, 5000], [0, 5000, 0, 0]]


def room_map(**objects) -> MapData:
    return MapData(
        scans=(Scan.from_arrays(lines=ROOM),),
        objects=(
            MapObject("RobotHome", 2000, 2500, 0, name="Home"),
            MapObject("Goal", 6000, 2500, 0, name="A"),
            MapObject("GoalWithHeading", 6000, 1000, 90, name="B"),
        ),
    )


def test_ray_cast_matches_geometry() -> None:
    angles = np.linspace(-90, 90, 181)
    r = ray_cast(
        (2000, 2500, 0), angles, np.array(ROOM, dtype=float), np.zeros((0, 2)), max_range=20000
    )
    a = np.radians(angles)
    # Distance to the box from inside, analytically: the nearest of the walls in each direction.
    with np.errstate(divide="ignore"):
        tx = np.where(np.cos(a) > 1e-12, 6000 / np.cos(a), np.inf)
        ty = np.where(
            np.sin(a) > 1e-12,
            2500 / np.sin(a),
            np.where(np.sin(a) < -1e-12, -2500 / np.sin(a), np.inf),
        )
    assert np.allclose(r, np.minimum(tx, ty), rtol=1e-9)


def test_ray_cast_range_points_and_full_circle() -> None:
    far = ray_cast(
        (0, 0, 0),
        np.array([0.0]),
        np.array([[5000.0, -10, 5000, 10]]),
        np.zeros((0, 2)),
        max_range=4000,
    )
    assert np.isinf(far).all()
    angles = np.linspace(-180, 180, 361)
    pts = np.array([[1000.0, 0.0], [-2000.0, 0.0]])
    r = ray_cast((0, 0, 0), angles, np.zeros((0, 4)), pts, max_range=5000, point_size=20)
    assert r[180] == pytest.approx(1000.0)
    assert r[0] == pytest.approx(2000.0) and r[360] == pytest.approx(2000.0)
    assert np.isinf(r[90])


def test_simulation_is_deterministic_and_drifts(tmp_path) -> None:
    m = room_map()
    a = simulate_log(m, seed=4, loop=True)
    b = simulate_log(m, seed=4, loop=True)
    assert np.array_equal(a.truth, b.truth)
    assert a.log == b.log
    odo = a.log.poses()
    err = np.hypot(*(odo[:, :2] - a.truth[:, :2]).T)
    assert err[0] < 1.0 and err.max() > 5.0  # starts at the truth, then drifts
    kinds = [(e.kind, e.name) for e in a.log.events]
    assert kinds == [("loop", "1"), ("goal", "A"), ("goal", "B"), ("loop", "1")]
    assert np.allclose(a.truth[-1, :2], a.truth[0, :2], atol=1.0)  # back at the start


def test_perfect_odometry_and_laser(tmp_path) -> None:
    m = room_map()
    sim = simulate_log(m, seed=1, translation_error=0, rotation_error=0, drift=0, range_noise=0)
    assert np.allclose(sim.log.poses()[:, :2], sim.truth[:, :2], atol=0.6)
    laser = sim.log.header.laser(1)
    for scan, true in zip(sim.log.scans, sim.truth, strict=True):
        p = scan.global_points(laser, pose=true)
        d = np.min(
            np.stack(
                [np.abs(p[:, 0]), np.abs(p[:, 0] - 8000), np.abs(p[:, 1]), np.abs(p[:, 1] - 5000)]
            ),
            axis=0,
        )
        assert d.max() < 2.0  # every hit on a wall (integer rounding only)


def test_save_writes_log_and_truth(tmp_path) -> None:
    sim = simulate_log(room_map(), seed=2, version=3, readings=91, fov=270, raw_ranges=True)
    path = tmp_path / "room.2d"
    msg = sim.save(path)
    assert "room.truth.tsv" in msg and truth_path_for(path).endswith("room.truth.tsv")
    log = read_log(path)
    assert log.header.version == 3 and log.header.laser(1).count == 91
    ids, poses = read_truth(truth_path_for(path))
    assert ids.tolist() == [s.scan_id for s in log.scans]
    assert np.allclose(poses, sim.truth, atol=0.06)
    s = log.scans[3]
    assert s.ranges is not None and len(s.ranges) == 91


def test_unreachable_goal_is_skipped_and_errors() -> None:
    m = room_map()
    walled = m.replace(objects=(*m.objects, MapObject("Goal", 20000, 20000, 0, name="Out")))
    sim = simulate_log(walled, seed=1)
    assert "Out" in sim.skipped and [e.name for e in sim.log.events] == ["A", "B"]
    with pytest.raises(MapkitError, match="neither points nor lines"):
        simulate_log(MapData(objects=m.objects))
    with pytest.raises(MapkitError, match="nothing to drive to"):
        simulate_log(MapData(scans=(Scan.from_arrays(lines=ROOM),)))
    with pytest.raises(ValueError, match="at least 2 readings"):
        simulate_log(m, readings=1)


def test_read_truth_rejects_bad_lines(tmp_path) -> None:
    p = tmp_path / "t.truth.tsv"
    p.write_text("# header\n0 0.0 1 2 3\n1 oops\n")
    with pytest.raises(MapkitError, match=r"t\.truth\.tsv:3: expected 'scanId time x y th'"):
        read_truth(p)


def test_waypoints_and_zero_origin() -> None:
    sim = simulate_log(
        room_map(),
        waypoints=[(3000, 1000), (7000, 4000)],
        seed=3,
        odometry_origin="zero",
        goal_names="aria",
    )
    assert sim.log.scans[0].robot == (0.0, 0.0, 0.0)
    assert [e.name for e in sim.log.events] == ["goal1", "goal2"]
    assert math.hypot(*(sim.truth[0, :2] - [2000, 2500])) < 1.0  # starts at RobotHome


@pytest.mark.parametrize("lag", [0.05, -0.05])
def test_a_lagging_sweep_is_seen_from_where_the_robot_was(lag: float) -> None:
    """With ``scan_lag`` the sweep is taken ``lag`` seconds before the pose and velocities
    logged with it (after, when negative), and the truth is where it was taken from: while the
    robot turns on the spot, the logged heading is the true one plus the turn rate times the
    lag; the hits lie on the walls seen from the truth."""
    m = room_map()
    sim = simulate_log(
        m, seed=1, translation_error=0, rotation_error=0, drift=0, range_noise=0, scan_lag=lag
    )
    laser = sim.log.header.laser(1)
    logged = sim.log.poses()
    spins = 0
    for scan, pose, true in zip(sim.log.scans, logged, sim.truth, strict=True):
        assert scan.velocities is not None
        vel, rate = scan.velocities[:2]
        p = scan.global_points(laser, pose=true)
        d = np.min(
            np.stack(
                [np.abs(p[:, 0]), np.abs(p[:, 0] - 8000), np.abs(p[:, 1]), np.abs(p[:, 1] - 5000)]
            ),
            axis=0,
        )
        assert d.max() < 2.0
        if vel == 0 and rate != 0:  # turning on the spot, at the same rate a lag before
            spins += 1
            ahead = (pose[2] - true[2] + 180.0) % 360.0 - 180.0
            assert ahead == pytest.approx(rate * lag, abs=0.02)
    assert spins >= 3
    if lag > 0:  # the same robot logs the same poses; only its sweeps are older
        plain = simulate_log(m, seed=1, translation_error=0, rotation_error=0, drift=0)
        assert np.allclose(plain.log.poses(), logged, atol=1e-9)
    with pytest.raises(ValueError, match="scan_lag"):
        simulate_log(m, scan_lag=2.0)


def test_a_sweeps_lag_varies_by_the_jitter() -> None:
    """With ``scan_lag_jitter`` each sweep's lag is drawn within that much of ``scan_lag``:
    while turning on the spot, the logged heading runs ahead of the truth by the turn rate times
    a lag of its own, within the range and not the same for every sweep."""
    m = room_map()
    sim = simulate_log(
        m,
        seed=2,
        translation_error=0,
        rotation_error=0,
        drift=0,
        range_noise=0,
        scan_lag=0.05,
        scan_lag_jitter=0.04,
    )
    lags = []
    for scan, pose, true in zip(sim.log.scans, sim.log.poses(), sim.truth, strict=True):
        assert scan.velocities is not None
        vel, rate = scan.velocities[:2]
        if vel == 0 and rate != 0:
            lags.append(((pose[2] - true[2] + 180.0) % 360.0 - 180.0) / rate)
    assert len(lags) >= 3
    assert min(lags) >= 0.01 - 1e-3 and max(lags) <= 0.09 + 1e-3, lags
    assert max(lags) - min(lags) > 0.005, lags
    with pytest.raises(ValueError, match="scan_lag_jitter"):
        simulate_log(m, scan_lag_jitter=-0.01)


def test_a_second_laser_sweeps_in_the_same_cycle() -> None:
    """With ``second_laser`` each cycle logs a sweep of each laser under the same pose, time and
    velocities (one ``scanId`` counter for both), the second laser's from its own mount: a rear
    laser's hits lie on the walls behind the robot, seen from the truth. The poses are the
    one-laser log's (its ranges are not: the two lasers' noise draws interleave)."""
    m = room_map()
    sim = simulate_log(
        m, seed=3, translation_error=0, rotation_error=0, drift=0, second_laser=(-200, 0, 180)
    )
    scans = sim.log.scans
    assert [s.laser for s in scans[:4]] == [1, 2, 1, 2]
    assert [s.scan_id for s in scans[:4]] == [0, 1, 2, 3]
    assert len(sim.truth) == len(scans)
    behind = 0
    for front, rear, t_front, t_rear in zip(
        scans[::2], scans[1::2], sim.truth[::2], sim.truth[1::2], strict=True
    ):
        assert (front.robot, front.time, front.velocities) == (
            rear.robot,
            rear.time,
            rear.velocities,
        )
        assert np.array_equal(t_front, t_rear)
        p = rear.global_points(sim.log.header.laser(2), pose=t_rear)
        d = np.min(
            np.stack(
                [np.abs(p[:, 0]), np.abs(p[:, 0] - 8000), np.abs(p[:, 1]), np.abs(p[:, 1] - 5000)]
            ),
            axis=0,
        )
        assert np.median(d) < 30.0  # 10 mm of range noise
        # Behind the robot: the rear laser's hits are on the far side of its centre.
        th = math.radians(t_rear[2])
        ahead = (p[:, 0] - t_rear[0]) * math.cos(th) + (p[:, 1] - t_rear[1]) * math.sin(th)
        behind += int(np.all(ahead < 0.0))
    assert behind == len(scans) // 2
    one = simulate_log(m, seed=3, translation_error=0, rotation_error=0, drift=0)
    assert np.allclose(one.log.poses(), sim.log.poses()[::2])
    with pytest.raises(MapkitError, match="version 4"):
        simulate_log(m, version=3, second_laser=(-200, 0, 180))
