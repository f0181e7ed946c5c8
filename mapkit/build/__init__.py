"""Build a ``.map`` from a ``.2d`` laser log, as Mapper3 did.

The pipeline (:func:`build_map`):

1. **Odometry replay**: each scan's ``robot:`` pose (or ``robotGlobal:``) gives the motion since
   the previous scan.
2. **Scan-to-map registration**: each scan is matched by point-to-line ICP (scipy's ``cKDTree``)
   against a local map made of the scans registered just before it, starting from the pose
   odometry predicts.
3. **Loop closure**: a ``loop: start K`` / ``loop: stop K`` pair in the log says the robot came
   back where it was; revisits are also detected (the robot is near a pose it had long before).
   Each is matched (a correlative search, then ICP) and becomes an edge of a pose graph, which is
   optimised (sparse Gauss-Newton) when it moves poses noticeably, and once at the end.
4. **Map**: every scan's points through its final pose, quantised to the resolution lattice
   (20 mm, as ARIA maps), cells hit too rarely dropped, walls thinned to the cells hit most; the
   points are sorted as ARIA's are.
5. **Lines**: segments fitted to the points (direction bins, split at gaps and corners, merge).
6. **Objects**: ``cairn:`` goal events become ``GoalWithHeading`` objects at their corrected
   pose; the first scan's pose becomes ``RobotHome``.

``register=False`` skips 2 and 3: the map of raw odometry.

Examples:
    >>> from mapkit.model import MapData, Scan
    >>> from mapkit.simulate import simulate_log
    >>> room = Scan.from_arrays(lines=[[0, 0, 8000, 0], [8000, 0, 8000, 5000],
    ...                                [8000, 5000, 0, 5000], [0, 5000, 0, 0]])
    >>> sim = simulate_log(MapData(scans=(room,)), start=(1500, 2500, 0),
    ...                    waypoints=[(6500, 2500), (6500, 1500)], seed=2)
    >>> result = build_map(sim.log)
    >>> m = result.map
    >>> m.scan.resolution, m.scan.points_sorted, len(m.lines) >= 3, m.objects[0].type
    (20, True, True, 'RobotHome')
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from mapkit._typing import PathLike
from mapkit.build._graph import PoseGraph, between, sigma_info, wrap
from mapkit.build._lines import extract_lines
from mapkit.build._mapping import pass_counts
from mapkit.build._match import correlative, icp, scan_normals, transform, voxel_keep
from mapkit.build._odometry import _OdometryModel
from mapkit.diagnostics import Issue, IssueCode
from mapkit.errors import LogFormatError
from mapkit.formats.laser2d import goal_fields, read_log, recover_log
from mapkit.model import MapData, MapObject, Scan
from mapkit.model.scan import LaserLog, LaserScan

__all__ = ["BuildResult", "build_map", "extract_lines"]

FloatArray = np.ndarray[Any, np.dtype[np.float64]]
#: progress(done, total): called as scans are registered.
Progress = Callable[[int, int], None]


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
    """

    map: MapData
    poses: FloatArray
    odometry: FloatArray
    scan_ids: np.ndarray[Any, Any]
    summary: dict[str, Any] = field(default_factory=dict)
    issues: tuple[Issue, ...] = ()
    residuals: FloatArray = field(default_factory=lambda: np.zeros(0))
    closures: np.ndarray[Any, Any] = field(default_factory=lambda: np.zeros((0, 2), dtype=np.int64))

    @property
    def moved(self) -> FloatArray:
        """``(N,)`` how far each scan's final pose lies from its odometry pose (mm)."""
        d: FloatArray = np.hypot(self.poses[:, 0] - self.odometry[:, 0],
                                 self.poses[:, 1] - self.odometry[:, 1])
        return d


def _deg(p: FloatArray) -> FloatArray:
    out = np.array(p, dtype=np.float64)
    out[..., 2] = np.degrees(out[..., 2])
    return out


def _rad(p: Any) -> FloatArray:
    out = np.array(p, dtype=np.float64)
    out[..., 2] = np.radians(out[..., 2])
    return out


