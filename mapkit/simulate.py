"""Simulate a laser log: drive a robot through a known map and record what a laser would see.

:func:`simulate_log` plans a route through the map (from its goals, or through given waypoints),
drives it, ray-casts a laser against the map's lines and points (vectorised with numpy: each
line or point is turned into the range of beams it covers, then each beam keeps its nearest hit;
a point lying on a line is the same wall scanned, and is left out so walls stay flat),
adds range noise, and integrates odometry with drift. The result holds the log's records (in the
:mod:`mapkit.model.scan` convention) and the **true** pose of every scan.

Where the truth goes: ARIA's ``robotGlobal:`` is the pose corrected by localisation, and when
nothing corrects it the logger writes the odometry pose there too (FORMATS.md B.5a). The
simulator does the same (``robot:`` = ``robotGlobal:`` = odometry), so the log looks like one
recorded by a robot that is being mapped, and writes the true poses to a **sidecar file** beside
the log, ``NAME.truth.tsv`` (one line per scan: ``scanId time x y th``), read back by
:func:`read_truth`. Nothing in the ``.2d`` then tells a map builder the answer.

Examples:
    >>> from mapkit.model import MapData, Scan, MapObject
    >>> room = Scan.from_arrays(lines=[[0, 0, 6000, 0], [6000, 0, 6000, 4000],
    ...                                [6000, 4000, 0, 4000], [0, 4000, 0, 0]])
    >>> m = MapData(scans=(room,), objects=(MapObject("RobotHome", 1000, 1000, 0),))
    >>> sim = simulate_log(m, waypoints=[(5000, 1000), (5000, 3000)], seed=1, range_noise=0)
    >>> scan = sim.log.scans[0]
    >>> round(float(scan.xy[180, 0]) + 160 + 1000)    # the beam straight ahead hits x = 6000
    6000
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from mapkit._atomic import atomic_write
from mapkit._text import plural
from mapkit._typing import PathLike
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

__all__ = ["SimulatedLog", "read_truth", "simulate_log", "truth_path_for", "ray_cast"]

FloatArray = np.ndarray[Any, np.dtype[np.float64]]
#: What the laser reports for a beam without a return (raw range), as a SICK LMS does.
NO_RETURN = 32767


# -- ray casting -------------------------------------------------------------------------------


def _beam_pairs(lo: FloatArray, width: FloatArray, start: float, step: float,
                n: int) -> tuple[np.ndarray[Any, Any], np.ndarray[Any, Any]]:
    """(element index, beam index) for every beam whose angle lies in [lo, lo + width]."""
    two_pi = 2.0 * math.pi
    t_lo = np.mod(lo - start, two_pi)
    t_hi = t_lo + width
    first = np.ceil(t_lo / step - 1e-9).astype(np.int64)
    last = np.minimum(np.floor(t_hi / step + 1e-9).astype(np.int64), n - 1)
    # The part of an interval past 2*pi wraps to the first beams.
    wrap_last = np.minimum(np.floor((t_hi - two_pi) / step + 1e-9).astype(np.int64), n - 1)
    elems, beams = [], []
    for a, b in ((first, last), (np.zeros_like(first), wrap_last)):
        counts = np.maximum(b - a + 1, 0)
        total = int(counts.sum())
        if total == 0:
            continue
        idx = np.repeat(np.arange(len(a)), counts)
        offsets = np.cumsum(counts) - counts
        beams.append(a[idx] + (np.arange(total) - offsets[idx]))
        elems.append(idx)
    if not elems:
        empty = np.zeros(0, dtype=np.int64)
        return empty, empty
    return np.concatenate(elems), np.concatenate(beams)


def ray_cast(
    pose: Sequence[float] | FloatArray, angles_deg: FloatArray, segments: FloatArray,
    points: FloatArray, *, max_range: float, point_size: float = 20.0,
) -> FloatArray:
    """Ranges (mm) of beams from ``pose`` to the nearest segment or point; ``inf`` for no hit.

    Args:
        pose: Laser pose in the world (x, y, theta degrees).
        angles_deg: Beam angles relative to the laser, increasing (degrees).
        segments: ``(M, 4)`` world segments ``x1 y1 x2 y2``.
        points: ``(K, 2)`` world points; each blocks beams as a plate ``point_size`` wide facing
            the laser.
        max_range: Elements farther than this are ignored.
        point_size: Width of a point's plate (the map's resolution).

    Returns:
        ``(N,)`` ranges; ``inf`` where a beam hits nothing within ``max_range``.

    Examples:
        >>> ray_cast((0, 0, 0), np.array([-10.0, 0.0, 10.0]), np.array([[1000., -500, 1000, 500]]),
        ...          np.zeros((0, 2)), max_range=5000).round(1).tolist()
        [1015.4, 1000.0, 1015.4]
    """
    n = len(angles_deg)
    ranges = np.full(n, np.inf)
    if n == 0:
        return ranges
    a = np.radians(np.asarray(angles_deg, dtype=np.float64))
    start = float(a[0])
    step = float(a[1] - a[0]) if n > 1 else 1.0
    x0, y0, th = float(pose[0]), float(pose[1]), math.radians(float(pose[2]))
    c, s = math.cos(th), math.sin(th)

    def to_laser(xy: FloatArray) -> FloatArray:
        dx, dy = xy[:, 0] - x0, xy[:, 1] - y0
        return np.stack([c * dx + s * dy, -s * dx + c * dy], axis=1)

    if len(segments):
        seg = np.asarray(segments, dtype=np.float64)
        p1, p2 = seg[:, :2], seg[:, 2:]
        d = p2 - p1
        ll = np.einsum("ij,ij->i", d, d)
        t = np.clip(np.einsum("ij,ij->i", np.array([x0, y0]) - p1, d) / np.where(ll > 0, ll, 1), 0, 1)
        near = p1 + t[:, None] * d
        keep = np.hypot(near[:, 0] - x0, near[:, 1] - y0) < max_range
        if keep.any():
            q1, q2 = to_laser(p1[keep]), to_laser(p2[keep])
            f1 = np.arctan2(q1[:, 1], q1[:, 0])
            f2 = np.arctan2(q2[:, 1], q2[:, 0])
            delta = np.mod(f2 - f1 + math.pi, 2 * math.pi) - math.pi
            lo = np.where(delta >= 0, f1, f2)
            ei, bi = _beam_pairs(lo, np.abs(delta), start, step, n)
            if len(ei):
                u = np.stack([np.cos(a[bi]), np.sin(a[bi])], axis=1)
                dd = q2[ei] - q1[ei]
                den = u[:, 0] * dd[:, 1] - u[:, 1] * dd[:, 0]
                ok = np.abs(den) > 1e-12
                den = np.where(ok, den, 1.0)
                r = (q1[ei, 0] * dd[:, 1] - q1[ei, 1] * dd[:, 0]) / den
                r = np.where(ok & (r > 0), r, np.inf)
                np.minimum.at(ranges, bi, r)
    if len(points):
        pts = np.asarray(points, dtype=np.float64)
        rho_all = np.hypot(pts[:, 0] - x0, pts[:, 1] - y0)
        keep = (rho_all < max_range + point_size) & (rho_all > point_size)
        if keep.any():
            q = to_laser(pts[keep])
            rho = rho_all[keep]
            phi = np.arctan2(q[:, 1], q[:, 0])
            half = np.arctan2(point_size / 2.0, rho)
            ei, bi = _beam_pairs(phi - half, 2 * half, start, step, n)
            if len(ei):
                r = rho[ei] / np.maximum(np.cos(a[bi] - phi[ei]), 1e-6)
                np.minimum.at(ranges, bi, r)
    ranges[ranges > max_range] = np.inf
    return ranges


# -- route planning on a coarse grid ---------------------------------------------------------------


@dataclass
class _Grid:
    origin: tuple[float, float]
    cell: float
    clearance: np.ndarray[Any, Any]  # mm to the nearest obstacle, per cell

    def index(self, xy: Sequence[float]) -> tuple[int, int]:
        i = int(round((xy[1] - self.origin[1]) / self.cell))
        j = int(round((xy[0] - self.origin[0]) / self.cell))
        h, w = self.clearance.shape
        return min(max(i, 0), h - 1), min(max(j, 0), w - 1)

    def center(self, i: int, j: int) -> tuple[float, float]:
        return self.origin[0] + j * self.cell, self.origin[1] + i * self.cell

    def clear_at(self, xy: FloatArray) -> FloatArray:
        i = np.clip(np.rint((xy[:, 1] - self.origin[1]) / self.cell).astype(int), 0,
                    self.clearance.shape[0] - 1)
        j = np.clip(np.rint((xy[:, 0] - self.origin[0]) / self.cell).astype(int), 0,
                    self.clearance.shape[1] - 1)
        return self.clearance[i, j]  # type: ignore[no-any-return]


def _obstacles(m: MapData) -> FloatArray:
    """Points along every wall (lines sampled every 50 mm) and the map's points."""
    parts = [m.points.astype(np.float64)]
    lines = m.lines.astype(np.float64)
    if len(lines):
        length = np.hypot(lines[:, 2] - lines[:, 0], lines[:, 3] - lines[:, 1])
        k = np.maximum(np.ceil(length / 50.0).astype(np.int64), 1) + 1
        idx = np.repeat(np.arange(len(lines)), k)
        t = (np.arange(int(k.sum())) - np.repeat(np.cumsum(k) - k, k)) / np.repeat(k - 1, k)
        parts.append(lines[idx, :2] + t[:, None] * (lines[idx, 2:] - lines[idx, :2]))
    return np.concatenate(parts) if parts else np.zeros((0, 2))


