"""How much older each sweep is than the pose logged with it, and the poses the sweeps were
really taken from.

ARIA stamps a simulated laser's sweep with the robot's pose when the sweep's first packet
arrives (``ArSimulatedLaser``), and a real laser's with the latency it was told: a sweep can be
tens of milliseconds older (or newer) than the ``robot:`` pose logged with it. While the robot
turns, every sweep is then turned by the turn rate times that lag against its pose. Steps
within a turn do not show it (both scans are turned alike), but the steps into and out of a
turn do: the scans' match and the odometry differ there by the lag times the change of turn
rate. Left in, those steps disagree by a degree or two with odometry that is otherwise good to
hundredths, and the map is bent at every turn (a 50 ms lag at 40 deg/s: 2 degrees).

:func:`measure` matches the scans on either side of every change of turn rate directly (scan to
scan, from the odometry's guess, turned by the lag most of the sharpest of those steps match
from: a long lag turns a sweep by degrees) and fits the lag (and the odometry's turn scale,
which also shows in those steps) to the heading differences by robust least squares;
:func:`taken_from` moves each pose back along the robot's motion (the ``velocities:`` logged
with it) by the lag.

The lag need not be the same for every sweep (a packet arrives early or late in the robot's
cycle). Its spread shows in the same steps: they disagree more than the matches of calm steps
(straight drives and stops, where no lag shows) by the turn rates times each sweep's own part.
When :func:`measure` finds one, each sweep is taken as off its pose by its speed and turn rate
times that spread (:func:`sweep_variance`), and odometry is not chained through such sweeps: it
is taken from the last calm sweep to each of them and across them to the next calm one
(:func:`bases`), where it is as good as the robot's.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Iterator
from typing import Any, NamedTuple

import numpy as np

from mapkit.build._common import FloatArray
from mapkit.build._graph import between, wrap
from mapkit.build._loops import _CAUCHY
from mapkit.build._match import MatchResult, icp, scan_normals, scatter, widened
from mapkit.model.scan import LaserScan

#: Least change of turn rate (radians per second) between two scans for their match to count.
_MIN_CHANGE = math.radians(10.0)

#: Fewest such pairs of scans that a lag is measured from.
_MIN_PAIRS = 8

#: Most pairs matched (evenly spread over the log).
_MAX_PAIRS = 400

#: Standard errors by which the lag must differ from none to be taken.
_SIGNIFICANT = 4.0

#: A lag that turns a sweep by less than this (radians) at the log's turn rate is left alone.
_NEGLIGIBLE = math.radians(0.1)

#: Largest lag taken (seconds).
_LARGEST = 0.5

#: Most calm pairs matched (straight drives and stops: the matches' own noise).
_MAX_CALM = 100

#: Least spread of the lag taken (s), and least it must turn a sweep by at the log's turn rate
#: (radians). Logs without one fit up to 6 ms, a robot slipping 2-5 % in its turns up to 10 ms
#: (its turns' own errors look alike), and taken there it costs.
_JITTER_LEAST = 0.012
_JITTER_NEGLIGIBLE = math.radians(0.4)

#: Least scale (radians) of the fit's residuals.
_LEAST_SIGMA = math.radians(0.01)

#: The median of chi-square with one degree of freedom.
_CHI2_1_MEDIAN = 0.4549

#: Scans further apart than this (mm, radians) are not matched directly.
_NEAR = (1000.0, math.radians(45.0))


class Lag(NamedTuple):
    """What :func:`measure` found."""

    #: How much older (s) each sweep is than its pose: the lag taken (0.0 when none was).
    seconds: float
    #: The fitted lag (s) and its standard error, taken or not (nan: not measured).
    fitted: float
    error: float
    #: Pairs of scans that it was measured from.
    pairs: int
    #: How much the lag varies from sweep to sweep (s, a standard deviation): the spread taken
    #: (0.0 when none was) and the fitted one (nan: not measured).
    jitter: float = 0.0
    jitter_fitted: float = math.nan


def velocities(scans: list[LaserScan]) -> FloatArray | None:
    """The ``(N, 2)`` forward speed (mm/s) and turn rate (radians per second) logged with each
    scan; None when a scan has none."""
    out = np.empty((len(scans), 2))
    for i, s in enumerate(scans):
        v = s.velocities
        if v is None or not (math.isfinite(v[0]) and math.isfinite(v[1])):
            return None
        out[i] = v[0], math.radians(v[1])
    return out


def measure(
    odo: FloatArray, vel: FloatArray, pts: list[FloatArray], laser_noise: float = 0.0
) -> Lag:
    """The lag of the sweeps behind the poses ``odo`` (``(N, 3)``, radians) logged with
    velocities ``vel`` (:func:`velocities`), from the scans' points ``pts`` (robot frame, in
    beam order); ``laser_noise``: the laser's scatter about the walls (mm,
    :func:`~mapkit.build._match.surface_noise`: a noisier laser's matches reach further)."""
    if len(odo) < 2:
        return Lag(0.0, math.nan, math.nan, 0)
    change = np.diff(vel[:, 1])
    rel = between(odo[:-1], odo[1:])
    near = (np.hypot(rel[:, 0], rel[:, 1]) < _NEAR[0]) & (np.abs(rel[:, 2]) < _NEAR[1])
    cand = np.flatnonzero((np.abs(change) >= _MIN_CHANGE) & near)
    if len(cand) < _MIN_PAIRS:
        return Lag(0.0, math.nan, math.nan, len(cand))
    if len(cand) > _MAX_PAIRS:
        cand = cand[np.linspace(0, len(cand) - 1, _MAX_PAIRS).round().astype(int)]
    # Matched from the odometry turned by the lag the sharpest changes of turn rate match from
    # best (none, unless another lets clearly more of them match): a long lag turns a sweep by
    # degrees, and matches started that far off fail.
    widen = widened(laser_noise)
    ready = list(_prepared(pts, cand))
    start = _start(ready, cand, rel, change, widen)
    rows, seen, rates = [], [], []
    for k, turn in _matched(ready, rel, -start * change, widen):
        rows.append((rel[k][2], -change[k]))
        seen.append(turn)
        rates.append(vel[k, 1] ** 2 + vel[k + 1, 1] ** 2)
    if len(rows) < _MIN_PAIRS:
        return Lag(0.0, math.nan, math.nan, len(rows))
    a = np.array(rows)
    e = np.array(seen)
    coef, error, res = _robust_fit(a, e)
    lag = float(coef[1])
    turning = np.abs(vel[:, 1][vel[:, 1] != 0.0])
    rate = float(np.percentile(turning, 90)) if len(turning) else 0.0
    # The calm steps' matches (a straight drive's or a stop's, where no lag shows): their
    # scatter is the matches' own noise.
    calm = np.flatnonzero((vel[:-1, 1] == 0.0) & (vel[1:, 1] == 0.0) & near)
    if len(calm) > _MAX_CALM:
        calm = calm[np.linspace(0, len(calm) - 1, _MAX_CALM).round().astype(int)]
    quiet = np.array(
        [turn - coef[0] * rel[k][2] for k, turn in _matched(_prepared(pts, calm), rel, None, widen)]
    )
    noise = scatter(quiet) if len(quiet) >= _MIN_PAIRS else math.nan
    # The steps into and out of turns match no better than calm ones: where a few of them
    # agree more closely than that by chance, the lag's error is from the calm steps' noise
    # (a showroom's log without a lag: its 17 steps scattered 0.11 degrees where 81 calm ones
    # scattered 0.23, and a lag of -3.8 +- 0.8 ms was taken).
    if noise > 0.0:
        error *= max(1.0, noise / max(scatter(res), _LEAST_SIGMA))
    # How much the lag varies: the steps into and out of turns disagree more than the calm
    # steps' matches do by the turn rates times the sweeps' own parts of the lag.
    jitter = math.nan if math.isnan(noise) else _spread(res, np.array(rates), noise)
    vary = jitter > _JITTER_LEAST and jitter * rate > _JITTER_NEGLIGIBLE
    # A spread is measured about the fitted lag: taken, it is taken with that lag (a short
    # tour's 35 +- 12 ms fell short of its own bar, and its spread was taken about none).
    plausible = abs(lag) * rate > _NEGLIGIBLE and abs(lag) <= _LARGEST
    taken = plausible and (abs(lag) > _SIGNIFICANT * error or vary)
    return Lag(
        lag if taken else 0.0,
        lag,
        error,
        len(rows),
        min(jitter, _LARGEST) if vary else 0.0,
        jitter,
    )


