"""How good a built map is: distances of its points to the true walls, trajectory error.

Used by the tests and ``benchmarks/bench_build.py`` on simulated logs, where the truth is known.
"""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["distance_to_segments", "trajectory_rms"]

FloatArray = np.ndarray[Any, np.dtype[np.float64]]


def distance_to_segments(points: Any, segments: Any, *, chunk: int = 4096) -> FloatArray:
    """Distance (mm) from each point to the nearest segment.

    Args:
        points: ``(N, 2)`` points.
        segments: ``(M, 4)`` segments ``x1 y1 x2 y2``.
        chunk: Points handled at once (memory is ``chunk * M``).

    Returns:
        ``(N,)`` distances (``inf`` when there are no segments).

    Examples:
        >>> distance_to_segments([[0, 5], [20, 0]], [[0, 0, 10, 0]]).tolist()
        [5.0, 10.0]
    """
    p = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    s = np.asarray(segments, dtype=np.float64).reshape(-1, 4)
    out = np.full(len(p), np.inf)
    if len(s) == 0 or len(p) == 0:
        return out
    a, d = s[:, :2], s[:, 2:] - s[:, :2]
    ll = np.einsum("ij,ij->i", d, d)
    ll = np.where(ll > 0, ll, 1.0)
    for k in range(0, len(p), chunk):
        q = p[k : k + chunk]
        rel = q[:, None, :] - a[None, :, :]
        t = np.clip(np.einsum("nmj,mj->nm", rel, d) / ll, 0.0, 1.0)
        diff = rel - t[..., None] * d[None, :, :]
        out[k : k + chunk] = np.sqrt(np.einsum("nmj,nmj->nm", diff, diff).min(axis=1))
    return out


def trajectory_rms(poses: Any, truth: Any) -> tuple[float, float]:
    """RMS position error (mm) and RMS heading error (degrees) of poses against the truth.

    Examples:
        >>> trajectory_rms([[0, 0, 0], [3, 4, 10]], [[0, 0, 0], [0, 0, 0]])
        (3.5355339059327378, 7.0710678118654755)
    """
    a = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
    b = np.asarray(truth, dtype=np.float64).reshape(-1, 3)
    d = np.hypot(a[:, 0] - b[:, 0], a[:, 1] - b[:, 1])
    dth = (a[:, 2] - b[:, 2] + 180.0) % 360.0 - 180.0
    return float(np.sqrt(np.mean(d * d))), float(np.sqrt(np.mean(dth * dth)))