class _Submap:
    """The local map scans are registered against: recent scans, thinned, with normals."""

    def __init__(self, voxel: float) -> None:
        self.voxel = voxel
        self.tree: Any = None
        self.pts = np.zeros((0, 2))
        self.nrm = np.zeros((0, 2))
        self._cache: dict[int, tuple[tuple[float, ...], FloatArray, FloatArray]] = {}

    def rebuild(self, idx: Iterable[int], pts: list[FloatArray], nrm: list[FloatArray],
                poses: FloatArray) -> None:
        from scipy.spatial import cKDTree

        cache: dict[int, tuple[tuple[float, ...], FloatArray, FloatArray]] = {}
        for k in idx:
            key = tuple(poses[k])
            hit = self._cache.get(k)
            if hit is None or hit[0] != key:
                hit = (key, *_world(pts[k], nrm[k], poses[k]))
            cache[k] = hit
        self._cache = cache
        self.pts, self.nrm = _thinned([h[1] for h in cache.values()],
                                      [h[2] for h in cache.values()], self.voxel)
        self.tree = (cKDTree(self.pts, balanced_tree=False, compact_nodes=False)
                     if len(self.pts) else None)


def _world(pts: FloatArray, nrm: FloatArray, pose: FloatArray) -> tuple[FloatArray, FloatArray]:
    """A scan's points that have a normal, and the normals, in the world through ``pose``."""
    good = np.isfinite(nrm[:, 0])
    c, s = math.cos(pose[2]), math.sin(pose[2])
    return transform(pts[good], pose), nrm[good] @ np.array([[c, s], [-s, c]])


def _thinned(P: list[FloatArray], N: list[FloatArray], voxel: float) -> tuple[FloatArray, FloatArray]:
    """Points (and normals) of several scans together, one per ``voxel`` cell."""
    if not P:
        return np.zeros((0, 2)), np.zeros((0, 2))
    p, n = np.concatenate(P), np.concatenate(N)
    keep = voxel_keep(p, voxel)
    return p[keep], n[keep]


def _scan_arrays(log: LaserLog, pose_source: str, max_range: float
                 ) -> tuple[list[LaserScan], FloatArray, list[FloatArray]]:
    scans, odo, pts = [], [], []
    for s in log.scans:
        las = log.header.laser(s.laser)
        p = s.robot_points(las, max_range=max_range)
        if len(p) < 10:
            continue
        pose = s.robot_global if pose_source == "robotGlobal" and s.robot_global is not None else s.robot
        scans.append(s)
        odo.append(pose)
        pts.append(p)
    return scans, _rad(np.array(odo, dtype=np.float64).reshape(-1, 3)), pts


def _loop_pairs(log: LaserLog, scan_records: list[LaserScan], issues: list[Issue]
                ) -> list[tuple[int, int, str]]:
    """(start scan index, stop scan index, tag) for each ``loop: start``/``stop`` pair."""
    position = {id(s): k for k, s in enumerate(scan_records)}
    last_scan = -1
    open_tags: dict[str, int] = {}
    pairs = []
    for rec in log.records:
        if isinstance(rec, LaserScan):
            if id(rec) in position:
                last_scan = position[id(rec)]
            continue
        if rec.kind != "loop":
            continue
        where = max(last_scan, 0)
        if rec.action == "start":
            open_tags[rec.name] = where
        elif rec.name in open_tags:
            pairs.append((open_tags.pop(rec.name), where, rec.name))
        else:
            issues.append(Issue.make(IssueCode.LOG_UNPAIRED_LOOP,
                                     f"loop: {rec.action} {rec.name} without a start",
                                     source=log.source, line=rec.line or None))
    for tag in open_tags:
        issues.append(Issue.make(IssueCode.LOG_UNPAIRED_LOOP, f"loop: start {tag} without a stop",
                                 source=log.source))
    return pairs