def _grid(m: MapData, cell: float) -> _Grid:
    from scipy import ndimage

    obs = _obstacles(m)
    if len(obs) == 0:
        raise MapkitError("the map has neither points nor lines: there is nothing to simulate a laser against")
    lo = obs.min(axis=0) - 2000.0
    hi = obs.max(axis=0) + 2000.0
    shape = (int((hi[1] - lo[1]) / cell) + 2, int((hi[0] - lo[0]) / cell) + 2)
    occ = np.zeros(shape, dtype=bool)
    i = np.rint((obs[:, 1] - lo[1]) / cell).astype(int)
    j = np.rint((obs[:, 0] - lo[0]) / cell).astype(int)
    occ[i, j] = True
    clearance = ndimage.distance_transform_edt(~occ) * cell
    return _Grid((float(lo[0]), float(lo[1])), cell, clearance)


def _plan(grid: _Grid, a: Sequence[float], b: Sequence[float], radius: float) -> list[tuple[float, float]]:
    """Shortest safe path from a to b (grid Dijkstra, then line-of-sight shortcuts)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import dijkstra

    free = grid.clearance > radius
    h, w = free.shape
    si, sj = _nearest_free(grid, free, a)
    gi, gj = _nearest_free(grid, free, b)
    ids = np.full(free.shape, -1, dtype=np.int64)
    ids[free] = np.arange(int(free.sum()))
    # Cost favours the middle of corridors: 1 at 1 m clearance or more, up to 3 near walls.
    cost = 1.0 + 2.0 * np.clip(1.0 - grid.clearance / 1000.0, 0.0, 1.0)
    rows, cols, vals = [], [], []
    for di, dj in ((0, 1), (1, 0), (1, 1), (1, -1)):
        sl_src = (slice(0, h - di), slice(max(0, -dj), w - max(0, dj)))
        sl_dst = (slice(di, h), slice(max(0, dj), w + min(0, dj)))
        src = free[sl_src]
        dst = free[sl_dst]
        both = src & dst
        rows.append(ids[sl_src][both])
        cols.append(ids[sl_dst][both])
        c = (cost[sl_src][both] + cost[sl_dst][both]) / 2.0
        vals.append(c * math.hypot(di, dj) * grid.cell)
    n = int(free.sum())
    graph = coo_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                       shape=(n, n)).tocsr()
    start, goal = int(ids[si, sj]), int(ids[gi, gj])
    dist, pred = dijkstra(graph, directed=False, indices=start, return_predecessors=True)
    if not np.isfinite(dist[goal]):
        raise MapkitError(f"no path for the robot from ({a[0]:.0f}, {a[1]:.0f}) to "
                          f"({b[0]:.0f}, {b[1]:.0f}) with {radius:.0f} mm clearance")
    chain = [goal]
    while chain[-1] != start:
        chain.append(int(pred[chain[-1]]))
    chain.reverse()
    flat = np.flatnonzero(free.ravel())[chain]
    cells = np.stack([grid.origin[0] + (flat % w) * grid.cell,
                      grid.origin[1] + (flat // w) * grid.cell], axis=1)
    cells[0] = a[:2]
    cells[-1] = b[:2]
    # Greedy line-of-sight shortcuts.
    out = [tuple(cells[0])]
    k = 0
    while k < len(cells) - 1:
        nxt = k + 1
        for j in range(k + 2, len(cells)):
            if _visible(grid, cells[k], cells[j], radius):
                nxt = j
            elif j - nxt > 20:
                break
        out.append(tuple(cells[nxt]))
        k = nxt
    return [(float(x), float(y)) for x, y in out]


def _nearest_free(grid: _Grid, free: np.ndarray[Any, Any], xy: Sequence[float]) -> tuple[int, int]:
    i, j = grid.index(xy)
    if free[i, j]:
        return i, j
    fi, fj = np.nonzero(free)
    if len(fi) == 0:
        raise MapkitError("the map leaves no room for the robot to drive")
    k = int(np.argmin((fi - i) ** 2 + (fj - j) ** 2))
    return int(fi[k]), int(fj[k])


def _visible(grid: _Grid, a: FloatArray, b: FloatArray, radius: float) -> bool:
    n = max(int(math.hypot(b[0] - a[0], b[1] - a[1]) / (grid.cell / 2)), 2)
    t = np.linspace(0.0, 1.0, n)[:, None]
    pts = a[None, :] * (1 - t) + b[None, :] * t
    return bool(np.all(grid.clear_at(pts) > radius))


def _drive(path: list[tuple[float, float]], start_th: float, speed: float, turn_rate: float,
           dt: float) -> Iterator[tuple[float, float, float]]:
    """True poses every ``dt``: turn in place towards each leg, then drive it."""
    x, y = path[0]
    th = start_th
    yield x, y, th
    for nx, ny in path[1:]:
        length = math.hypot(nx - x, ny - y)
        if length < 1.0:
            continue
        target = math.degrees(math.atan2(ny - y, nx - x))
        turn = (target - th + 180.0) % 360.0 - 180.0
        steps = int(abs(turn) / (turn_rate * dt))
        for _ in range(steps):
            th += math.copysign(turn_rate * dt, turn)
            yield x, y, th
        th = target
        steps = max(int(length / (speed * dt)), 1)
        x0, y0 = x, y
        for k in range(1, steps + 1):
            x = x0 + (nx - x0) * k / steps
            y = y0 + (ny - y0) * k / steps
            yield x, y, th


# -- the simulation ------------------------------------------------------------------------------


@dataclass(frozen=True)
class SimulatedLog:
    """A simulated log and what really happened.

    Attributes:
        log: The log (records in file order; header version as asked).
        truth: ``(N, 3)`` true robot pose of each scan (mm, mm, degrees), in scan order.
        truth_ids: ``(N,)`` the scans' ``scanId``.
        truth_times: ``(N,)`` the scans' times (s).
        distance: Distance driven (mm).
        odometry_error: Final odometry position error (mm) and heading error (degrees).
        skipped: Goals or waypoints the planner found no path to (left out of the route).
    """

    log: LaserLog
    truth: FloatArray
    truth_ids: np.ndarray[Any, Any]
    truth_times: FloatArray
    distance: float = 0.0
    odometry_error: tuple[float, float] = (0.0, 0.0)
    skipped: tuple[str, ...] = ()
    params: dict[str, Any] = field(default_factory=dict)

    def truth_text(self, log_name: str = "the log") -> str:
        """The truth sidecar's text: a comment, then ``scanId time x y th`` per scan."""
        lines = [f"# true robot poses of {log_name} (mapkit simulate): scanId time x y th "
                 "(mm, degrees)"]
        lines += [f"{int(i)} {t:.3f} {p[0]:.1f} {p[1]:.1f} {p[2]:.3f}"
                  for i, t, p in zip(self.truth_ids, self.truth_times, self.truth)]
        return "\n".join(lines) + "\n"

    def save(self, path: PathLike, *, version: int | None = None, truth: bool | PathLike = True) -> str:
        """Write the log (atomically) and, unless ``truth`` is false, the truth sidecar.

        Args:
            path: The ``.2d`` file.
            version: Logger version (default: the log's header version).
            truth: ``True`` for ``NAME.truth.tsv`` beside the log, a path, or ``False``.

        Returns:
            A one-line summary.

        Raises:
            OSError: When a file cannot be written.
        """
        from mapkit.formats.laser2d import write_log

        write_log(self.log, path, version=version)
        msg = (f"wrote {os.fspath(path)}: {plural(len(self.truth), 'scan')}, "
               f"{plural(len(self.log.events), 'event')}, "
               f"{self.distance / 1000:.1f} m driven, odometry off by {self.odometry_error[0]:.0f} mm "
               f"/ {self.odometry_error[1]:.1f} deg at the end")
        if truth:
            tpath = truth_path_for(path) if truth is True else truth
            atomic_write(tpath, self.truth_text(os.path.basename(os.fspath(path))).encode())
            msg += f"; true poses in {os.fspath(tpath)}"
        return msg