def _start(
    ready: list[_Pair],
    cand: np.ndarray[Any, Any],
    rel: FloatArray,
    change: FloatArray,
    widen: float = 1.0,
) -> float:
    """The lag (s) whose turn the pairs into and out of turns ``cand`` (``ready``: those of
    them :func:`_prepared` to match) are matched from: the one of a grid up to ``_LARGEST``
    either way (steps that turn the sharpest of them by ``_START_STEP``) from which the most of
    their ``_START_PAIRS`` sharpest match, when that is ``_START_MORE`` more than match from the
    odometry itself; else none. ``widen``: as :func:`_kept` takes it.

    A sweep that lags by 120 ms is turned 4.8 degrees at 40 deg/s: started from the odometry,
    matches of a showroom's and a triangular hall's steps into and out of turns failed (7 of
    22 and 7 of 13 kept) and no lag was measured. At 40 ms they held (19 and 8)."""
    sharp = set(cand[np.argsort(-np.abs(change[cand]), kind="stable")[:_START_PAIRS]].tolist())
    ready = [pair for pair in ready if pair[0] in sharp]
    turn = -change[[k for k, *_ in ready]]

    def matching(lag: float) -> int:
        return sum(
            _kept(one, rel[one[0]] + (0.0, 0.0, lag * t), widen) is not None
            for one, t in zip(ready, turn, strict=True)
        )

    best, most = 0.0, matching(0.0)
    bar = most + _START_MORE  # what another lag must let match
    if bar > len(ready):
        return 0.0  # nothing to gain
    step = _START_STEP / float(np.max(np.abs(turn)))
    for lag in np.arange(step, _LARGEST + step / 2.0, step):
        for signed in (float(lag), -float(lag)):
            found = matching(signed)
            if found > most and found >= bar:
                best, most = signed, found
                if most == len(ready):
                    return best  # all match: none can do better
    return best


