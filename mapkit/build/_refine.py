"""Global refinement: every scan matched once more against the map of all scans.

After loop closing the trajectory is right in the large, but where the robot passed a place
more than once each pass still sits a few mm to a few cm from the others (each was registered
against its own local map, and the closures only pinned a few scans of it): the walls come out
doubled or blurred. Here every scan is matched against the scans of the *other* passes (the
scans more than a few metres of path away), and a pose graph holds each scan to its match (in
the directions the match fixes) and to its neighbours by the relative poses the registration
found. The passes meet half way; where a place was seen once there is nothing to match, and
nothing moves.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable
from typing import Any, NamedTuple

import numpy as np

from mapkit.build._common import FloatArray, _world
from mapkit.build._graph import PoseGraph, between, plus_variance, sigma_info, wrap
from mapkit.build._lag import calm
from mapkit.build._loops import _CAUCHY, _MATCH_POINTS, _MATCH_SIGMA, _edge_info
from mapkit.build._match import MatchResult, icp, local_planes, widened

#: Scans within this much path (mm) of a scan are its own pass: not matched against.
_OWN_PASS = 5000.0

#: What the registration's relative pose of neighbouring scans is worth (mm, mm, radians).
_STEP_SIGMA = (3.0, 3.0, math.radians(0.07))

#: Most the first scan's match may turn the map about the start (radians): beyond it the first
#: scan and the map disagree by more than the first scan's match can err (0.06-0.16 degrees,
#: one standard deviation, on real ARIA maps), and one of them is wrong (a match on the wrong
#: walls). At 0.15 degrees it also refused the first scan where the start's turn on the spot had
#: gone 0.2 degrees wrong by odometry (two of its standard deviations, docs/logs.md, round 17).
#: The start's own odometry widens it (:func:`_anchor_turn`): a robot that slips in its turns
#: turned a map 0.6 degrees in its first turn on the spot (round 21).
_ANCHOR_TURN = math.radians(0.5)

#: Path (mm) from the start whose odometry widens that bar: the start's first metre, as
#: registration takes it (``_register._START_PATH``, matched with all its points).
_START = 1000.0

#: Points of the other passes each local plane the first scan is matched against is fitted to.
_ANCHOR_PLANE_POINTS = 8

#: Neighbours looked at per point to find one of another pass.
_K = 8

#: Path (mm) along which neighbouring scans' matches err together (see :func:`refine`).
_SHARED_PATH = 1000.0

#: What a turn counts for, as path: this much of the distance its beams' hits slide along the
#: walls (the scans' median range times the angle turned).
_TURN_SHARE = 0.3

#: Step (radians per mm: 0.01 deg/m) of the search for a drift the calibration missed.
_DRIFT_STEP = math.radians(0.01) / 1000.0

#: Largest such drift taken (radians per mm: 0.2 deg/m).
_DRIFT_MAX = math.radians(0.2) / 1000.0

#: Standard errors by which that drift must differ from none to be taken.
_DRIFT_SIGNIFICANT = 3.0


class Refined(NamedTuple):
    """What :func:`refine` found."""

    #: The new ``(N, 3)`` poses (radians).
    poses: FloatArray
    #: How many scans matched in the last round.
    matched: int
    #: The heading drift (radians per mm) the odometry still had and the matches showed, taken
    #: out of the odometry's steps (0.0: none, or none to speak of; see :func:`_drift_left`).
    drift: float


class _OtherPasses:
    """A KD-tree of all scans' points that answers, for scan i, only with points of other passes
    (scans more than ``_OWN_PASS`` of path away): the interface of ``cKDTree.query`` that
    :func:`~mapkit.build._match.icp` uses."""

    def __init__(self, pts: FloatArray, owner: np.ndarray[Any, Any], path: FloatArray) -> None:
        from scipy.spatial import cKDTree

        self.tree = cKDTree(pts, balanced_tree=False, compact_nodes=False)
        self.owner_path = path[owner]
        self.n = len(pts)
        self.at = 0.0

    def of_other_passes(self, idx: Any = slice(None)) -> np.ndarray[Any, Any]:
        """Whether the points ``idx`` (default: all) are of another pass than the scan at
        ``at``."""
        other: np.ndarray[Any, Any] = np.abs(self.owner_path[idx] - self.at) > _OWN_PASS
        return other

    def query(
        self, p: FloatArray, k: int = 1, distance_upper_bound: float = np.inf, eps: float = 0.0
    ) -> tuple[FloatArray, np.ndarray[Any, Any]]:
        del k
        d, idx = self.tree.query(p, k=_K, distance_upper_bound=distance_upper_bound, eps=eps)
        found = idx < self.n
        other = found.copy()
        other[found] = self.of_other_passes(idx[found])
        first = np.argmax(other, axis=1)
        rows = np.arange(len(p))
        has = other[rows, first]
        d_out = np.where(has, d[rows, first], np.inf)
        i_out = np.where(has, idx[rows, first], self.n)
        return d_out, i_out


def match(
    src: FloatArray,
    tree: Any,
    tgt: FloatArray,
    tn: FloatArray,
    pose: FloatArray,
    widen: float = 1.0,
) -> MatchResult | None:
    """A scan's match from ``pose`` as the refinement matches: against ``tree``, the other passes
    (:class:`_OtherPasses` set to the scan's place on the path) or any KD-tree of ``tgt`` (points,
    with ``tn`` their normals). None when it found too little. ``widen``: its last reach and
    residual bar that many times further (a noisy laser's, :func:`~mapkit.build._match.widened`).
    """
    # Down to a 20 mm reach: matched at the true poses, a match that stopped at 40 mm was 5-30 %
    # further off in heading (docs/logs.md, round 11).
    r = icp(
        src, tree, tgt, tn, pose, schedule=(80.0, 40.0, 20.0 * widen), max_iter=20, cauchy=_CAUCHY
    )
    return r if r.holds(0.3, 30.0, widen) else None


def claim(r: MatchResult, widen: float = 1.0) -> FloatArray:
    """What a refinement match ``r`` claims (its information, world frame) for a laser widened
    ``widen`` times (:func:`~mapkit.build._match.widened`): ``_MATCH_POINTS`` points of
    ``_MATCH_SIGMA`` mm, times the widening *squared*.

    A match's heading errs with the laser's scatter twice over: its own points scatter, and so
    do the other passes' points it is matched against. Matched at the true poses, a 10-15 mm
    laser's matches erred 0.060 degrees RMS where they claimed 0.049; with the claim widened
    once, a 30 mm laser's (23-25 mm about the walls) erred 0.142 where they claimed 0.080, and a
    40 mm laser's 0.180 where they claimed 0.086. Widened twice they claim 0.116 and 0.154: each
    laser's matches err a fifth more than they claim, as the quiet laser's do. Claimed at half
    their error, a noisy laser's matches outvoted the odometry and registration's steps with
    errors of their own (docs/logs.md, round 26)."""
    info: FloatArray = r.info(sigma=_MATCH_SIGMA * widen * widen, points=_MATCH_POINTS)
    return info


def anchor_match(
    first: FloatArray,
    others: _OtherPasses,
    tgt: FloatArray,
    tn: FloatArray,
    pose: FloatArray,
    widen: float = 1.0,
) -> MatchResult | None:
    """The first scan's match from ``pose``: as :func:`match`, against the other passes' points
    within its reach smoothed into local planes (:func:`~mapkit.build._match.local_planes`, over
    ``_ANCHOR_PLANE_POINTS`` each). It alone places the map around the start, and there the other
    passes' range noise is most of its error: matched at the true poses of 72 logs on real ARIA
    maps, the first scan erred 0.113 degrees RMS against their points and 0.086 against their
    planes (docs/logs.md, round 13)."""
    from scipy.spatial import cKDTree

    reach = float(np.hypot(first[:, 0], first[:, 1]).max()) + 1000.0 if len(first) else 0.0
    near = others.of_other_passes() & (np.hypot(tgt[:, 0] - pose[0], tgt[:, 1] - pose[1]) < reach)
    if np.count_nonzero(near) < _ANCHOR_PLANE_POINTS:
        return None
    planes, normals = local_planes(tgt[near], tn[near], _ANCHOR_PLANE_POINTS)
    return match(first, cKDTree(planes), planes, normals, pose, widen)


def refine(
    est: FloatArray,
    path: FloatArray,
    src: list[FloatArray],
    pts: list[FloatArray],
    nrm: list[FloatArray],
    *,
    first: FloatArray | None = None,
    rounds: int = 1,
    odometry: tuple[FloatArray, FloatArray] | None = None,
    odometry_from: np.ndarray[Any, Any] | None = None,
    unsure: FloatArray | None = None,
    laser_noise: float = 0.0,
) -> Refined:
    """The poses after ``rounds`` of matching every scan against the other passes' scans.

    ``first``: the first scan's points to match (default ``pts[0]``): it alone places the map
    around the start, so it is matched with all it has, against the other passes' planes
    (:func:`anchor_match`).

    ``odometry``: the ``(N - 1, 3)`` odometry steps between neighbouring scans and their
    ``(N - 1, 3, 3)`` information. The neighbours are held by them too: where odometry is
    better than a scan's match (a simulator's, a well-kept robot's), the matches' noise does
    not bend the chain.

    ``odometry_from``: the ``(N - 1,)`` scans the odometry steps start from (default: the scan
    before each; sweeps each off their pose by a part of their own are not chained, see
    :func:`mapkit.build._lag.bases`, and are neither matched nor matched against, see
    :func:`_calm`).

    ``laser_noise``: the laser's own scatter about the walls (mm,
    :func:`~mapkit.build._match.surface_noise`): a noisier laser's matches reach further, allow
    more residual (:func:`~mapkit.build._match.widened`) and claim more noise (:func:`claim`).

    With ``odometry``, a heading drift the calibration missed is looked for too (see
    :func:`_drift_left`) and taken out of the odometry's steps when the matches show one.
    """
    n = len(est)
    x = est.copy()
    matched = 0
    drift = 0.0
    step_info = sigma_info(*_STEP_SIGMA)
    widen = widened(laser_noise)
    # Node n is the map's frame: the matches place the scans in it. It is free, and the first
    # scan (node 0, held fixed: the map's origin is where the robot started) is matched into it
    # like every other scan, so that where the map sits around the start is the first scan's
    # own view too, not only the chain of matches that led away from it.
    frame = n
    anchor = pts[0] if first is None else first
    # Scans close along the path see the same walls against the same map: their matches err
    # together, not independently (a log that scans every 150 mm is not six times as sure of a
    # wall as one that scans every metre). Each match counts for its scan's share of
    # ``_SHARED_PATH``; counted in full, a dense log's matches outvoted its odometry and bent the
    # chain with their shared errors.
    # A turn brings a view of its own too, though less than a drive does: the beams' hits slide
    # along the walls by their range times the angle turned, and a scan turned on the spot is
    # counted for ``_TURN_SHARE`` of that (counted as no path at all, the scans of a turn on the
    # spot, often all a log has of its start, were not heard).
    ranges = np.hypot(*np.concatenate(pts).T) if n else np.zeros(0)
    reach = _TURN_SHARE * float(np.median(ranges)) if len(ranges) else 0.0
    along = path + reach * np.concatenate(([0.0], np.cumsum(np.abs(wrap(np.diff(est[:, 2]))))))
    ahead = np.append(along[1:], along[-1])
    behind = np.insert(along[:-1], 0, along[0])
    share = np.clip((ahead - behind) / 2.0, 1.0, _SHARED_PATH) / _SHARED_PATH
    # How far each odometry step goes (a drift is taken out in proportion).
    lengths = [] if odometry is None else [math.hypot(s[0], s[1]) for s in odometry[0]]
    calm = _calm(odometry_from, n)
    anchor_turn = _anchor_turn(path, odometry, calm)
    for _ in range(rounds):
        parts = [
            _world(p, q, e) if keep else (p[:0], q[:0])
            for p, q, e, keep in zip(pts, nrm, x, calm, strict=True)
        ]
        sizes = np.array([len(a) for a, _ in parts])
        tgt = np.concatenate([a for a, _ in parts])
        tn = np.concatenate([b for _, b in parts])
        if len(tgt) < 50:
            break
        owner = np.repeat(np.arange(n), sizes)
        others = _OtherPasses(tgt, owner, path)
        found: list[tuple[int, FloatArray, FloatArray]] = []
        for i in range(n):
            if not calm[i]:
                continue
            others.at = float(path[i])
            r = (
                match(src[i], others, tgt, tn, x[i], widen)
                if i
                else anchor_match(anchor, others, tgt, tn, x[0], widen)
            )
            if r is None:
                continue
            if math.hypot(*(r.pose[:2] - x[i, :2])) > 150.0:
                continue
            if i == 0 and abs(wrap(r.pose[2] - x[0, 2])) > anchor_turn:
                continue  # the first scan and the map disagree: one of them is wrong
            info = claim(r, widen) * share[i]
            # The scan's place in the map (whose frame is that of x, node 0's estimate).
            found.append((i, between(x[0], r.pose), _edge_info(info, r.pose)))
        matched = len(found)
        if not matched:
            break

        # The registration's steps, the same in every graph of the round.
        steps = [between(a, b) for a, b in itertools.pairwise(x)]

        def graph(
            drift: float, steps: list[FloatArray] = steps, found: list[Any] = found
        ) -> PoseGraph:
            """The round's pose graph, with ``drift`` taken out of the odometry's steps."""
            g = PoseGraph()
            for i in range(1, n):
                g.add(
                    i - 1,
                    i,
                    steps[i - 1],
                    step_info if unsure is None else plus_variance(step_info, unsure[i - 1]),
                )
                if odometry is not None:
                    step = odometry[0][i - 1].copy()
                    step[2] += drift * lengths[i - 1]
                    a = i - 1 if odometry_from is None else int(odometry_from[i - 1])
                    g.add(a, i, step, odometry[1][i - 1])
            for i, z, info in found:
                g.add(frame, i, z, info, robust=True)
            return g

        start = np.vstack([x, x[:1]])
        if odometry is None:
            drift, solved = 0.0, graph(0.0).optimize(start, iterations=5)
        else:
            drift, solved = _drift_left(graph, start)
            if drift:
                solved = graph(drift).optimize(start, iterations=5)
        x = solved[:n]
    return Refined(x, matched, drift)


def _anchor_turn(
    path: FloatArray,
    odometry: tuple[FloatArray, FloatArray] | None,
    calm: np.ndarray[Any, Any],
) -> float:
    """The most the first scan's match may turn the map about the start (radians):
    ``_ANCHOR_TURN``, and three standard deviations more of what the odometry over the start's
    first ``_START`` mm of path may have turned it by (its steps to the calm scans there: each
    turning sweep's own part of a lag that varies does not add up). A robot that slips in its
    turns may turn the map by more than ``_ANCHOR_TURN`` in its first turn on the spot alone."""
    if odometry is None or len(path) < 2:
        return _ANCHOR_TURN
    at_start = (path[1:] <= _START) & calm[1:]
    var = float(np.sum(1.0 / odometry[1][at_start, 2, 2]))
    return _ANCHOR_TURN + 3.0 * math.sqrt(var)


def _calm(odometry_from: np.ndarray[Any, Any] | None, n: int) -> np.ndarray[Any, Any]:
    """Whether each of ``n`` scans is calm: the odometry of the scan after it starts from it
    (``odometry_from``, see :func:`mapkit.build._lag.bases`; None: every scan is). The others
    are sweeps each off their pose by their own part of a lag that varies.

    The refinement neither matches them nor matches against them (registration keeps them out
    of its local maps too). Their poses are registration's within a degree or two (a turn rate
    times their part of the lag), and a match from there stops in a minimum near where it
    started: on the first turn on the spot of AMROffice ``jitter`` 3 the matches of three of
    them erred 0.3-1.0 degrees where they claimed 0.07-0.10. The odometry holds such a scan only
    as loosely as its part of the lag (0.8-1.2 degrees there), so nothing outvoted its match,
    and together they turned the whole map about the start by 0.4 degrees (docs/logs.md, round
    18). Left to the registration's steps and the odometry from the calm scans around them, they
    follow the calm scans."""
    if odometry_from is None:
        return np.ones(n, dtype=bool)
    return calm(odometry_from)


def _drift_left(graph: Callable[[float], PoseGraph], start: FloatArray) -> tuple[float, FloatArray]:
    """A heading drift (radians per mm) still in the odometry's steps, as the matches show it,
    and the graph solved with none taken out (what the refinement keeps when there is none).

    The calibration measures drift scan to scan over two metres, where a small one (0.02 deg/m)
    is lost in the matches' noise; odometry that is otherwise good then holds the passes apart,
    and the refinement cannot bring them together. Here the whole log is the baseline: the
    graph's cost (chi-square, robust where its edges are) is found with a drift of
    ``-_DRIFT_STEP``, none and ``+_DRIFT_STEP`` taken out of every step, and a parabola through
    the three gives the drift that fits best and its standard error. It is taken when it differs
    from none by more than ``_DRIFT_SIGNIFICANT`` standard errors.
    """
    h = _DRIFT_STEP
    costs = []
    solved = start
    for d in (-h, 0.0, h):
        g = graph(d)
        x = g.optimize(start, iterations=5)
        costs.append(g.cost(x))
        if d == 0.0:
            solved = x
    curve = (costs[0] + costs[2] - 2.0 * costs[1]) / (2.0 * h * h)
    if not curve > 0.0:
        return 0.0, solved
    best = -(costs[2] - costs[0]) / (2.0 * h) / (2.0 * curve)
    if abs(best) <= _DRIFT_SIGNIFICANT / math.sqrt(curve):
        return 0.0, solved
    return float(np.clip(best, -_DRIFT_MAX, _DRIFT_MAX)), solved
