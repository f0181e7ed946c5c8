""":func:`build_map`: a map from a ``.2d`` laser log, scan registration, loop closure and the
grid of hits, with its :class:`BuildResult` report."""

from __future__ import annotations

import math
import time
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any, NamedTuple

import numpy as np

from mapkit._typing import PathLike
from mapkit.build._common import FloatArray, Progress, _deg, _rad
from mapkit.build._goals import _goals, _obj_pose
from mapkit.build._graph import between
from mapkit.build._lag import Lag, measure as measure_lag, sweep_variance, taken_from, velocities
from mapkit.build._lines import extract_lines
from mapkit.build._mapping import pass_counts
from mapkit.build._match import scan_normals_many, surface_noise, transform
from mapkit.build._odometry import TurnEvidence, pooled_turn_error
from mapkit.build._register import _register
from mapkit.diagnostics import Issue
from mapkit.errors import LogFormatError
from mapkit.formats.laser2d import read_log, recover_log
from mapkit.model import MapData, MapObject, Scan
from mapkit.model.scan import LaserLog, LaserScan

__all__ = ["BuildResult", "TurnEvidence", "build_map", "robot_turn_error"]


@dataclass(frozen=True)
class BuildResult:
    """A built map and how it was made.

    Attributes:
        map: The map.
        poses: ``(N, 3)`` final pose of each scan used (mm, mm, degrees).
        odometry: ``(N, 3)`` the same scans' odometry poses.
        scan_ids: ``(N,)`` their ``scanId``.
        summary: Figures for people and ``--json`` (scans, registration, loops, timings).
        issues: Problems met in the log (tolerant reading) and while building.
        residuals: ``(N,)`` RMS point-to-wall residual of each scan's match (mm; NaN where the
            scan was placed by odometry alone).
        closures: ``(K, 2)`` scan indices ``(old, new)`` of every loop closed.
        turns: What the log's turning steps (each turning more than 5 degrees) said of how
            far the robot's odometry errs in its turns: pooled over several logs of one robot
            by :func:`robot_turn_error` (empty without registration).
    """

    map: MapData
    poses: FloatArray
    odometry: FloatArray
    scan_ids: np.ndarray[Any, Any]
    summary: dict[str, Any] = field(default_factory=dict)
    issues: tuple[Issue, ...] = ()
    residuals: FloatArray = field(default_factory=lambda: np.zeros(0))
    closures: np.ndarray[Any, Any] = field(default_factory=lambda: np.zeros((0, 2), dtype=np.int64))
    turns: TurnEvidence = field(default_factory=TurnEvidence.none)

    @property
    def moved(self) -> FloatArray:
        """``(N,)`` how far each scan's final pose lies from its odometry pose (mm)."""
        d: FloatArray = np.hypot(
            self.poses[:, 0] - self.odometry[:, 0], self.poses[:, 1] - self.odometry[:, 1]
        )
        return d


def robot_turn_error(builds: Iterable[BuildResult | TurnEvidence]) -> float | None:
    """How far a robot's odometry errs in its turns (a fraction of each turn, standard
    deviation), learnt from the builds of several of its logs at once (or their
    :attr:`BuildResult.turns`, kept from earlier builds): the value to give :func:`build_map` as
    ``turn_error`` for this robot's logs. None when the logs have fewer than 10 turning steps
    in all.

    Each build fits its own log's turns too where they rule out the presumed 0.1 %
    (``odometry_turn_error`` in its summary), but a log's hundred-odd turning steps resolve
    them only coarsely: on simulated logs of robots
    whose turns err 0.1 %, one log alone gave anywhere from 0.03 % to 0.42 %. Built with what
    the 17 other logs of its robot taught (1,800-2,000 turning steps), 264 of 270 logs met
    every target where 258 did with their own fits; what 3 logs taught (300-400 steps) was no
    better than each log's own fit (docs/logs.md, round 20). The more logs, the better.

    Examples:
        >>> from mapkit.model import MapData, Scan
        >>> from mapkit.simulate import simulate_log
        >>> room = Scan.from_arrays(lines=[[0, 0, 8000, 0], [8000, 0, 8000, 5000],
        ...                                [8000, 5000, 0, 5000], [0, 5000, 0, 0]])
        >>> tour = [(6500, 2500), (6500, 1500), (2000, 1500), (2000, 3500)]
        >>> builds = [build_map(simulate_log(MapData(scans=(room,)), start=(1500, 2500, 0),
        ...                                  waypoints=tour, seed=seed).log)
        ...           for seed in (1, 2)]
        >>> error = robot_turn_error(builds)
        >>> 0.0 <= error < 0.05
        True
    """
    return pooled_turn_error(b.turns if isinstance(b, BuildResult) else b for b in builds)