#: Pairs into and out of turns (the sharpest changes of turn rate) :func:`_start` matches.
_START_PAIRS = 16

#: Most that one of :func:`_start`'s steps turns a pair's start (radians): within the reach of a
#: match's first correspondences (150 mm) at 8 m.
_START_STEP = math.radians(1.0)

#: How many more of :func:`_start`'s pairs a lag must let match than none does to be started from.
_START_MORE = 2

#: A pair of scans prepared to match: ``(k, the later scan's points, KD-tree of the earlier
#: scan's, those points, their normals)``.
_Pair = tuple[int, FloatArray, Any, FloatArray, FloatArray]


def _prepared(pts: list[FloatArray], pairs: np.ndarray[Any, Any]) -> Iterator[_Pair]:
    """Each pair ``k`` (scan ``k`` and ``k + 1``) of ``pairs`` with points enough to match.

    Like with like: only the points on walls (with a normal of their own) are matched, as only
    those are matched against. In a wide hall most beams end far apart or on posts and shelving,
    and the rest, counted as misses, failed the inlier bar of matches that were right (a
    showroom's log: 3 pairs of 21 kept, no lag found)."""
    from scipy.spatial import cKDTree

    for k in pairs:
        nrm = scan_normals(pts[k])
        good = np.isfinite(nrm[:, 0])
        if good.sum() < 20:
            continue
        own = pts[k + 1][np.isfinite(scan_normals(pts[k + 1])[:, 0])]
        if len(own) < 20:
            continue
        tgt = pts[k][good]
        yield int(k), own[:: max(1, len(own) // 120)], cKDTree(tgt), tgt, nrm[good]


def _kept(pair: _Pair, guess: FloatArray, widen: float = 1.0) -> MatchResult | None:
    """The pair's match from ``guess`` (the later scan's pose in the earlier's frame), when it
    matches well; ``widen``: its last reach and residual bar that many times further (a noisy
    laser's, :func:`~mapkit.build._match.widened`)."""
    _, src, tree, tgt, nrm = pair
    r = icp(src, tree, tgt, nrm, guess, schedule=(150.0, 60.0, 30.0 * widen), cauchy=_CAUCHY)
    return r if r.holds(0.3, 30.0, widen) else None


def _matched(
    pairs: Iterable[_Pair],
    rel: FloatArray,
    ahead: FloatArray | None = None,
    widen: float = 1.0,
) -> Iterator[tuple[int, float]]:
    """Each of the ``pairs`` (:func:`_prepared`) that matches well, as ``k`` (scan ``k`` and
    ``k + 1``) and how much more the match turns than the odometry (``rel``: the odometry's
    steps); ``ahead``: how much more (radians) each step's match starts turned than the
    odometry (None: none); ``widen``: as :func:`_kept` takes it."""
    for pair in pairs:
        k = pair[0]
        guess = rel[k] if ahead is None else rel[k] + (0.0, 0.0, ahead[k])
        r = _kept(pair, guess, widen)
        if r is not None:
            yield k, float(wrap(r.pose[2] - rel[k][2]))


def _spread(res: FloatArray, rates: FloatArray, calm: float) -> float:
    """The spread (s, a standard deviation) of the sweeps' lags that makes the residuals ``res``
    of the steps into and out of turns (``rates``: the sum of both sweeps' squared turn rates)
    as large as chance gives beside the calm steps' noise ``calm`` (radians): the median of
    ``res ** 2 / (calm ** 2 + rates * spread ** 2)`` is chi-square's with one degree of freedom."""

    def excess(spread: float) -> float:
        return float(np.median(res**2 / (calm**2 + rates * spread**2))) - _CHI2_1_MEDIAN

    if not calm > 0.0 or excess(0.0) <= 0.0:
        return 0.0
    lo, hi = 0.0, _LARGEST
    for _ in range(40):
        mid = (lo + hi) / 2.0
        lo, hi = (mid, hi) if excess(mid) > 0.0 else (lo, mid)
    return (lo + hi) / 2.0


def _robust_fit(a: FloatArray, e: FloatArray) -> tuple[FloatArray, float, FloatArray]:
    """The coefficients ``(scale, lag)`` of ``e ~ a @ (scale, lag)`` fitted with Cauchy weights
    (scale from the residuals' median absolute deviation), the lag's standard error and the
    residuals."""
    w: FloatArray = np.ones(len(e))
    coef: FloatArray = np.zeros(2)
    sigma = 1.0
    for _ in range(10):
        sw = np.sqrt(w)
        coef = np.asarray(np.linalg.lstsq(a * sw[:, None], e * sw, rcond=None)[0], dtype=np.float64)
        res = e - a @ coef
        sigma = max(scatter(res), _LEAST_SIGMA)
        w = np.asarray(1.0 / (1.0 + (res / (2.385 * sigma)) ** 2), dtype=np.float64)
    cov = sigma**2 * np.linalg.pinv((a * w[:, None]).T @ a)
    return coef, float(math.sqrt(max(cov[1, 1], 0.0))), e - a @ coef


def taken_from(odo: FloatArray, vel: FloatArray, lag: float) -> FloatArray:
    """The poses (``(N, 3)``, radians) the sweeps were taken from: each of ``odo`` moved back
    along the robot's motion (``vel``) by ``lag`` seconds (forward when it is negative)."""
    if lag == 0.0:
        return odo.copy()
    turn = -lag * vel[:, 1]
    dist = -lag * vel[:, 0]
    mid = odo[:, 2] + turn / 2.0
    out = odo.copy()
    out[:, 0] += dist * np.cos(mid)
    out[:, 1] += dist * np.sin(mid)
    out[:, 2] = wrap(odo[:, 2] + turn)
    return out


def sweep_variance(vel: FloatArray, jitter: float) -> FloatArray:
    """The ``(N, 3)`` variances (x, y, heading) of each sweep about the pose it is logged with
    when its lag varies by ``jitter`` seconds (a standard deviation) from the lag taken: a sweep
    is off by its speed and its turn rate times its own part of the lag. (The speed's part lies
    along the robot's heading; it is given to x and y alike, so that it holds in any frame, the
    world's of a match as well as a step's own.)"""
    per = np.zeros((len(vel), 3))
    per[:, 0] = per[:, 1] = (vel[:, 0] * jitter) ** 2
    per[:, 2] = (vel[:, 1] * jitter) ** 2
    return per


def step_variance(per: FloatArray) -> FloatArray:
    """The ``(N - 1, 3)`` variances each step between neighbouring sweeps gets from both ends'
    (``per``, :func:`sweep_variance`)."""
    out: FloatArray = per[:-1] + per[1:]
    return out


#: A sweep turned less than this (radians, a standard deviation) by its own part of the lag
#: is calm: odometry is taken from it.
_CALM = math.radians(0.05)


def bases(per: FloatArray | None, n: int) -> np.ndarray[Any, np.dtype[np.int64]]:
    """For each scan ``i >= 1``, the scan its odometry is taken from: the last calm one before it
    (see ``_CALM``; ``per`` from :func:`sweep_variance`, None: every sweep is calm, and each
    scan's is the one before). Sweeps each off their pose by a part of their own are not
    chained: the odometry from a calm sweep to each of them, and across them to the next calm
    one, is as good as the robot's."""
    out = np.arange(-1, n - 1, dtype=np.int64)
    if per is None:
        return out
    last = 0
    for i in range(1, n):
        out[i] = last
        if per[i, 2] < _CALM**2:
            last = i
    return out


def calm(odometry_from: np.ndarray[Any, Any]) -> np.ndarray[Any, np.dtype[np.bool_]]:
    """Whether each scan is calm, from ``odometry_from`` (``bases(...)[1:]``, the scan each
    later one's odometry is taken from): a scan is calm when the scan after it takes its
    odometry from it (the last scan counts as calm). The others are sweeps each off their pose
    by their own part of a varying lag, which registration keeps out of its local maps and the
    refinement leaves out (see :func:`mapkit.build._refine.refine`)."""
    out: np.ndarray[Any, np.dtype[np.bool_]] = np.append(
        odometry_from == np.arange(len(odometry_from)), True
    )
    return out