def _quantise(world: FloatArray, res: float, min_hits: int, thin: float,
              normals: FloatArray | None = None, origins: FloatArray | None = None,
              free_ratio: float = 0.0) -> np.ndarray[Any, Any]:
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
    scans, odo, pts = _scan_arrays(log, pose_source, max_range)
    n = len(scans)
    if n == 0:
        raise LogFormatError("the log has no scan with enough valid readings to build a map",
                             source=log.source)
    est = odo.copy()
    stats: dict[str, Any] = {"registered": 0, "odometry_only": 0, "residuals": [],
                             "residual_per_scan": np.full(n, np.nan), "closures": [],
                             "tag_loops": 0, "tag_loops_matched": 0, "revisits": 0,
                             "optimisations": 0, "corrections_mm": [], "corrections_deg": []}
    t1 = time.perf_counter()
    if register and n > 1:
        est = _register(scans, odo, pts, log, issues, stats, loop_closure, progress)
    elif progress:
        progress(n, n)
    t_reg = time.perf_counter() - t1
    # The map.
    t2 = time.perf_counter()
    world = np.concatenate([transform(p, e) for p, e in zip(pts, est)])
    origins = None
    if free_ratio > 0:
        mounts = np.array([log.header.laser(s.laser).pose[:2] for s in scans], dtype=np.float64)
        sensor = np.stack([transform(mounts[k:k + 1], est[k])[0] for k in range(n)])
        origins = np.repeat(sensor, [len(p) for p in pts], axis=0)
    normals = np.concatenate([
        scan_normals(p) @ np.array([[math.cos(e[2]), math.sin(e[2])], [-math.sin(e[2]), math.cos(e[2])]])
        for p, e in zip(pts, est)]) if thin > 0 else None
    points = _quantise(world, float(resolution), min_hits, thin, normals, origins, free_ratio)
    segs = (extract_lines(points.astype(np.float64), resolution=resolution,
                          min_length=min_line_length) if lines and len(points) else np.zeros((0, 4)))
    t_map = time.perf_counter() - t2
    objects = [MapObject("RobotHome", *_obj_pose(est[0]), name="Home")]
    objects.extend(_goals(log, scans, odo, est, pose_source, merge_goals))
    scan = Scan.from_arrays(points, np.rint(segs).astype(np.int64), resolution=resolution, sort=True)
    m = MapData(category="2D-Map", scans=(scan,), objects=tuple(objects))
    poses = _deg(est)
    odom = _deg(odo)
    res = stats.pop("residuals")
    per_scan = stats.pop("residual_per_scan")
    closures = np.array(stats.pop("closures"), dtype=np.int64).reshape(-1, 2)
    cm, cd = stats.pop("corrections_mm"), stats.pop("corrections_deg")
    length = float(np.sum(np.hypot(*np.diff(odo[:, :2], axis=0).T))) if n > 1 else 0.0
    summary = {
        "source": log.source,
        "version": log.header.version,
        "scans_in_log": len(log.scans),
        "scans_used": n,
        "register": register,
        "resolution": resolution,
        "path_length_m": round(length / 1000.0, 2),
        "registration": {
            "registered": stats["registered"],
            "odometry_only": stats["odometry_only"],
            "median_residual_mm": round(float(np.median(res)), 2) if res else None,
            "odometry_noise_scale": stats.get("odometry_scale"),
            "odometry_calibration": stats.get("calibration"),
        },
        "loops": {
            "tags": stats["tag_loops"],
            "tags_matched": stats["tag_loops_matched"],
            "revisits": stats["revisits"],
            "optimisations": stats["optimisations"],
            "max_correction_mm": round(max(cm), 1) if cm else 0.0,
            "max_correction_deg": round(max(cd), 2) if cd else 0.0,
        },
        "end_shift_from_odometry_mm": round(float(np.hypot(*(est[-1, :2] - odo[-1, :2]))), 1),
        "points": int(len(points)),
        "lines": int(len(segs)),
        "goals": len(objects) - 1,
        "seconds": {"read": round(t_read, 2), "register": round(t_reg, 2), "map": round(t_map, 2)},
    }
    return BuildResult(map=m, poses=poses, odometry=odom,
                       scan_ids=np.array([s.scan_id for s in scans]), summary=summary,
                       issues=tuple(issues), residuals=per_scan, closures=closures)


def _obj_pose(p: FloatArray) -> tuple[float, float, float]:
    return float(round(p[0])), float(round(p[1])), float(round(math.degrees(p[2]), 1))