def _ms(seconds: float) -> float | None:
    """Seconds as milliseconds for the summary (None: not measured)."""
    return round(seconds * 1000.0, 1) if math.isfinite(seconds) else None


class _Cycles(NamedTuple):
    """The scans registration works on (see :func:`_cycles`)."""

    #: Each scan's record (a cycle's first sweep).
    scans: list[LaserScan]
    #: ``(N, 3)`` their poses (radians).
    odo: FloatArray
    #: Each scan's points (robot frame).
    pts: list[FloatArray]
    #: Where each point's beam starts (its laser, robot frame).
    origins: list[FloatArray]
    #: How many sweeps were merged into another's scan.
    merged: int


def _scan_arrays(
    log: LaserLog, pose_source: str, max_range: float
) -> tuple[list[LaserScan], FloatArray, list[FloatArray]]:
    """The scans registration works on: records, poses (radians) and points (:func:`_cycles`)."""
    c = _cycles(log, pose_source, max_range)
    return c.scans, c.odo, c.pts


def _cycles(log: LaserLog, pose_source: str, max_range: float) -> _Cycles:
    """The scans registration works on: their records, poses, points and the points' laser
    origins, and how many sweeps were merged into another's scan.

    The sweeps of one logging cycle (one ``logTime:``, a sweep of each laser: a front and a rear
    laser, say) are one scan: their points, in the first sweep's robot frame, see all round.
    Matched as scans of their own, each laser's sweep met a local map half made of the other
    laser's view: on 30 two-laser logs of real ARIA maps, 10.9 mm RMS on average against 9.0
    merged, worst 27.9 against 22.0, in 2.4 times the CPU (docs/logs.md, round 16)."""
    scans: list[LaserScan] = []
    odo: list[Any] = []
    pts: list[FloatArray] = []
    origins: list[FloatArray] = []
    merged = 0
    group: list[LaserScan] = []

    def pose_of(s: LaserScan) -> Any:
        if pose_source == "robotGlobal" and s.robot_global is not None:
            return s.robot_global
        return s.robot

    def flush() -> None:
        nonlocal merged
        if not group:
            return
        first = group[0]
        # The sweeps' poses, for the later ones (a one-laser log has none: no work per scan).
        at = _rad(np.array([pose_of(s) for s in group], dtype=np.float64)) if group[1:] else None
        parts, mounts = [], []
        for k, s in enumerate(group):
            las = log.header.laser(s.laser)
            p = s.robot_points(las, max_range=max_range)
            mount = np.array(las.pose[:2], dtype=np.float64)
            if at is not None and k:
                # Into the first sweep's frame (the robot may have moved between the sweeps).
                rel = between(at[0], at[k])
                p = transform(p, rel)
                mount = transform(mount[None, :], rel)[0]
            parts.append(p)
            mounts.append(np.broadcast_to(mount, p.shape))
        p = np.concatenate(parts) if len(parts) > 1 else parts[0]
        group.clear()
        if len(p) < 10:
            return
        merged += len(parts) - 1
        scans.append(first)
        odo.append(pose_of(first))
        pts.append(p)
        origins.append(np.concatenate(mounts) if len(mounts) > 1 else mounts[0])

    for s in log.scans:
        if not (
            group
            and s.time is not None
            and s.time == group[0].time
            and all(g.laser != s.laser for g in group)
        ):
            flush()
        group.append(s)
    flush()
    return _Cycles(
        scans, _rad(np.array(odo, dtype=np.float64).reshape(-1, 3)), pts, origins, merged
    )


def _through(local: FloatArray, poses: FloatArray, sizes: list[int], *, shift: bool) -> FloatArray:
    """Points (or, without ``shift``, directions) of consecutive scans, ``sizes[k]`` of them
    through ``poses[k]`` (radians): :func:`transform` of all scans at once."""
    # One cosine and sine per scan, repeated for its points.
    c, s = np.repeat(np.cos(poses[:, 2]), sizes), np.repeat(np.sin(poses[:, 2]), sizes)
    out = np.empty_like(local)
    out[:, 0] = local[:, 0] * c - local[:, 1] * s
    out[:, 1] = local[:, 0] * s + local[:, 1] * c
    if shift:
        out[:, 0] += np.repeat(poses[:, 0], sizes)
        out[:, 1] += np.repeat(poses[:, 1], sizes)
    return out