def truth_path_for(log_path: PathLike) -> str:
    """The truth sidecar of a log: ``office.2d`` → ``office.truth.tsv``."""
    p = os.fspath(log_path)
    base = p[:-3] if p.lower().endswith(".2d") else p
    return base + ".truth.tsv"


def read_truth(path: PathLike) -> tuple[np.ndarray[Any, Any], FloatArray]:
    """Read a truth sidecar: ``(scan ids, (N, 3) poses)``.

    Raises:
        MapkitError: When a line is not ``id time x y th``.
        OSError: When the file cannot be read.
    """
    ids, poses = [], []
    with open(path, encoding="utf-8") as fh:
        for lineno, line in enumerate(fh, 1):
            if not line.strip() or line.startswith("#"):
                continue
            parts = line.split()
            try:
                if len(parts) != 5:
                    raise ValueError
                ids.append(int(parts[0]))
                poses.append([float(v) for v in parts[2:5]])
            except ValueError:
                raise MapkitError(f"{os.fspath(path)}:{lineno}: expected 'scanId time x y th'") from None
    return np.array(ids, dtype=np.int64), np.array(poses, dtype=np.float64).reshape(-1, 3)


def _points_off_lines(points: FloatArray, segments: FloatArray, tol: float) -> FloatArray:
    """The points that are not copies of a line (farther than ``tol`` from every line).

    Scanned maps hold each wall twice, as points and as a fitted line; the laser should see one
    wall, not a line with a rough skin of points in front of it. Points elsewhere (furniture,
    walls without a line) stay.
    """
    from scipy.spatial import cKDTree

    if len(points) == 0 or len(segments) == 0:
        return points
    length = np.hypot(segments[:, 2] - segments[:, 0], segments[:, 3] - segments[:, 1])
    k = np.maximum(np.ceil(length / (tol / 2)).astype(np.int64), 1) + 1
    idx = np.repeat(np.arange(len(segments)), k)
    t = (np.arange(int(k.sum())) - np.repeat(np.cumsum(k) - k, k)) / np.repeat(k - 1, k)
    samples = segments[idx, :2] + t[:, None] * (segments[idx, 2:] - segments[idx, :2])
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
                    self.ends.append((a, b, float(rng.uniform(800.0, 1400.0)),
                                      float(rng.uniform(0, 100))))
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
    if not 0 <= outliers < 1 or people < 0 or abs(scale_error) >= 0.5 or abs(turn_slip) >= 0.5:
        raise ValueError("outliers is a fraction in [0, 1); people >= 0; scale_error and "
                         "turn_slip are fractions under 0.5")
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
        th0 = 0.0 if not goals else math.degrees(
            math.atan2(goals[0][1] - first[1], goals[0][0] - first[0]))
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
    laser = LaserConfig(number=1, pose=Pose2D(*laser_pose), start=-half, end=half,
                        count=readings, name="sim_laser_1", z=0.0)
    angles = laser.angles()
    header = LogHeader(version=version, lasers=(laser,), location_types=("robot", "robotGlobal"),
                       comments=("Created by mapkit simulate",))
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

    def log_scan() -> None:
        nonlocal scan_id, last_logged
        lp = compose(true, laser.pose)
        r = ray_cast(lp, angles, segments, points, max_range=max_range, point_size=point_size)
        if crowd is not None:
            body = crowd.bodies(t)
            r = np.minimum(r, ray_cast(lp, angles, np.zeros((0, 4)), body, max_range=max_range,
                                       point_size=_BODY_PLATE))
        hit = np.isfinite(r)
        rn = np.where(hit, r + rng.normal(0.0, range_noise, len(r)) if range_noise > 0 else r, 0.0)
        if outliers > 0:
            bad = hit & (rng.random(len(r)) < outliers)
            rn = np.where(bad, rn * rng.uniform(0.05, 0.95, len(r)), rn)
        rn = np.where(hit & (rn < 1.0), 1.0, rn)
        a = np.radians(angles)
        xy = np.stack([rn * np.cos(a), rn * np.sin(a)], axis=1)
        xy[~hit] = 0.0
        xy = np.rint(xy)
        pose = Pose2D(round(float(odo[0])), round(float(odo[1])), round(float(odo[2]), 2))
        records.append(LaserScan(
            scan_id=scan_id, laser=1, robot=pose, robot_global=pose, time=round(t, 3),
            velocities=(round(speed if moving else 0.0, 2), round(turn_now, 2), 0.0), xy=xy,
            ranges=np.where(hit, np.rint(rn), NO_RETURN) if raw_ranges else None))
        truth.append(true.copy())
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
            event(loop_event("stop", str(loop_no), odo_pose(), time=round(t, 3),
                             robot_global=odo_pose()))
            if laps > 1 and loop_no < laps:
                loop_no += 1
                event(loop_event("start", str(loop_no), odo_pose(), time=round(t, 3),
                                 robot_global=odo_pose()))
        elif name is not None:
            goal_no += 1
            t += 0.5
            event(goal_event(name or f"goal{goal_no}", odo_pose(), time=round(t, 3),
                             robot_global=odo_pose()))
    tr = np.array(truth)
    odo_world = odo if odometry_origin == "start" else compose(np.array(home), odo)
    odo_err = relative(true, odo_world)
    log = LaserLog(header=header, records=tuple(records), complete=True, source="<simulated>")
    return SimulatedLog(
        log=log, truth=tr, truth_ids=np.array(truth_ids), truth_times=np.array(truth_times),
        distance=distance, skipped=tuple(skipped), odometry_error=(float(math.hypot(odo_err[0], odo_err[1])),
                                           float(abs(odo_err[2]))),
        params={"seed": seed, "fov": fov, "readings": readings, "max_range": max_range,
                "range_noise": range_noise, "translation_error": translation_error,
                "rotation_error": rotation_error, "drift": drift, "scale_error": scale_error,
                "turn_slip": turn_slip, "outliers": outliers, "people": people})

