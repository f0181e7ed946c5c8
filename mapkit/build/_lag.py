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
scan, from the odometry's guess) and fits the lag (and the odometry's turn scale, which also
shows in those steps) to the heading differences by robust least squares; :func:`taken_from`
moves each pose back along the robot's motion (the ``velocities:`` logged with it) by the lag.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from mapkit.build._common import FloatArray
from mapkit.build._graph import between, wrap
from mapkit.build._loops import _CAUCHY
from mapkit.build._match import icp, scan_normals
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


def measure(odo: FloatArray, vel: FloatArray, pts: list[FloatArray]) -> Lag:
    """The lag of the sweeps behind the poses ``odo`` (``(N, 3)``, radians) logged with
    velocities ``vel`` (:func:`velocities`), from the scans' points ``pts`` (robot frame, in
    beam order)."""
    from scipy.spatial import cKDTree

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
    rows, seen = [], []
    for k in cand:
        nrm = scan_normals(pts[k])
        good = np.isfinite(nrm[:, 0])
        if good.sum() < 20:
            continue
        tgt = pts[k][good]
        src = pts[k + 1][:: max(1, len(pts[k + 1]) // 120)]
        r = icp(
            src, cKDTree(tgt), tgt, nrm[good], rel[k], schedule=(150.0, 60.0, 30.0), cauchy=_CAUCHY
        )
        if not (r.ok and r.inliers > 0.3 and r.rms < 30.0):
            continue
        rows.append((rel[k][2], -change[k]))
        seen.append(wrap(r.pose[2] - rel[k][2]))
    if len(rows) < _MIN_PAIRS:
        return Lag(0.0, math.nan, math.nan, len(rows))
    a = np.array(rows)
    e = np.array(seen)
    lag, error = _robust_fit(a, e)
    turning = np.abs(vel[:, 1][vel[:, 1] != 0.0])
    rate = float(np.percentile(turning, 90)) if len(turning) else 0.0
    taken = (
        abs(lag) > _SIGNIFICANT * error and abs(lag) * rate > _NEGLIGIBLE and abs(lag) <= _LARGEST
    )
    return Lag(lag if taken else 0.0, lag, error, len(rows))


def _robust_fit(a: FloatArray, e: FloatArray) -> tuple[float, float]:
    """The lag (the second column's coefficient) of ``e ~ a @ (scale, lag)`` fitted with Cauchy
    weights (scale from the residuals' median absolute deviation), and its standard error."""
    w: FloatArray = np.ones(len(e))
    coef: FloatArray = np.zeros(2)
    sigma = 1.0
    for _ in range(10):
        sw = np.sqrt(w)
        coef = np.asarray(np.linalg.lstsq(a * sw[:, None], e * sw, rcond=None)[0], dtype=np.float64)
        res = e - a @ coef
        sigma = max(1.4826 * float(np.median(np.abs(res))), math.radians(0.01))
        w = np.asarray(1.0 / (1.0 + (res / (2.385 * sigma)) ** 2), dtype=np.float64)
    cov = sigma**2 * np.linalg.pinv((a * w[:, None]).T @ a)
    return float(coef[1]), float(math.sqrt(max(cov[1, 1], 0.0)))


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