def _goals(log: LaserLog, scans: list[LaserScan], odo: FloatArray, est: FloatArray,
           pose_source: str, merge: bool = True) -> list[MapObject]:
    """``cairn:`` goal events as objects at their corrected poses.

    With ``merge``, the goals of one name (a tag given on every lap) become one object at the
    mean pose (headings averaged on the circle), where the name first appeared.
    """
    position = {id(s): k for k, s in enumerate(scans)}
    last = 0
    out: list[MapObject] = []
    for rec in log.records:
        if isinstance(rec, LaserScan):
            last = position.get(id(rec), last)
            continue
        if rec.kind != "goal" or rec.robot is None:
            continue
        pose = rec.robot_global if pose_source == "robotGlobal" and rec.robot_global else rec.robot
        g = _rad(np.array(pose, dtype=np.float64))
        # The goal's pose relative to the nearest scan's odometry, put on that scan's final pose.
        rel = between(odo[last], g)
        c, s = math.cos(est[last][2]), math.sin(est[last][2])
        x = est[last][0] + c * rel[0] - s * rel[1]
        y = est[last][1] + s * rel[0] + c * rel[1]
        th = wrap(est[last][2] + rel[2])
        typ, desc, _icon, name = goal_fields(rec)
        out.append(MapObject(typ, *_obj_pose(np.array([x, y, th])), name=name, description=desc))
    return _merge_goals(out) if merge else out


def _merge_goals(goals: list[MapObject]) -> list[MapObject]:
    """One object per (type, name) at the mean pose; unnamed goals are kept as they are."""
    groups: dict[tuple[str, str], list[MapObject]] = {}
    order: list[tuple[str, str] | int] = []
    for k, g in enumerate(goals):
        if not g.name:
            order.append(k)
            continue
        key = (g.type, g.name)
        if key not in groups:
            groups[key] = []
            order.append(key)
        groups[key].append(g)
    out = []
    for item in order:
        if isinstance(item, int):
            out.append(goals[item])
            continue
        grp = groups[item]
        if len(grp) == 1:
            out.append(grp[0])
            continue
        th = np.radians([g.theta for g in grp])
        mean = np.array([np.mean([g.x for g in grp]), np.mean([g.y for g in grp]),
                         math.atan2(float(np.sin(th).sum()), float(np.cos(th).sum()))])
        out.append(MapObject(grp[0].type, *_obj_pose(mean), name=grp[0].name,
                             description=grp[0].description))
    return out


