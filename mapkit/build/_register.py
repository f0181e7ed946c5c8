"""Scan registration: each scan matched against the submap of those before it, in one or two
passes."""

from __future__ import annotations

import functools
import itertools
import math
from typing import Any

import numpy as np

from mapkit.build._calibrate import CalibrationFeed
from mapkit.build._common import FloatArray, Progress, _Submap
from mapkit.build._graph import PoseGraph, between, plus_variance, sigma_info, then, wrap
from mapkit.build._lag import bases, calm, step_variance
from mapkit.build._loops import (
    _CAUCHY,
    _close,
    _edge_info,
    _fuse,
    _loop_pairs,
    _revisit_candidate,
    match_info,
)
from mapkit.build._match import MatchResult, icp, scan_normals_many, widened
from mapkit.build._odometry import _OdometryModel
from mapkit.build._refine import refine
from mapkit.diagnostics import Issue, IssueCode
from mapkit.model.scan import LaserLog, LaserScan


def _register(
    scans: list[LaserScan],
    odo: FloatArray,
    all_pts: list[FloatArray],
    log: LaserLog,
    issues: list[Issue],
    stats: dict[str, Any],
    loop_closure: bool,
    progress: Progress | None,
    unsure: FloatArray | None = None,
    turn_error: float | None = None,
    noise: float = 0.0,
) -> FloatArray:
    """The front end (scan-to-local-map ICP) with loop closures and pose-graph optimisation.

    The odometry's worth is learnt from the first scans (a warm-up pass over them) so that the
    first metres are not registered with a guess of it.

    ``unsure``: the ``(N, 3)`` variances (x, y, heading) of each sweep about its
    pose that the odometry's model does not know of (sweeps whose lag varies,
    :func:`mapkit.build._lag.sweep_variance`); None: none.

    ``turn_error``: how far the robot's turns err, as a fraction of the turn, when it is known
    (see :meth:`_OdometryModel.stated_as`); None: presumed under a laser that scatters no more
    than 16 mm about the walls, unless the log's turns rule that out; fitted from the log
    otherwise.

    ``noise``: the laser's own scatter about the walls (mm,
    :func:`~mapkit.build._match.surface_noise`): no match's residual is taken as less, and a
    noisier laser's matches reach further (:func:`~mapkit.build._match.widened`).
    """
    n = len(scans)
    per = np.zeros((n, 3)) if unsure is None else unsure
    base = bases(unsure, n)
    model = _OdometryModel.stated_as(turn_error)
    warm_up = min(_WARM_UP, n // 2)
    if warm_up >= 20:
        warm_sides = _sides(all_pts[:warm_up])
        for _ in range(2):  # twice: the second pass runs with the scale the first found
            model = model.fresh()
            warm: dict[str, Any] = {
                "registered": 0,
                "odometry_only": 0,
                "residuals": [],
                "residual_per_scan": np.full(warm_up, np.nan),
                "closures": [],
            }
            _register_pass(
                scans[:warm_up],
                odo[:warm_up],
                all_pts[:warm_up],
                warm_sides,
                log,
                [],
                warm,
                False,
                None,
                model,
                (per[:warm_up], base[:warm_up]),
                noise,
            )
            model.settle()
    model.presume(noise)
    model.calibration.mark()
    blank = dict(stats)

    def fresh() -> dict[str, Any]:
        """Figures for a pass of their own (a pass run again does not add to the last's)."""
        return dict(
            blank,
            residuals=[],
            closures=[],
            corrections_mm=[],
            corrections_deg=[],
            residual_per_scan=blank["residual_per_scan"].copy(),
        )

    first = fresh()
    sides = _sides(all_pts)
    est = _register_pass(
        scans,
        odo,
        all_pts,
        sides,
        log,
        issues,
        first,
        loop_closure,
        progress,
        model,
        (per, base),
        noise,
    )
    model.calibration.settle()

    def again(model: _OdometryModel, drift: float) -> tuple[FloatArray, _OdometryModel]:
        """Once more from the start, with the odometry as calibrated (and ``drift`` taken out
        of it too), the calibration frozen."""
        model = model.fresh()
        model.calibration.drift += drift
        model.frozen = True
        stats.clear()
        stats.update(fresh())
        est = _register_pass(
            scans,
            odo,
            all_pts,
            sides,
            log,
            [],
            stats,
            loop_closure,
            None,
            model,
            (per, base),
            noise,
        )
        return est, model

    if model.calibration.moved and n <= _SECOND_PASS_MAX:
        # The odometry's systematic errors were learnt on the way: the first metres were
        # registered without them. (A long log comes back over its first metres many times:
        # its loop closures correct them instead.)
        est, model = again(model, 0.0)
    else:
        stats.update(first)
    # The refinement of a pass's poses est, with its odometry model.
    refined = functools.partial(
        _refined,
        odo=odo,
        sides=sides,
        first=all_pts[0],
        stats=stats,
        loop_closure=loop_closure,
        sweeps=(per, base),
        noise=noise,
    )
    poses, drift = refined(est, model=model)
    if drift and n <= _SECOND_PASS_MAX:
        # The refinement found a drift the calibration missed: the registration and the loop
        # closures ran with it and left the passes apart, which the refinement alone cannot
        # undo. Once more with the drift taken out.
        est, model = again(model, drift)
        poses, _ = refined(est, model=model)
    return poses


#: A scan's points as registration uses them: the scan side, the map side and its normals.
_Sides = tuple[list[FloatArray], list[FloatArray], list[FloatArray]]


def _sides(all_pts: list[FloatArray]) -> _Sides:
    """The points each scan is matched with (the scan side: about 120 points, a sparse
    laser's all, fewer leave too few to match; at the start registration takes the map side,
    see ``_START_PATH``) and matched against (the map side: every other point, the local map is
    thinned to 40 mm anyway), with the map side's normals from the beam order (the points are
    still in the laser's reading order)."""
    src = [p[:: max(1, len(p) // 120)] for p in all_pts]
    pts = [p[::2] if len(p) > 240 else p for p in all_pts]
    return src, pts, scan_normals_many(pts)


def _refined(
    est: FloatArray,
    odo: FloatArray,
    sides: _Sides,
    first: FloatArray,
    stats: dict[str, Any],
    loop_closure: bool,
    model: _OdometryModel,
    sweeps: tuple[FloatArray, np.ndarray[Any, Any]],
    noise: float = 0.0,
) -> tuple[FloatArray, float]:
    """The poses after the global refinement (:mod:`mapkit.build._refine`) where a place was
    seen more than once (loops closed), on logs of up to ``_REFINE_MAX`` scans, and the drift
    it found left in the odometry (radians per mm, 0.0: none). The odometry goes in as
    registration weighed it: its calibrated steps, with the noise the log showed. ``noise``:
    the laser's scatter about the walls (mm), as :func:`_register` takes it."""
    closed = stats.get("revisits", 0) or stats.get("tag_loops_matched", 0)
    if not loop_closure or not closed or len(est) > _REFINE_MAX:
        return est, 0.0
    path = np.concatenate(([0.0], np.cumsum(np.hypot(*np.diff(odo[:, :2], axis=0).T))))
    steps = np.array([model.calibration.correct(between(a, b)) for a, b in itertools.pairwise(odo)])
    per, base = sweeps
    spans = [_span(steps, per, base, i, model) for i in range(1, len(odo))]
    found = refine(
        est,
        path,
        *sides,
        first=first,
        rounds=_REFINE_ROUNDS,
        odometry=(np.array([z for z, _ in spans]), np.array([info for _, info in spans])),
        odometry_from=base[1:],
        unsure=_turning(step_variance(per)) if per.any() else None,
        laser_noise=noise,
    )
    stats["refined"] = found.matched
    return found.poses, found.drift


#: Longest log (scans) refined against the map of all its scans.
_REFINE_MAX = 5000

#: Rounds of the refinement (the second starts from the first's map, where the passes met).
_REFINE_ROUNDS = 2


#: Longest log (scans) registered a second time when the calibration was learnt on the way.
_SECOND_PASS_MAX = 5000

#: Scans of the warm-up pass that learns the odometry's noise.
_WARM_UP = 150

#: Path (mm) over which registration matches each scan with all its map-side points, not the
#: scan side's 120: the start, often a turn on the spot, sets how the whole map sits about it.
#: With 120 points a 361-beam scan matched from its true pose erred 0.11-0.26 degrees RMS there,
#: with all 0.04-0.12 (docs/logs.md, round 12).
_START_PATH = 1000.0


def _register_pass(
    scans: list[LaserScan],
    odo: FloatArray,
    all_pts: list[FloatArray],
    sides: _Sides,
    log: LaserLog,
    issues: list[Issue],
    stats: dict[str, Any],
    loop_closure: bool,
    progress: Progress | None,
    model: _OdometryModel,
    sweeps: tuple[FloatArray, np.ndarray[Any, Any]],
    noise: float = 0.0,
) -> FloatArray:
    """One pass of registration over ``scans``; ``noise``: the laser's own scatter about the
    walls (mm, :func:`~mapkit.build._match.surface_noise`), the least a match's residual is
    taken as (a noisier laser's matches reach further too)."""
    n = len(scans)
    per, base = sweeps
    observed = model.observed  # the steps of earlier passes (the warm-up's) are not this one's
    # The odometry from each scan's base (the scan before it, or across sweeps each off their
    # pose by a part of their own, the last calm one): calibrated, composed step by step.
    from_base = np.zeros((n, 3))
    # The sweeps the local map is made of: one off its pose by its own part of a varying lag
    # stays out of it (the calm sweep after a turn is matched against calm sweeps, not against
    # the turning ones, each placed by its own match).
    in_map = calm(base[1:])
    est = odo.copy()
    residuals = stats["residual_per_scan"]
    graph = PoseGraph()
    sub = _Submap(voxel=40.0)
    src, pts, nrm = sides
    path = np.zeros(n)
    # Running sums of the odometry's variance along the log (see _loops._within_reach).
    reach = (np.zeros(n), np.zeros(n))
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
    feed = CalibrationFeed(model.calibration, odo, path, src, all_pts, noise)
    widen = widened(noise)  # a noisy laser's matches reach further
    # A loop closure's match: scan i against the map around old scan j, from the estimate est.
    close = functools.partial(
        _close,
        src=src,
        pts=pts,
        nrm=nrm,
        path=path,
        graph=graph,
        stats=stats,
        reach=reach,
        laser_noise=noise,
    )
    last_reach = _REACH * widen
    for i in range(1, n):
        raw_step = between(odo[i - 1], odo[i])
        step = model.calibration.correct(raw_step)
        trans = math.hypot(step[0], step[1])
        path[i] = path[i - 1] + trans
        a = int(base[i])
        if a != i - 1:
            step = then(from_base[i - 1], step)  # i - 1 is not calm: its base is a too
            trans = path[i] - path[a]
        from_base[i] = step
        pred = then(est[a], step)
        # Odometry as the evidence it is: its noise grows with distance and turn, scaled to what
        # this log's odometry turns out to be worth (see _OdometryModel).
        own = model.info(trans, float(step[2]))
        # A sweep off its pose by its own part of a lag that varies: its heading is as unsure
        # as its turn rate makes it (see _lag.bases). Along its motion, that part is a few mm
        # and does not add up from sweep to sweep as a step's error does: it is only known noise
        # when the odometry's worth is fitted (observe), not a looser chain.
        odo_info = plus_variance(own, _turning(per[a] + per[i]))
        # How far odometry can be out since an old pose: what adds up, never less than at the
        # scan before (a span across a turn may net less turn than its steps).
        reach[0][i] = max(reach[0][a] + 1.0 / own[0, 0] + 1.0 / own[1, 1], reach[0][i - 1])
        reach[1][i] = max(reach[1][a] + 1.0 / own[2, 2], reach[1][i - 1])
        # The scan's own view: matched with only a weak pull to the prediction (which holds the
        # directions the scan cannot fix, a corridor's length), then fused with odometry.
        r = (
            icp(
                pts[i] if path[i] < _START_PATH else src[i],
                sub.tree,
                sub.pts,
                sub.nrm,
                pred,
                prior=pred,
                prior_info=weak_prior,
                schedule=(250.0, 100.0, last_reach),
                max_iter=12,
                cauchy=_CAUCHY,
            )
            if sub.tree is not None
            else None
        )
        dv = _seen(r, pred, trans, widen)
        if r is not None and dv is not None:
            scan_info = match_info(r, noise)
            model.observe(dv, scan_info, trans, float(step[2]), per[a] + per[i])
            if not model.frozen:
                feed.step(i, r.pose, scan_info)
            fused, scan_info = _fuse(dv, scan_info, odo_info)
            est[i] = pred + fused
            est[i, 2] = wrap(est[i, 2])
            stats["registered"] += 1
            stats["residuals"].append(r.rms)
            residuals[i] = r.rms
            # Two edges: the scan's (what it sees) and odometry's.
            seen = pred + dv
            graph.add(a, i, between(est[a], seen), _edge_info(scan_info, seen))
        else:
            est[i] = pred
            stats["odometry_only"] += 1
        graph.add(a, i, step, odo_info)
        # Loop closures.
        moved = False
        for s0, _tag in tag_at.get(i, []):
            if close(i, s0, est, tagged=True):
                stats["tag_loops_matched"] += 1
                moved = stats.pop("_moved", False) or moved
            else:
                # The tag says where the robot is, not which way it faces (it may come back
                # the other way round): a hint on the place alone.
                graph.add(
                    s0, i, _hint(est[s0], est[i]), sigma_info(500.0, 500.0, math.pi), robust=True
                )
                issues.append(
                    Issue.make(
                        IssueCode.LOG_UNPAIRED_LOOP,
                        f"loop tag {_tag}: the scans at its start and stop do "
                        "not match; used as a weak hint only",
                        source=log.source,
                    )
                )
                moved = True
        if loop_closure and i >= next_check:
            j = _revisit_candidate(i, est, path)
            if j is not None:
                if close(i, j, est, tagged=False):
                    stats["revisits"] += 1
                    moved = stats.pop("_moved", False) or moved
                    next_check = i + 20
                else:
                    next_check = i + 10
            else:
                next_check = i + 3
        if moved:
            feed.moved()  # the local map moves: older matches are in another frame
            est = graph.optimize(est, iterations=4)
            stats["optimisations"] += 1
            window = [k for k in window if k <= i]
            last_sub = -1
        # The local map: scans within the last 8 m of path (at most 40).
        if in_map[i]:
            window.append(i)
        while len(window) > 25 or (path[i] - path[window[0]] > 8000.0 and len(window) > 5):
            window.pop(0)
        # Every third scan; every scan while turning, when each scan brings a new view.
        if i - last_sub >= 3 or last_sub < 0 or abs(step[2]) > _TURNING:
            sub.rebuild(window, pts, nrm, est)
            last_sub = i
        if progress and (i % report_every == 0 or i == n - 1):
            progress(i + 1, n)
    stats["odometry_scale"] = round(float(model.scale), 4)
    stats["turn_error"] = model.turn_error
    stats["turn_error_stated"] = model.turn_stated
    stats["turn_error_ruled_out"] = model.turn_ruled_out
    stats["turn_error_presumed"] = model.turn_presumed
    stats["turns"] = model.turns(since=observed)
    stats["calibration"] = model.calibration.summary()
    if loop_closure and (stats["revisits"] or stats["tag_loops"]):
        est = graph.optimize(est, iterations=20, reject=_REJECT)
        stats["optimisations"] += 1
        # Closures the consistency check switched off are no closures.
        off = {(graph.i[k], graph.j[k]) for k in graph.rejected}
        stats["closures"] = [c for c in stats["closures"] if tuple(c) not in off]
        stats["closures_rejected"] = len(off)
    return est


def _span(
    steps: FloatArray, per: FloatArray, base: np.ndarray[Any, Any], i: int, model: _OdometryModel
) -> tuple[FloatArray, FloatArray]:
    """The odometry from scan ``i``'s base to it (``steps``: the calibrated steps between
    neighbours) and its information."""
    a = int(base[i])
    z = steps[i - 1]
    for k in range(i - 2, a - 1, -1):
        z = then(steps[k], z)
    trans = float(sum(math.hypot(s[0], s[1]) for s in steps[a:i]))
    return z, plus_variance(model.info(trans, float(z[2])), _turning(per[a] + per[i]))


def _turning(var: FloatArray) -> FloatArray:
    """The heading's part of a sweep's variances (see ``_register_pass``)."""
    out: FloatArray = var * _HEADING
    return out


_HEADING = np.array([0.0, 0.0, 1.0])


def _hint(start: FloatArray, now: FloatArray) -> FloatArray:
    """A ``loop:`` tag's claim when its scans do not match: the robot back at the tag's start
    (the same place), facing as the estimate has it."""
    return np.array([0.0, 0.0, wrap(now[2] - start[2])])


def _seen(
    r: MatchResult | None, pred: FloatArray, trans: float, widen: float = 1.0
) -> FloatArray | None:
    """How far the scan match ``r`` moved the prediction, or None for no usable match.

    Along a corridor the scan slides where nothing holds it: that part is no evidence and is
    taken out, and only the rest is checked against how far odometry can be off (a scan that
    slid half a metre along a corridor still fixes its heading and the corridor's width).
    ``widen``: its residual bar that many times higher (a noisy laser's).
    """
    if r is None or not r.holds(0.25, 60.0, widen):
        return None
    dv = r.pose - pred
    dv[2] = wrap(dv[2])
    weak = r.weak_direction()
    if weak is not None:
        dv[:2] -= weak * float(dv[:2] @ weak)
    if math.hypot(dv[0], dv[1]) >= 300.0 + 0.1 * trans or abs(dv[2]) >= math.radians(8.0):
        return None
    return dv


#: The last reach (mm) of registration's matches (each point's nearest point of the local map).
_REACH = 40.0

#: A step turning more than this (radians) rebuilds the local map at once.
_TURNING = math.radians(10.0)

#: A loop closure the optimised graph still misses by this many standard deviations is wrong.
_REJECT = 5.0


#: Scale of the robust (Cauchy) weights of scan points in registration (mm).
