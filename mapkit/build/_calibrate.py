"""What the odometry calibration (:class:`~mapkit.build._odometry._Calibration`) is fed while
scans are registered: the motion the scans saw, against the raw odometry over the same steps."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from mapkit.build._common import FloatArray
from mapkit.build._graph import between
from mapkit.build._loops import _CAUCHY, match_info
from mapkit.build._match import icp, scan_normals, widened
from mapkit.build._odometry import _EPS, _Calibration

#: Path (mm) over which the distance scale is measured (between two local-map matches).
BASE = 1000.0

#: Path (mm) over which the heading drift is measured (scan to scan).
DRIFT_BASE = 2000.0

#: A drift sample is taken at every scan until there are ``DRIFT_PLENTY``, then every
#: ``DRIFT_EVERY`` scans (each costs a scan-to-scan match), up to ``DRIFT_ENOUGH``.
DRIFT_EVERY = 3
DRIFT_PLENTY = 300
DRIFT_ENOUGH = 1500


class CalibrationFeed:
    """Measures the motion the scans saw and gives it to the calibration.

    * **Turn scale**: each step of a turn on the spot, between its two local-map matches.
    * **Distance scale**: between two local-map matches a metre or more of path apart (over a
      metre a match's few mm of noise are a small part of the motion). Both are matches against
      the local map, so how far the estimate lags behind the scans does not enter.
    * **Heading drift**: by matching a scan directly against one two metres or more back along a
      straight run (scan to scan). The local map is laid out with the odometry being calibrated,
      and over metres its heading leans towards it: a drift measured against it comes out too
      small. Scan to scan, only the two scans enter. The same match gives a distance scale
      sample too, which the calibration prefers where it has enough of them (the local map's
      length leans the same way, see :meth:`~mapkit.build._odometry._Calibration.observe_run`).
    """

    def __init__(
        self,
        calibration: _Calibration,
        odo: FloatArray,
        path: FloatArray,
        src: list[FloatArray],
        all_pts: list[FloatArray],
        noise: float = 0.0,
    ) -> None:
        self.cal, self.odo, self.path = calibration, odo, path
        self.src, self.all_pts = src, all_pts
        #: The laser's own scatter about the walls (mm): the least a match's residual is taken
        #: as (see :func:`~mapkit.build._loops.match_info`).
        self.noise = noise
        #: How much further than set its scan-to-scan matches reach and how much more residual
        #: they allow (a noisy laser's, :func:`~mapkit.build._match.widened`).
        self.widen = widened(noise)
        self._matches: list[tuple[int, FloatArray, FloatArray]] = []
        self._trees: dict[int, tuple[Any, FloatArray, FloatArray]] = {}
        self._last_drift = -DRIFT_EVERY
        self._scans: list[tuple[int, FloatArray]] = []

    def moved(self) -> None:
        """The local map moved (a loop closed): earlier matches are in another frame."""
        self._matches.clear()

    def step(self, i: int, pose: FloatArray, info: FloatArray) -> None:
        """Scan ``i`` matched the local map at ``pose`` with ``info`` (world frame)."""
        odo, path = self.odo, self.path
        matches = self._matches
        cov = np.asarray(np.linalg.inv(info + _EPS), dtype=np.float64)
        if matches and matches[-1][0] == i - 1:
            k, pk, ck = matches[-1]
            raw = between(odo[k], odo[i])
            if self.cal.on_the_spot(raw):
                self.cal.observe_turn(raw, between(pk, pose), ck + cov)
        for k, pk, ck in reversed(matches):
            if path[i] - path[k] >= BASE:
                if path[i] - path[k] < 3.0 * BASE:
                    # The motion's covariance (two matches'), turned into match k's frame.
                    c, s = math.cos(pk[2]), math.sin(pk[2])
                    R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
                    var = R.T @ (ck + cov) @ R
                    self.cal.observe_run(between(odo[k], odo[i]), between(pk, pose), var)
                break
        matches.append((i, pose.copy(), cov))
        while matches and path[i] - path[matches[0][0]] > 3.0 * BASE:
            matches.pop(0)
        self._drift(i, pose)

    def _drift(self, i: int, pose: FloatArray) -> None:
        odo, path = self.odo, self.path
        scans = self._scans
        # Every scan until there are samples enough, then every few (each costs a match).
        have = len(self.cal.drift_samples)
        every = 1 if have < DRIFT_PLENTY else DRIFT_EVERY
        if have < DRIFT_ENOUGH and i - self._last_drift >= every:
            for k, pk in reversed(scans):
                if path[i] - path[k] >= DRIFT_BASE:
                    run = between(odo[k], odo[i])
                    if path[i] - path[k] < 2.0 * DRIFT_BASE and abs(run[2]) < math.radians(3.0):
                        seen = self._scan_to_scan(k, i, between(pk, pose))
                        if seen is not None:
                            self.cal.observe_drift(run, float(seen[0][2]), float(seen[1][2, 2]))
                            self.cal.observe_run(run, *seen, direct=True)
                            self._last_drift = i
                    break
        scans.append((i, pose.copy()))
        while path[i] - path[scans[0][0]] > 2.0 * DRIFT_BASE:
            scans.pop(0)

    def _target(self, k: int) -> tuple[Any, FloatArray, FloatArray]:
        from scipy.spatial import cKDTree

        hit = self._trees.get(k)
        if hit is None:
            # The whole scan: a single scan's points are sparse far away.
            p = self.all_pts[k]
            nrm = scan_normals(p)
            good = np.isfinite(nrm[:, 0])
            hit = (cKDTree(p[good]) if good.sum() >= 20 else None, p[good], nrm[good])
            self._trees[k] = hit
            if len(self._trees) > 64:
                self._trees.pop(next(iter(self._trees)))
        return hit

    def _scan_to_scan(
        self, k: int, i: int, guess: FloatArray
    ) -> tuple[FloatArray, FloatArray] | None:
        """Scan i's pose in scan k's frame, matched directly, and its covariance."""
        tree, p, n = self._target(k)
        if tree is None:
            return None
        w = self.widen
        r = icp(self.src[i], tree, p, n, guess, schedule=(150.0, 60.0, 40.0 * w), cauchy=_CAUCHY)
        if not r.holds(0.3, 30.0, w):
            return None
        info = match_info(r, self.noise)
        var = np.asarray(np.linalg.inv(info + _EPS), dtype=np.float64)
        return r.pose, var
