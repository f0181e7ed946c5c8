"""Loop closure: revisits found along the path, matched, checked and added to the pose graph."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from mapkit.build._common import FloatArray, _thinned, _world
from mapkit.build._graph import PoseGraph, between, sigma_info, wrap
from mapkit.build._match import correlative, icp, transform, voxel_keep, widened
from mapkit.diagnostics import Issue, IssueCode
from mapkit.model.scan import LaserLog, LaserScan


def _loop_pairs(
    log: LaserLog, scan_records: list[LaserScan], issues: list[Issue]
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
            issues.append(
                Issue.make(
                    IssueCode.LOG_UNPAIRED_LOOP,
                    f"loop: {rec.action} {rec.name} without a start",
                    source=log.source,
                    line=rec.line or None,
                )
            )
    for tag in open_tags:
        issues.append(
            Issue.make(
                IssueCode.LOG_UNPAIRED_LOOP, f"loop: start {tag} without a stop", source=log.source
            )
        )
    return pairs


_CAUCHY = 25.0

#: What a scan match is worth, as if from this many independent points of this noise (mm).
_MATCH_SIGMA = 10.0
_MATCH_POINTS = 50.0

#: A loop closure's match is worth as much as its points at this noise (mm; MatchResult.info's
#: ten points).
_CLOSURE_SIGMA = 15.0

#: What a scan match is worth, as if from this many independent points of its
#: own residual's noise (at least ``_MATCH_SIGMA``), see :func:`match_info`.
_OWN_NOISE_POINTS = 35.0


def match_info(r: Any, noise: float = 0.0) -> FloatArray:
    """What a scan match is worth (its information, world frame).

    Measured on simulated logs with known poses (a sparse and a dense laser, 10 and 15 mm of
    range noise, an office and a building), a match's error is what ``_OWN_NOISE_POINTS`` points of
    its own residual's noise give: the noisier the laser, the more of the error is the local
    map's own (its walls are noisy points too), which a fixed noise did not see. A claim too
    strong makes good odometry look worse than it is: its noise scale is fitted against the
    matches' claims.

    ``noise``: the laser's own scatter about the walls (:func:`~mapkit.build._match.surface_noise`),
    below which a residual is not taken. Each point is paired with the nearest of the local
    map's points, themselves noisy, within 40 mm: the residuals read 14-16 mm whatever the
    laser's noise beyond 20 mm, and a 30 mm laser's matches claimed four times their worth. Exact
    odometry was then fitted 270 times worse than it is (76 mm RMS; docs/logs.md, round 22).
    """
    sigma = max(float(r.rms), noise, _MATCH_SIGMA)
    info: FloatArray = r.info(sigma=sigma, points=_OWN_NOISE_POINTS)
    return info


#: Mahalanobis distance of a match from odometry at which its weight halves.
_FUSE_ROBUST = 2.5


def _fuse(
    dv: FloatArray, scan_info: FloatArray, odo_info: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """How far to move the odometry prediction towards a scan match ``dv`` away from it, and what
    the match is worth (its information, down-weighted when it is wild; the pose graph's edge).

    The two are weighed by their information. A match that disagrees with odometry far beyond
    both noises (a feature seen for the first time caught on the wrong wall, a person) is
    down-weighted: Cauchy weights on the Mahalanobis distance, halved at ``_FUSE_ROBUST``.
    """
    both = np.linalg.inv(scan_info + np.eye(3) * 1e-9) + np.linalg.inv(odo_info)
    m2 = float(dv @ np.linalg.solve(both, dv))
    info = scan_info / (1.0 + m2 / _FUSE_ROBUST**2)
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


def _local(
    idx: range, est: FloatArray, pts: list[FloatArray], nrm: list[FloatArray]
) -> tuple[FloatArray, FloatArray]:
    parts = [_world(pts[k], nrm[k], est[k]) for k in idx]
    return _thinned([a for a, _ in parts], [b for _, b in parts], 40.0)


def _edge_info(world_info: FloatArray, pose_j: FloatArray) -> FloatArray:
    """A world-frame pose information turned into the frame of an edge's error (pose j)."""
    c, s = math.cos(pose_j[2]), math.sin(pose_j[2])
    M = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    info: FloatArray = M.T @ world_info @ M + np.eye(3) * 1e-9
    return info


def _close(
    i: int,
    j: int,
    est: FloatArray,
    src: list[FloatArray],
    pts: list[FloatArray],
    nrm: list[FloatArray],
    path: FloatArray,
    graph: PoseGraph,
    stats: dict[str, Any],
    *,
    tagged: bool,
    reach: tuple[FloatArray, FloatArray] | None = None,
    laser_noise: float = 0.0,
) -> bool:
    """Match scan i (with its predecessors) against the map around old scan j; add an edge.

    A ``loop:`` tag claims the robot is back where it was at the tag's start: the match then
    starts there and the claim holds the directions the scans cannot fix. A detected revisit
    starts from the current estimate, which also holds the unconstrained directions.

    ``laser_noise``: the laser's own scatter about the walls (mm,
    :func:`~mapkit.build._match.surface_noise`): a noisier laser's match allows more residual
    and claims more noise (:func:`~mapkit.build._match.widened`), but reaches no further. On 144
    logs of 30 and 40 mm lasers a wider reach let wrong closures through (an office's slipping
    robot: 14.3 to 131.2 mm RMS), and so did a lower bar on the share of points within reach
    (another office log: 8.0 to 169.6; docs/logs.md, round 23).
    """
    from scipy.spatial import cKDTree

    widen = widened(laser_noise)
    n = len(est)
    lo = j
    while lo > 0 and path[j] - path[lo - 1] < 3000.0 and j - lo < 15:
        lo -= 1
    hi = j
    while (
        hi < n - 1
        and hi < i
        and path[hi + 1] - path[j] < 3000.0
        and hi - j < 15
        and path[i] - path[hi + 1] > 5000.0
    ):
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
    r = icp(
        source, tree, tgt, tn, guess, schedule=sched, max_iter=20, prior=guess, prior_info=claim
    )
    good = _good_closure(r, tagged, widen, _share(r, source, tree, tgt, tn, widen))
    if not good:
        sub = source[:: max(1, len(source) // 150)]
        cp, score = correlative(sub, tgt, guess, xy_window=win, th_window=thw, cell=50.0)
        if score >= 0.25:
            r = icp(
                source,
                tree,
                tgt,
                tn,
                cp,
                schedule=(200.0, 100.0, 60.0),
                max_iter=20,
                prior=guess,
                prior_info=claim,
            )
            good = _good_closure(r, tagged, widen, _share(r, source, tree, tgt, tn, widen))
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
    if reach is not None and not _within_reach(reach, i, j, path, corr, dth):
        stats["closures_refused"] = stats.get("closures_refused", 0) + 1
        return False
    info = r.info(sigma=_CLOSURE_SIGMA * widen) + (claim if tagged else 0.0)
    graph.add(j, i, between(est[j], r.pose), _edge_info(info, r.pose), robust=True)
    stats["corrections_mm"].append(corr)
    stats["closures"].append((j, i))
    stats["corrections_deg"].append(math.degrees(dth))
    stats["_moved"] = corr > 80.0 or dth > math.radians(0.8)
    return True


#: A closure moves the estimate by at most this many standard deviations of the odometry
#: between its two ends (as the log's odometry noise scale has it) ...
_REACH_SIGMAS = 5.0

#: ... plus this much (mm, radians): matches have noise of their own.
_REACH_MM = 200.0
_REACH_TURN = math.radians(1.0)


def _within_reach(
    reach: tuple[FloatArray, FloatArray],
    i: int,
    j: int,
    path: FloatArray,
    corr: float,
    dth: float,
) -> bool:
    """Whether a closure's correction (``corr`` mm, ``dth`` radians) is one the odometry
    between scans j and i can have made.

    ``reach`` holds the running sums along the log of each step's odometry variance (position,
    mm squared, and heading, radians squared; the noise the model gives it). A heading error
    turns what follows: over a path of length L it moves the end by about its size times
    ``L / sqrt(3)``. Good odometry (a simulator's, a well-kept robot's) cannot be metres out
    after 45 m: a match that says so is caught on the wrong walls (a corridor like another).
    """
    cum_xy, cum_th = reach
    var_th = float(cum_th[i] - cum_th[j])
    length = float(path[i] - path[j])
    var_xy = float(cum_xy[i] - cum_xy[j]) + var_th * length * length / 3.0
    return (
        corr <= _REACH_SIGMAS * math.sqrt(var_xy) + _REACH_MM
        and dth <= _REACH_SIGMAS * math.sqrt(var_th) + _REACH_TURN
    )


#: Reach (mm) within which a closure's point looks for the map point whose wall it lies on, when
#: its share is counted on the walls' planes (see :func:`_share`).
_PLANE_NEAR = 200.0

#: Distance (mm) from that wall within which the point is on it (times the laser's widening).
_ON_PLANE = 60.0


def _share(
    r: Any, source: FloatArray, tree: Any, tgt: FloatArray, tn: FloatArray, widen: float
) -> float:
    """The share of a closure's ``source`` points, placed at its match ``r``, that found the map
    (``tgt``, its KD-tree ``tree`` and normals ``tn``): those within the match's last reach of a
    map point (``r.inliers``) or, for a laser noisier than the bars were set for (``widen`` over
    1, :func:`~mapkit.build._match.widened`), those on a wall's plane, if more.

    A noisy laser's points and the map's scatter about the walls both, and along far walls they
    lie apart (a 181-beam laser's 175 mm at 10 m): a point on a wall is often further than the
    last reach from any map point. The showroom's logs with a 30 mm laser closed no loop at all
    (every share 0.13-0.45, against 0.45). On the walls' planes (within ``_ON_PLANE`` of the
    plane of a map point within ``_PLANE_NEAR``), on 144 logs of 30 and 40 mm lasers, the logs
    over 100 mm RMS went from 5 to none and those meeting every target from 119 to 122
    (docs/logs.md, round 25). With a 10-15 mm laser the points' share holds: on the planes, 2
    more logs of the real maps' 270 missed (round 24)."""
    share = float(r.inliers)
    if widen <= 1.0 or not r.ok or len(source) == 0:
        return share
    p = transform(source, r.pose)
    d, idx = tree.query(p, k=1, distance_upper_bound=_PLANE_NEAR)
    found = np.isfinite(d)
    if not found.any():
        return share
    off = np.abs(np.sum((p[found] - tgt[idx[found]]) * tn[idx[found]], axis=1))
    return max(share, float(np.count_nonzero(off < _ON_PLANE * widen)) / len(p))


def _good_closure(r: Any, tagged: bool, widen: float = 1.0, share: float | None = None) -> bool:
    """Whether a closure's match ``r`` is one to go by: it converged, its residual is under 35
    mm (``widen`` times that for a noisy laser), it has points enough, and more than a bar of
    them found the map (``share``, default ``r.inliers``; see :func:`_share`): 0.35 of them for
    a ``loop:`` tag's, which starts where the tag says, 0.45 for a revisit's."""
    if tagged:
        return bool(r.holds(0.35, 35.0, widen, share) and r.n > 60)
    return bool(r.holds(0.45, 35.0, widen, share) and r.n > 80)