def _register(scans: list[LaserScan], odo: FloatArray, all_pts: list[FloatArray],
              log: LaserLog, issues: list[Issue], stats: dict[str, Any],
              loop_closure: bool, progress: Progress | None) -> FloatArray:
    """The front end (scan-to-local-map ICP) with loop closures and pose-graph optimisation.

    The odometry's worth is learnt from the first scans (a warm-up pass over them) so that the
    first metres are not registered with a guess of it.
    """
    n = len(scans)
    model = _OdometryModel()
    warm_up = min(_WARM_UP, n // 2)
    if warm_up >= 20:
        for _ in range(2):  # twice: the second pass runs with the scale the first found
            model = _OdometryModel(model.scale, model.calibration.fresh())
            warm: dict[str, Any] = {"registered": 0, "odometry_only": 0, "residuals": [],
                                    "residual_per_scan": np.full(warm_up, np.nan), "closures": []}
            _register_pass(scans[:warm_up], odo[:warm_up], all_pts[:warm_up], log, [], warm,
                           False, None, model)
            model.settle()
    start = model.calibration.fresh()
    first = dict(stats, residuals=[], closures=[], corrections_mm=[], corrections_deg=[],
                 residual_per_scan=stats["residual_per_scan"].copy())
    est = _register_pass(scans, odo, all_pts, log, issues, first, loop_closure, progress, model)
    if not model.calibration.differs(start) or n > _SECOND_PASS_MAX:
        stats.update(first)
        return est
    # The odometry's systematic errors were learnt on the way: the first metres were registered
    # without them. Once more from the start, with the odometry as calibrated. (A long log comes
    # back over its first metres many times: its loop closures correct them instead.)
    model = _OdometryModel(model.scale, model.calibration.fresh())
    model.frozen = True
    est = _register_pass(scans, odo, all_pts, log, [], stats, loop_closure, None, model)
    stats["passes"] = 2
    return est


#: Longest log (scans) registered a second time when the calibration was learnt on the way.
_SECOND_PASS_MAX = 5000

#: Scans of the warm-up pass that learns the odometry's noise.
_WARM_UP = 150


def _register_pass(scans: list[LaserScan], odo: FloatArray, all_pts: list[FloatArray],
                   log: LaserLog, issues: list[Issue], stats: dict[str, Any],
                   loop_closure: bool, progress: Progress | None, model: _OdometryModel
                   ) -> FloatArray:
    n = len(scans)
    est = odo.copy()
    residuals = stats["residual_per_scan"]
    graph = PoseGraph()
    odo_edges: list[int] = []
    raw_steps: list[FloatArray] = []
    sub = _Submap(voxel=40.0)
    src = [p[::3] if len(p) > 240 else (p[::2] if len(p) > 120 else p) for p in all_pts]
    # The map side: every other point (the local map is thinned to 40 mm anyway), with normals
    # from the beam order (the points are still in the laser's reading order).
    pts = [p[::2] if len(p) > 240 else p for p in all_pts]
    nrm = [scan_normals(p) for p in pts]
    path = np.zeros(n)
    pairs = _loop_pairs(log, scans, issues) if loop_closure else []
    stats["tag_loops"] = len(pairs)
    tag_at: dict[int, list[tuple[int, str]]] = {}
    for s0, s1, tag in pairs:
        tag_at.setdefault(s1, []).append((s0, tag))
    window: list[int] = [0]
    sub.rebuild(window, pts, nrm, est)
    next_check = 0
    last_sub = 0
    report_every = max(1, n // 200)
    weak_prior = sigma_info(300.0, 300.0, math.radians(10.0))
    for i in range(1, n):
        raw_step = between(odo[i - 1], odo[i])
        step = model.calibration.correct(raw_step)
        c, s = math.cos(est[i - 1][2]), math.sin(est[i - 1][2])
        pred = np.array([est[i - 1][0] + c * step[0] - s * step[1],
                         est[i - 1][1] + s * step[0] + c * step[1],
                         wrap(est[i - 1][2] + step[2])])
        trans = math.hypot(step[0], step[1])
        path[i] = path[i - 1] + trans
        # Odometry as the evidence it is: its noise grows with distance and turn, scaled to what
        # this log's odometry turns out to be worth (see _OdometryModel).
        odo_info = model.info(trans, float(step[2]))
        # The scan's own view: matched with only a weak pull to the prediction (which holds the
        # directions the scan cannot fix, a corridor's length), then fused with odometry.
        r = (icp(src[i], sub.tree, sub.pts, sub.nrm, pred, prior=pred, prior_info=weak_prior,
                 schedule=(250.0, 100.0, 40.0), max_iter=12, cauchy=_CAUCHY)
             if sub.tree is not None else None)
        if r is not None and r.ok and r.inliers > 0.25 and r.rms < 60.0 \
                and math.hypot(*(r.pose[:2] - pred[:2])) < 300.0 + 0.1 * trans \
                and abs(wrap(r.pose[2] - pred[2])) < math.radians(8.0):
            scan_info = r.info(sigma=_MATCH_SIGMA, points=_MATCH_POINTS)
            dv = r.pose - pred
            dv[2] = wrap(dv[2])
            weak = r.weak_direction()
            if weak is not None:
                # Along a corridor the scan slid where nothing held it: that is no evidence.
                dv[:2] -= weak * float(dv[:2] @ weak)
            model.observe(dv, scan_info, trans, float(step[2]))
            if not model.frozen:
                model.calibration.observe(raw_step, step, dv, scan_info, float(est[i - 1][2]))
            fused, scan_info = _fuse(dv, scan_info, odo_info)
            est[i] = pred + fused
            est[i, 2] = wrap(est[i, 2])
            stats["registered"] += 1
            stats["residuals"].append(r.rms)
            residuals[i] = r.rms
            # Two edges: the scan's (what it sees) and odometry's, so that odometry can be
            # recalibrated at the end without redoing the scans.
            seen = pred + dv
            graph.add(i - 1, i, between(est[i - 1], seen), _edge_info(scan_info, seen))
        else:
            est[i] = pred
            stats["odometry_only"] += 1
        odo_edges.append(len(graph))
        raw_steps.append(raw_step)
        graph.add(i - 1, i, step, odo_info)
        # Loop closures.
        moved = False
        for s0, _tag in tag_at.get(i, []):
            if _close(i, s0, est, src, pts, nrm, path, graph, stats, tagged=True):
                stats["tag_loops_matched"] += 1
                moved = stats.pop("_moved", False) or moved
            else:
                graph.add(s0, i, np.zeros(3), sigma_info(500.0, 500.0, math.radians(10.0)),
                          robust=True)
                issues.append(Issue.make(IssueCode.LOG_UNPAIRED_LOOP,
                                         f"loop tag {_tag}: the scans at its start and stop do "
                                         "not match; used as a weak hint only",
                                         source=log.source))
                moved = True
        if loop_closure and i >= next_check:
            j = _revisit_candidate(i, est, path)
            if j is not None:
                if _close(i, j, est, src, pts, nrm, path, graph, stats, tagged=False):
                    stats["revisits"] += 1
                    moved = stats.pop("_moved", False) or moved
                    next_check = i + 20
                else:
                    next_check = i + 10
            else:
                next_check = i + 3
        if moved:
            est = graph.optimize(est, iterations=4)
            stats["optimisations"] += 1
            window = [k for k in window if k <= i]
            last_sub = -1
        # The local map: scans within the last 8 m of path (at most 40).
        window.append(i)
        while len(window) > 25 or (path[i] - path[window[0]] > 8000.0 and len(window) > 5):
            window.pop(0)
        if i - last_sub >= 3 or last_sub < 0:
            sub.rebuild(window, pts, nrm, est)
            last_sub = i
        if progress and (i % report_every == 0 or i == n - 1):
            progress(i + 1, n)
    stats["odometry_scale"] = round(float(model.scale), 4)
    stats["calibration"] = model.calibration.summary()
    if loop_closure and (stats["revisits"] or stats["tag_loops"]):
        est = graph.optimize(est, iterations=20)
        stats["optimisations"] += 1
    return est


#: Mahalanobis distance of a match from odometry at which its weight halves.
_FUSE_ROBUST = 2.5

#: Scale of the robust (Cauchy) weights of scan points in registration (mm).
_CAUCHY = 25.0

#: What a scan match is worth, as if from this many independent points of this noise (mm).
_MATCH_SIGMA = 10.0
_MATCH_POINTS = 50.0


def _fuse(dv: FloatArray, scan_info: FloatArray, odo_info: FloatArray
          ) -> tuple[FloatArray, FloatArray]:
    """How far to move the odometry prediction towards a scan match ``dv`` away from it, and what
    the match is worth (its information, down-weighted when it is wild; the pose graph's edge).

    The two are weighed by their information. A match that disagrees with odometry far beyond
    both noises (a feature seen for the first time caught on the wrong wall, a person) is
    down-weighted: Cauchy weights on the Mahalanobis distance, halved at ``_FUSE_ROBUST``.
    """
    both = np.linalg.inv(scan_info + np.eye(3) * 1e-9) + np.linalg.inv(odo_info)
    m2 = float(dv @ np.linalg.solve(both, dv))
    info = scan_info / (1.0 + m2 / _FUSE_ROBUST ** 2)
    out = np.linalg.solve(info + odo_info + np.eye(3) * 1e-12, info @ dv)
    return np.asarray(out, dtype=np.float64), info


def _revisit_candidate(i: int, est: FloatArray, path: FloatArray) -> int | None:
    """An old scan near the current pose (path-wise far away), or None."""
    old = np.flatnonzero(path[:i] < path[i] - 10000.0)
    if len(old) == 0:
        return None
    d = np.hypot(est[old, 0] - est[i, 0], est[old, 1] - est[i, 1])
    gap = path[i] - path[old]
    allow = np.minimum(1000.0 + 0.02 * gap, 4000.0)
    near = d < allow
    if not near.any():
        return None
    cand = old[near]
    return int(cand[np.argmin(d[near])])


def _local(idx: range, est: FloatArray, pts: list[FloatArray], nrm: list[FloatArray]
           ) -> tuple[FloatArray, FloatArray]:
    parts = [_world(pts[k], nrm[k], est[k]) for k in idx]
    return _thinned([a for a, _ in parts], [b for _, b in parts], 40.0)


def _edge_info(world_info: FloatArray, pose_j: FloatArray) -> FloatArray:
    """A world-frame pose information turned into the frame of an edge's error (pose j)."""
    c, s = math.cos(pose_j[2]), math.sin(pose_j[2])
    M = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    info: FloatArray = M.T @ world_info @ M + np.eye(3) * 1e-9
    return info


def _close(i: int, j: int, est: FloatArray, src: list[FloatArray], pts: list[FloatArray],
           nrm: list[FloatArray], path: FloatArray, graph: PoseGraph, stats: dict[str, Any], *,
           tagged: bool) -> bool:
    """Match scan i (with its predecessors) against the map around old scan j; add an edge.

    A ``loop:`` tag claims the robot is back where it was at the tag's start: the match then
    starts there and the claim holds the directions the scans cannot fix. A detected revisit
    starts from the current estimate, which also holds the unconstrained directions.
    """
    from scipy.spatial import cKDTree

    n = len(est)
    lo = j
    while lo > 0 and path[j] - path[lo - 1] < 3000.0 and j - lo < 15:
        lo -= 1
    hi = j
    while hi < n - 1 and hi < i and path[hi + 1] - path[j] < 3000.0 and hi - j < 15 \
            and path[i] - path[hi + 1] > 5000.0:
        hi += 1
    tgt, tn = _local(range(lo, hi + 1), est, pts, nrm)
    if len(tgt) < 50:
        return False
    tree = cKDTree(tgt)
    # Source: scan i and a few before it, in scan i's frame.
    s_parts = [src[i]]
    for k in range(max(0, i - 4), i):
        s_parts.append(transform(src[k], between(est[i], est[k])))
    source = np.concatenate(s_parts)
    source = source[voxel_keep(source, 60.0)]
    gap = path[i] - path[j]
    if tagged:
        guess = np.array([est[j][0], est[j][1], est[i][2]])
        claim = sigma_info(400.0, 400.0, 10.0)
        win, thw = 3000.0, math.radians(25.0)
    else:
        guess = est[i].copy()
        allow = min(800.0 + 0.02 * gap, 3000.0)
        claim = sigma_info(allow, allow, 10.0)
        win, thw = allow, math.radians(min(5.0 + 0.2 * gap / 1000.0, 20.0))
    sched = (400.0, 200.0, 100.0, 60.0)
    r = icp(source, tree, tgt, tn, guess, schedule=sched, max_iter=20, prior=guess,
            prior_info=claim)
    good = _good_closure(r, tagged)
    if not good:
        sub = source[:: max(1, len(source) // 150)]
        cp, score = correlative(sub, tgt, guess, xy_window=win, th_window=thw, cell=50.0)
        if score >= 0.25:
            r = icp(source, tree, tgt, tn, cp, schedule=(200.0, 100.0, 60.0), max_iter=20,
                    prior=guess, prior_info=claim)
            good = _good_closure(r, tagged)
    if not good:
        return False
    weak = r.weak_direction()
    if weak is not None:
        # Along a corridor the match says nothing: keep the estimate there.
        r.pose[:2] -= weak * float((r.pose[:2] - guess[:2]) @ weak)
        if not tagged:
            r.pose[:2] += weak * float((guess[:2] - est[i][:2]) @ weak)
    corr = math.hypot(*(r.pose[:2] - est[i][:2]))
    dth = abs(float(wrap(r.pose[2] - est[i][2])))
    info = r.info() + (claim if tagged else 0.0)
    graph.add(j, i, between(est[j], r.pose), _edge_info(info, r.pose), robust=True)
    stats["corrections_mm"].append(corr)
    stats["closures"].append((j, i))
    stats["corrections_deg"].append(math.degrees(dth))
    stats["_moved"] = corr > 80.0 or dth > math.radians(0.8)
    return True


def _good_closure(r: Any, tagged: bool) -> bool:
    if tagged:
        return bool(r.ok and r.inliers > 0.35 and r.n > 60 and r.rms < 35.0)
    return bool(r.ok and r.inliers > 0.45 and r.n > 80 and r.rms < 35.0)



def _read_2d_as_map(path: PathLike) -> MapData:
    """``mapkit convert LOG.2d OUT``: the raw odometry map (no registration; see ``mapkit build``)."""
    return build_map(path, register=False).map


def _register_reader() -> None:
    from mapkit.formats.registry import register_reader

    register_reader(".2d", _read_2d_as_map)


_register_reader()
