""":func:`simulate_log`: drive a robot through a known map, record what its laser sees, add range
noise and odometry drift."""

from __future__ import annotations

import dataclasses
import itertools
import math
from collections.abc import Sequence

import numpy as np

from mapkit.errors import MapkitError
from mapkit.formats.laser2d import goal_event, loop_event
from mapkit.model import MapData
from mapkit.model.scan import (
    LaserConfig,
    LaserLog,
    LaserScan,
    LogEvent,
    LogHeader,
    LogRecord,
    Pose2D,
    compose,
    relative,
)
from mapkit.simulate.rays import NO_RETURN, FloatArray, ray_cast, segment_samples
from mapkit.simulate.route import _drive, _Grid, _grid, _plan, _visible
from mapkit.simulate.truth import SimulatedLog

__all__ = ["simulate_log"]


def _points_off_lines(points: FloatArray, segments: FloatArray, tol: float) -> FloatArray:
    """The points that are not copies of a line (farther than ``tol`` from every line).

    Scanned maps hold each wall twice, as points and as a fitted line; the laser should see one
    wall, not a line with a rough skin of points in front of it. Points elsewhere (furniture,
    walls without a line) stay.
    """
    from scipy.spatial import cKDTree

    if len(points) == 0 or len(segments) == 0:
        return points
    samples, _ = segment_samples(segments, tol / 2)
    d, _ = cKDTree(samples).query(points, k=1, distance_upper_bound=tol * 1.2)
    kept: FloatArray = points[~(d <= tol * 1.1)]
    return kept


#: Width of one of the plates a person's body is drawn with (mm).
_BODY_PLATE = 80.0


class _Crowd:
    """People walking back and forth between two free places each (at 0.8 to 1.4 m/s).

    Each body is a ring of plates 400 mm across; they walk through walls' free space only as
    straight lines between places in view of each other, so a person never stands in a wall.
    """

    def __init__(self, grid: _Grid, n: int, radius: float, rng: np.random.Generator) -> None:
        free = np.argwhere(grid.clearance > max(radius, 400.0))
        if len(free) == 0:
            raise MapkitError("the map leaves no room for people to walk")
        self.ends: list[tuple[FloatArray, FloatArray, float, float]] = []
        for _ in range(n):
            for _attempt in range(100):
                a = np.array(grid.center(*free[rng.integers(len(free))]))
                b = np.array(grid.center(*free[rng.integers(len(free))]))
                if 1500.0 < math.hypot(*(b - a)) < 12000.0 and _visible(grid, a, b, 400.0):
                    self.ends.append(
                        (a, b, float(rng.uniform(800.0, 1400.0)), float(rng.uniform(0, 100)))
                    )
                    break
        ang = np.linspace(0, 2 * math.pi, 16, endpoint=False)
        self.ring = 200.0 * np.stack([np.cos(ang), np.sin(ang)], axis=1)

    def bodies(self, t: float) -> FloatArray:
        """Points of every body at time ``t`` (s)."""
        out = [np.zeros((0, 2))]
        for a, b, v, phase in self.ends:
            length = math.hypot(*(b - a))
            s = ((t + phase) * v) % (2 * length)
            f = (s if s < length else 2 * length - s) / length
            out.append(a + f * (b - a) + self.ring)
        return np.concatenate(out)


def _back(
    recent: list[tuple[float, FloatArray, FloatArray, tuple[float, float]]], at: float, which: int
) -> FloatArray:
    """The true pose (``which`` 1) or the odometry (2) at time ``at``, interpolated between the
    recent steps (the first one's before them)."""
    for (t0, *a), (t1, *b) in itertools.pairwise(recent):
        if t0 <= at <= t1:
            p, q = np.asarray(a[which - 1]), np.asarray(b[which - 1])
            f = (at - t0) / (t1 - t0) if t1 > t0 else 1.0
            turn = (q[2] - p[2] + 180.0) % 360.0 - 180.0
            return np.array([p[0] + f * (q[0] - p[0]), p[1] + f * (q[1] - p[1]), p[2] + f * turn])
    return np.asarray(
        recent[0][which] if at < recent[0][0] else recent[-1][which], dtype=np.float64
    )