def _quantise(
    world: FloatArray,
    res: float,
    min_hits: int,
    thin: float,
    normals: FloatArray | None = None,
    origins: FloatArray | None = None,
    free_ratio: float = 0.0,
) -> np.ndarray[Any, Any]:
    """Lattice points hit often enough, with walls thinned to the cells hit most.

    A cell is kept when hit at least ``min_hits`` times and at least ``thin`` x its most-hit
    neighbour; where the hits have a clear wall direction (``normals``), only the cell hit most
    across the wall (non-maximum suppression along the normal) is kept, so a wall is one cell thick
    instead of the two or three that range noise spreads it over.

    With ``origins`` (the laser's position for each hit), a cell is also dropped when other beams
    passed through it more than ``free_ratio`` times as often as it was hit: a person walking by
    or a spurious reading, not a wall (see :mod:`mapkit.build._mapping`).
    """
    cells = np.rint(world / res).astype(np.int64)
    off = 1 << 24
    key = ((cells[:, 0] + off) << 32) | (cells[:, 1] + off)
    uk, inverse, counts = np.unique(key, return_inverse=True, return_counts=True)
    cx = (uk >> 32) - off
    cy = (uk & 0xFFFFFFFF) - off

    def neighbour(dx: Any, dy: Any) -> np.ndarray[Any, Any]:
        nk = ((cx + dx + off) << 32) | (cy + dy + off)
        pos = np.minimum(np.searchsorted(uk, nk), len(uk) - 1)
        return np.where(uk[pos] == nk, counts[pos], 0)

    best = counts.copy()
    for dx in (-1, 0, 1):
        for dy in (-1, 0, 1):
            if dx or dy:
                best = np.maximum(best, neighbour(dx, dy))
    keep = (counts >= min_hits) & (counts >= thin * best)
    if origins is not None and free_ratio > 0 and keep.any():
        cand = np.flatnonzero(keep)
        passes = pass_counts(world, origins, res, np.stack([cx[cand], cy[cand]], axis=1))
        keep[cand[passes > free_ratio * counts[cand]]] = False
    if normals is not None and len(normals) == len(world):
        ok = np.isfinite(normals[:, 0])
        phi2 = 2.0 * np.arctan2(normals[ok, 1], normals[ok, 0])  # sign-free (doubled) angle
        n_ok = np.bincount(inverse[ok], minlength=len(uk))
        c2 = np.bincount(inverse[ok], weights=np.cos(phi2), minlength=len(uk))
        s2 = np.bincount(inverse[ok], weights=np.sin(phi2), minlength=len(uk))
        strength = np.hypot(c2, s2) / np.maximum(n_ok, 1)
        ang = 0.5 * np.arctan2(s2, c2)
        sector = np.rint(ang / (np.pi / 4)).astype(np.int64) % 4
        steps = np.array([[1, 0], [1, 1], [0, 1], [-1, 1]])
        sx, sy = steps[sector, 0], steps[sector, 1]
        plus, minus = neighbour(sx, sy), neighbour(-sx, -sy)
        walled = (strength > 0.7) & (n_ok >= min_hits)
        keep &= ~walled | ((counts >= plus) & (counts >= minus))
    return np.stack([cx[keep], cy[keep]], axis=1) * int(res)