def _map_home(m: MapData) -> tuple[float, float, float] | None:
    for kind in ("RobotHome", "Dock"):
        for o in m.objects:
            if o.type == kind and o.is_point:
                return (o.x, o.y, o.theta)
    return None


def simulate_log(
    m: MapData,
    *,
    waypoints: Sequence[Sequence[float]] | None = None,
    start: Sequence[float] | None = None,
    loop: bool = False,
    laps: int = 1,
    version: int = 4,
    fov: float = 180.0,
    readings: int = 361,
    max_range: float = 16000.0,
    range_noise: float = 10.0,
    laser_pose: Sequence[float] = (160.0, 0.0, 0.0),
    translation_error: float = 0.01,
    rotation_error: float = 0.02,
    drift: float = 0.05,
    dist_step: float = 300.0,
    deg_step: float = 25.0,
    speed: float = 500.0,
    turn_rate: float = 40.0,
    robot_radius: float = 300.0,
    raw_ranges: bool = False,
    odometry_origin: str = "start",
    goal_names: str = "map",
    scale_error: float = 0.0,
    turn_slip: float = 0.0,
    outliers: float = 0.0,
    people: int = 0,
    scan_lag: float = 0.0,
    scan_lag_jitter: float = 0.0,
    second_laser: Sequence[float] | None = None,
    seed: int = 0,
) -> SimulatedLog:
    """Drive a simulated robot through ``m`` and record a ``.2d`` log with drifting odometry.

    Args:
        m: The map whose lines and points the laser sees.
        waypoints: ``(x, y)`` points to visit in order; default: the map's goals in file order.
        start: Start pose ``(x, y, th)``; default: the map's ``RobotHome`` (else ``Dock``, else the
            first goal or waypoint).
        loop: Come back to the start at the end and mark the loop with ``loop: start 1`` /
            ``loop: stop 1`` events (as the robot's loop button does).
        laps: Drive the route this many times (each lap returns to the start when ``loop``).
        version: Logger version of the header (1 to 4); :meth:`SimulatedLog.save` may override.
        fov: Laser field of view (degrees), centred on the laser's forward axis.
        readings: Beams per sweep.
        max_range: Longest range the laser reports (mm); farther beams read "no return".
        range_noise: Standard deviation of the range noise (mm).
        laser_pose: Laser mount on the robot ``(x, y, th)``.
        translation_error: Odometry distance error, standard deviation as a fraction of the
            distance driven in a step (random walk).
        rotation_error: Odometry turn error, as a fraction of the turn.
        drift: Systematic heading drift in degrees per metre driven (what makes maps bend).
        dist_step: Log a scan after this many mm (ARIA: 300) ...
        deg_step: ... or this many degrees of turning (ARIA: 25).
        speed: Driving speed (mm/s).
        turn_rate: Turning speed (degrees/s).
        robot_radius: Clearance kept from walls by the route planner (mm).
        raw_ranges: Also log raw ranges (``sick1:``), as ARIA's "old readings" option does.
        odometry_origin: ``"start"``: odometry starts at the true start pose, so a map built from
            the log overlays ``m``; ``"zero"``: odometry starts at 0 0 0, as on a real robot.
        goal_names: ``"map"``: goal events carry the map's goal names; ``"aria"``: ``goal1``,
            ``goal2``... as ARIA's logger names them.
        scale_error: Systematic odometry distance error: every distance reads this fraction
            too long (a wrong wheel diameter; 0.01 = 1 %).
        turn_slip: Wheel slip while turning on the spot: the odometry reports this fraction more
            turn than the robot made (systematic), plus a random part of half that size per turn.
        outliers: Fraction of readings that are spurious: a random range short of the true one
            (dust, reflections, a leg in the beam).
        people: Moving people: each walks back and forth between two free places of the map at
            walking pace and blocks the laser as a 400 mm wide body.
        scan_lag: How much older (s) each sweep is than the pose and velocities logged with it:
            ARIA stamps a simulated laser's sweep with the robot's pose when its packet arrives,
            and a real laser's with a latency it is told. Negative: the sweep is newer. The
            truth is the pose the sweep was taken from.
        scan_lag_jitter: Each sweep's lag is ``scan_lag`` plus a uniform draw within this many
            seconds either way (packets that arrive early or late in the robot's cycle).
        second_laser: The mount pose ``(x mm, y mm, theta degrees)`` of a second laser of the
            same kind (a rear laser: ``(-200, 0, 180)``), logged as ARIA's logger logs one: in
            each cycle a sweep of each laser under one ``logTime:``, one ``scanId`` counter for
            both (the truth has a pose per sweep). None: one laser.
        seed: Random seed (the same seed gives the same log).

    Returns:
        The simulated log and the true poses.

    Raises:
        MapkitError: When the map gives nothing to drive to or no path exists.
        ValueError: For parameters out of range.
    """
    if readings < 2 or not 0 < fov <= 360:
        raise ValueError("need at least 2 readings and a field of view in (0, 360] degrees")
    if dist_step <= 0 or deg_step <= 0 or speed <= 0 or turn_rate <= 0 or laps < 1:
        raise ValueError("steps, speeds and laps must be positive")
    if odometry_origin not in ("start", "zero"):
        raise ValueError("odometry_origin is 'start' or 'zero'")
    if not (abs(scan_lag) <= 1.0 and 0.0 <= scan_lag_jitter <= 1.0):
        raise ValueError(
            "scan_lag is a time in seconds, at most 1 either way; scan_lag_jitter in [0, 1] s"
        )
    if not 0 <= outliers < 1 or people < 0 or abs(scale_error) >= 0.5 or abs(turn_slip) >= 0.5:
        raise ValueError(
            "outliers is a fraction in [0, 1); people >= 0; scale_error and "
            "turn_slip are fractions under 0.5"
        )
    if second_laser is not None and (version < 4 or len(second_laser) != 3):
        raise MapkitError(
            "second_laser is a mount pose (x, y, theta) and is logged by version 4 logs only"
        )
    rng = np.random.default_rng(seed)
    home: tuple[float, float, float] | None = None
    if start is not None:
        home = (float(start[0]), float(start[1]), float(start[2]) if len(start) > 2 else 0.0)
    else:
        home = _map_home(m)
    if waypoints is not None:
        goals = [(float(w[0]), float(w[1]), f"goal{i + 1}") for i, w in enumerate(waypoints)]
    else:
        goals = [(o.x, o.y, o.name) for o in m.objects if o.is_point and o.base_type == "Goal"]
    if home is None:
        if not goals:
            raise MapkitError("nothing to drive to: give waypoints, or a map with goals or a home")
        first = goals.pop(0)
        th0 = (
            0.0
            if not goals
            else math.degrees(math.atan2(goals[0][1] - first[1], goals[0][0] - first[0]))
        )
        home = (first[0], first[1], th0)
    if goal_names == "aria":
        goals = [(x, y, f"goal{i + 1}") for i, (x, y, _) in enumerate(goals)]
    stops = [(home[0], home[1], None)] + [(x, y, nm) for x, y, nm in goals]
    legs: list[tuple[float, float, str | None]] = []
    for _ in range(laps):
        legs.extend(stops[1:])
        if loop:
            legs.append((home[0], home[1], "__home__"))
    if not legs:
        raise MapkitError("the route is empty: give waypoints or a map with goals")

    grid = _grid(m, 100.0)
    segments = m.lines.astype(np.float64)
    point_size = float(max(m.scan.resolution, 20))
    points = _points_off_lines(m.points.astype(np.float64), segments, 1.5 * point_size)
    half = fov / 2.0
    laser = LaserConfig(
        number=1,
        pose=Pose2D(*laser_pose),
        start=-half,
        end=half,
        count=readings,
        name="sim_laser_1",
        z=0.0,
    )
    angles = laser.angles()
    lasers: tuple[LaserConfig, ...] = (laser,)
    if second_laser is not None:
        lasers += (
            dataclasses.replace(
                laser, number=2, pose=Pose2D(*map(float, second_laser)), name="sim_laser_2"
            ),
        )
    header = LogHeader(
        version=version,
        lasers=lasers,
        location_types=("robot", "robotGlobal"),
        comments=("Created by mapkit simulate",),
    )
    dt = 0.1
    crowd = _Crowd(grid, people, robot_radius, rng) if people > 0 else None
    records: list[LogRecord] = []
    truth: list[FloatArray] = []
    truth_ids: list[int] = []
    truth_times: list[float] = []
    true = np.array(home, dtype=np.float64)
    odo = true.copy() if odometry_origin == "start" else np.zeros(3)
    last_logged: FloatArray | None = None
    t = 0.0
    scan_id = 0
    distance = 0.0
    goal_no = 0
    where = (home[0], home[1])
    heading = home[2]

    # (time, true pose, odometry, velocities) of the last steps: what a lagging sweep saw.
    recent: list[tuple[float, FloatArray, FloatArray, tuple[float, float]]] = []

    def sweep(las: LaserConfig, seen: FloatArray) -> tuple[FloatArray, FloatArray | None]:
        """What laser ``las`` reads from the true pose ``seen``: its points and, with
        ``raw_ranges``, its ranges."""
        lp = compose(seen, las.pose)
        r = ray_cast(lp, angles, segments, points, max_range=max_range, point_size=point_size)
        if crowd is not None:
            body = crowd.bodies(t)
            r = np.minimum(
                r,
                ray_cast(
                    lp, angles, np.zeros((0, 4)), body, max_range=max_range, point_size=_BODY_PLATE
                ),
            )
        hit = np.isfinite(r)
        rn = np.where(hit, r + rng.normal(0.0, range_noise, len(r)) if range_noise > 0 else r, 0.0)
        if outliers > 0:
            bad = hit & (rng.random(len(r)) < outliers)
            rn = np.where(bad, rn * rng.uniform(0.05, 0.95, len(r)), rn)
        rn = np.where(hit & (rn < 1.0), 1.0, rn)
        a = np.radians(angles)
        xy = np.stack([rn * np.cos(a), rn * np.sin(a)], axis=1)
        xy[~hit] = 0.0
        return np.rint(xy), np.where(hit, np.rint(rn), NO_RETURN) if raw_ranges else None

    def log_scan() -> None:
        nonlocal scan_id, last_logged
        seen, logged = true, odo
        vel = (speed if moving else 0.0, turn_now)
        lag = scan_lag + (
            rng.uniform(-scan_lag_jitter, scan_lag_jitter) if scan_lag_jitter else 0.0
        )
        if lag > 0:
            seen = _back(recent, t - lag, 1)
        elif lag < 0:
            logged = _back(recent, t + lag, 2)
            vel = next((v for tv, _, _, v in recent if tv >= t + lag), vel)
        pose = Pose2D(round(float(logged[0])), round(float(logged[1])), round(float(logged[2]), 2))
        for las in lasers:
            xy, ranges = sweep(las, seen)
            records.append(
                LaserScan(
                    scan_id=scan_id,
                    laser=las.number,
                    robot=pose,
                    robot_global=pose,
                    time=round(t, 3),
                    velocities=(round(vel[0], 2), round(vel[1], 2), 0.0),
                    xy=xy,
                    ranges=ranges,
                )
            )
            truth.append(np.array(seen, dtype=np.float64))
            truth_ids.append(scan_id)
            truth_times.append(round(t, 3))
            scan_id += 1
        last_logged = odo.copy()

    def event(ev: LogEvent) -> None:
        records.append(ev)

    def odo_pose() -> Pose2D:
        return Pose2D(round(float(odo[0])), round(float(odo[1])), round(float(odo[2]), 2))

    moving = False
    turn_now = 0.0
    recent.append((t, true.copy(), odo.copy(), (0.0, 0.0)))
    log_scan()
    if loop:
        event(loop_event("start", "1", odo_pose(), time=round(t, 3), robot_global=odo_pose()))
    loop_no = 1
    skipped: list[str] = []
    for gx, gy, name in legs:
        try:
            path = _plan(grid, where, (gx, gy), robot_radius)
        except MapkitError:
            if name == "__home__":
                raise
            skipped.append(name or f"({gx:.0f}, {gy:.0f})")
            continue
        prev = true.copy()
        slip = turn_slip * (1.0 + 0.5 * rng.normal()) if turn_slip > 0 else 0.0
        for x, y, th in _drive(path, heading, speed, turn_rate, dt):
            nxt = np.array([x, y, th])
            step = relative(prev, nxt)
            d = math.hypot(step[0], step[1])
            if d < 1e-9 and abs(step[2]) < 1e-9:
                continue
            moving, turn_now = d > 1e-9, float(step[2]) / dt
            # Odometry: noisy, drifting copy of the true step.
            ds = step[:2] * (1.0 + rng.normal(0.0, translation_error)) * (1.0 + scale_error)
            dth = step[2] * (1.0 + rng.normal(0.0, rotation_error)) + drift * d / 1000.0
            if d < 1.0:  # turning on the spot
                dth += step[2] * slip
            odo = compose(odo, np.array([ds[0], ds[1], dth]))
            true = nxt
            prev = nxt
            distance += d
            t += dt
            if scan_lag or scan_lag_jitter:
                recent.append((t, true.copy(), odo.copy(), (speed if moving else 0.0, turn_now)))
                while len(recent) > 2 and recent[1][0] < t - abs(scan_lag) - scan_lag_jitter - dt:
                    recent.pop(0)
            assert last_logged is not None
            moved = relative(last_logged, odo)
            if math.hypot(moved[0], moved[1]) > dist_step or abs(moved[2]) > deg_step:
                log_scan()
        where = (gx, gy)
        heading = float(true[2])
        moving, turn_now = False, 0.0
        if name == "__home__":
            if np.any(np.abs(relative(last_logged, odo)) > 1e-6):
                log_scan()
            event(
                loop_event(
                    "stop", str(loop_no), odo_pose(), time=round(t, 3), robot_global=odo_pose()
                )
            )
            if laps > 1 and loop_no < laps:
                loop_no += 1
                event(
                    loop_event(
                        "start", str(loop_no), odo_pose(), time=round(t, 3), robot_global=odo_pose()
                    )
                )
        elif name is not None:
            goal_no += 1
            t += 0.5
            if scan_lag or scan_lag_jitter:
                recent.append((t, true.copy(), odo.copy(), (0.0, 0.0)))
            event(
                goal_event(
                    name or f"goal{goal_no}", odo_pose(), time=round(t, 3), robot_global=odo_pose()
                )
            )
    tr = np.array(truth)
    odo_world = odo if odometry_origin == "start" else compose(np.array(home), odo)
    odo_err = relative(true, odo_world)
    log = LaserLog(header=header, records=tuple(records), complete=True, source="<simulated>")
    return SimulatedLog(
        log=log,
        truth=tr,
        truth_ids=np.array(truth_ids),
        truth_times=np.array(truth_times),
        distance=distance,
        skipped=tuple(skipped),
        odometry_error=(float(math.hypot(odo_err[0], odo_err[1])), float(abs(odo_err[2]))),
        params={
            "seed": seed,
            "fov": fov,
            "readings": readings,
            "max_range": max_range,
            "range_noise": range_noise,
            "translation_error": translation_error,
            "rotation_error": rotation_error,
            "drift": drift,
            "scale_error": scale_error,
            "turn_slip": turn_slip,
            "outliers": outliers,
            "people": people,
            "scan_lag": scan_lag,
            "scan_lag_jitter": scan_lag_jitter,
        },
    )