def build_map(
    source: LaserLog | PathLike,
    *,
    resolution: int = 20,
    register: bool = True,
    loop_closure: bool = True,
    pose_source: str = "robot",
    max_range: float = 16000.0,
    min_hits: int = 2,
    thin: float = 0.3,
    free_ratio: float = 4.0,
    lines: bool = True,
    min_line_length: float = 300.0,
    strict: bool = True,
    merge_goals: bool = True,
    turn_error: float | None = None,
    progress: Progress | None = None,
) -> BuildResult:
    """Turn a ``.2d`` laser log into a map (see the module's description of the pipeline).

    Args:
        source: A :class:`~mapkit.model.LaserLog` or the path of a ``.2d`` file.
        resolution: Grid of the map's points in mm (ARIA maps: 20).
        register: Register scans and close loops; ``False`` gives the raw odometry map.
        loop_closure: Close loops (``loop:`` tags and detected revisits).
        pose_source: ``"robot"`` (odometry, as Mapper3) or ``"robotGlobal"``.
        max_range: Readings at or beyond this range (mm) are not used.
        min_hits: A map point needs at least this many laser hits in its cell.
        thin: A cell is kept only when hit at least this fraction of its most-hit neighbour
            (thins walls to the cells the laser hit most, one cell across a wall; 0 keeps every
            cell).
        free_ratio: A cell is left out when beams passed through it more than this many times
            as often as they hit it (people walking by, spurious readings); 0 keeps every cell.
        lines: Fit line segments to the points (the map's ``LINES``).
        min_line_length: Shortest line kept (mm).
        strict: Read a file strictly (the first bad record raises); ``False`` skips bad records
            and lists them in :attr:`BuildResult.issues`.
        merge_goals: Goals of the same name (a tag repeated on every lap) become one object at
            their mean pose; ``False`` keeps one object per ``cairn:`` event.
        turn_error: How far the robot's odometry errs in its turns, as a fraction of each turn
            (standard deviation: 0.001 for 0.1 %), when it is known. None (the default)
            presumes 0.1 % once registration's warm-up (the first 150 scans) has seen the turns
            and they do not rule that out (``odometry_turn_error_presumed`` in the summary's
            ``registration``), and fits it from the log where they do (a robot that slips) or
            where the laser scatters more than 16 mm about the walls (``laser_noise_mm``).
            A log's few dozen turns resolve it only coarsely: fitted alone, a good robot's
            turns (0.1 % or less) came out as 0.2-0.45 %, and each turn's own scan match then
            outvoted its odometry (docs/logs.md, rounds 19 and 27). Where the log's turns rule
            a stated error out, it is fitted after all (``odometry_turn_error_ruled_out``).
        progress: Called as ``progress(done, total)`` while scans are registered.

    Returns:
        The map and the figures of how it was built.

    Raises:
        LogFormatError: When the log cannot be read, or has no usable scan.
        ValueError: For a parameter out of range.
        OSError: When the file cannot be read.
    """
    if resolution < 1:
        raise ValueError("resolution must be at least 1 mm")
    if pose_source not in ("robot", "robotGlobal"):
        raise ValueError("pose_source is 'robot' or 'robotGlobal'")
    if turn_error is not None and not 0.0 <= turn_error < 1.0:
        raise ValueError("turn_error is a fraction of the turn, at least 0 and below 1")
    t0 = time.perf_counter()
    issues: list[Issue] = []
    if isinstance(source, LaserLog):
        log = source
    elif strict:
        log = read_log(source)
    else:
        log, found = recover_log(source)
        issues.extend(found)
    t_read = time.perf_counter() - t0
    scans, odo, pts, mounts, merged = _cycles(log, pose_source, max_range)
    n = len(scans)
    if n == 0:
        raise LogFormatError(
            "the log has no scan with enough valid readings to build a map", source=log.source
        )
    est = odo.copy()
    stats: dict[str, Any] = {
        "registered": 0,
        "odometry_only": 0,
        "residuals": [],
        "residual_per_scan": np.full(n, np.nan),
        "closures": [],
        "tag_loops": 0,
        "tag_loops_matched": 0,
        "revisits": 0,
        "optimisations": 0,
        "corrections_mm": [],
        "corrections_deg": [],
    }
    t1 = time.perf_counter()
    lag = Lag(0.0, math.nan, math.nan, 0)
    taken = odo  # the poses the sweeps were taken from (odo, unless they lag behind it)
    vel = velocities(scans) if register else None
    unsure = None  # how far each sweep is off its pose, when the lag varies
    # How far the laser's points scatter about the walls: no match is taken as better, and a
    # noisier laser's matches reach further.
    noise = surface_noise(pts) if register else 0.0
    stats["surface_noise"] = noise if register else None
    if vel is not None:
        lag = measure_lag(odo, vel, pts, noise)
        taken = taken_from(odo, vel, lag.seconds)
        est = taken.copy()
        if lag.jitter > 0.0:
            unsure = sweep_variance(vel, lag.jitter)
    if register and n > 1:
        est = _register(
            scans, taken, pts, log, issues, stats, loop_closure, progress, unsure, turn_error, noise
        )
    elif progress:
        progress(n, n)
    t_reg = time.perf_counter() - t1
    # The map.
    t2 = time.perf_counter()
    sizes = [len(p) for p in pts]
    world = _through(np.concatenate(pts), est, sizes, shift=True)
    origins = None
    if free_ratio > 0:
        origins = _through(np.concatenate(mounts), est, sizes, shift=True)
    normals = (
        _through(np.concatenate(scan_normals_many(pts)), est, sizes, shift=False)
        if thin > 0
        else None
    )
    points = _quantise(world, float(resolution), min_hits, thin, normals, origins, free_ratio)
    segs = (
        extract_lines(points.astype(np.float64), resolution=resolution, min_length=min_line_length)
        if lines and len(points)
        else np.zeros((0, 4))
    )
    t_map = time.perf_counter() - t2
    objects = [MapObject("RobotHome", *_obj_pose(est[0]), name="Home")]
    objects.extend(_goals(log, scans, taken, est, pose_source, merge_goals))
    scan = Scan.from_arrays(
        points, np.rint(segs).astype(np.int64), resolution=resolution, sort=True
    )
    m = MapData(category="2D-Map", scans=(scan,), objects=tuple(objects))
    poses = _deg(est)
    odom = _deg(odo)
    res = stats.pop("residuals")
    per_scan = stats.pop("residual_per_scan")
    closures = np.array(stats.pop("closures"), dtype=np.int64).reshape(-1, 2)
    cm, cd = stats.pop("corrections_mm"), stats.pop("corrections_deg")
    turns = stats.pop("turns", TurnEvidence.none())
    length = float(np.sum(np.hypot(*np.diff(odo[:, :2], axis=0).T))) if n > 1 else 0.0
    summary = {
        "source": log.source,
        "version": log.header.version,
        "scans_in_log": len(log.scans),
        "scans_used": n,
        "sweeps_merged": merged,
        "register": register,
        "resolution": resolution,
        "path_length_m": round(length / 1000.0, 2),
        "registration": {
            "registered": stats["registered"],
            "odometry_only": stats["odometry_only"],
            "median_residual_mm": round(float(np.median(res)), 2) if res else None,
            "laser_noise_mm": (
                None if stats.get("surface_noise") is None else round(stats["surface_noise"], 1)
            ),
            "odometry_noise_scale": stats.get("odometry_scale"),
            "odometry_calibration": stats.get("calibration"),
            "odometry_turn_error": (
                None if stats.get("turn_error") is None else round(stats["turn_error"], 5)
            ),
            "odometry_turn_error_stated": stats.get("turn_error_stated", False),
            "odometry_turn_error_ruled_out": stats.get("turn_error_ruled_out", False),
            "odometry_turn_error_presumed": stats.get("turn_error_presumed", False),
            "refined": stats.get("refined", 0),
            "scan_lag_ms": _ms(lag.seconds),
            "scan_lag_fitted_ms": _ms(lag.fitted),
            "scan_lag_error_ms": _ms(lag.error),
            "scan_lag_pairs": lag.pairs,
            "scan_lag_jitter_ms": _ms(lag.jitter),
            "scan_lag_jitter_fitted_ms": _ms(lag.jitter_fitted),
        },
        "loops": {
            "tags": stats["tag_loops"],
            "tags_matched": stats["tag_loops_matched"],
            "revisits": stats["revisits"],
            "rejected": stats.get("closures_rejected", 0),
            "refused": stats.get("closures_refused", 0),
            "optimisations": stats["optimisations"],
            "max_correction_mm": round(max(cm), 1) if cm else 0.0,
            "max_correction_deg": round(max(cd), 2) if cd else 0.0,
        },
        "end_shift_from_odometry_mm": round(float(np.hypot(*(est[-1, :2] - odo[-1, :2]))), 1),
        "points": len(points),
        "lines": len(segs),
        "goals": len(objects) - 1,
        "seconds": {"read": round(t_read, 2), "register": round(t_reg, 2), "map": round(t_map, 2)},
    }
    return BuildResult(
        map=m,
        poses=poses,
        odometry=odom,
        scan_ids=np.array([s.scan_id for s in scans]),
        summary=summary,
        issues=tuple(issues),
        residuals=per_scan,
        closures=closures,
        turns=turns,
    )
