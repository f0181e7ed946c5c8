"""The simulated laser: beams ray-cast against a map's lines and points, vectorised with numpy."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

__all__ = ["NO_RETURN", "FloatArray", "ray_cast", "segment_samples"]


FloatArray = np.ndarray[Any, np.dtype[np.float64]]
#: What the laser reports for a beam without a return (raw range), as a SICK LMS does.
NO_RETURN = 32767


def segment_samples(
    segments: FloatArray, step: float
) -> tuple[FloatArray, np.ndarray[Any, np.dtype[np.int64]]]:
    """Points along each ``x1 y1 x2 y2`` segment, both ends included and at most ``step`` mm
    apart (a segment of no length gives its point twice), and the segment each comes from.

    Examples:
        >>> pts, idx = segment_samples(np.array([[0.0, 0, 100, 0]]), 25.0)
        >>> pts[:, 0].tolist(), idx.tolist()
        ([0.0, 25.0, 50.0, 75.0, 100.0], [0, 0, 0, 0, 0])
    """
    length = np.hypot(segments[:, 2] - segments[:, 0], segments[:, 3] - segments[:, 1])
    k = np.maximum(np.ceil(length / step).astype(np.int64), 1) + 1
    idx = np.repeat(np.arange(len(segments)), k)
    t = (np.arange(int(k.sum())) - np.repeat(np.cumsum(k) - k, k)) / np.repeat(k - 1, k)
    pts: FloatArray = segments[idx, :2] + t[:, None] * (segments[idx, 2:] - segments[idx, :2])
    return pts, idx


# -- ray casting -------------------------------------------------------------------------------


def _beam_pairs(
    lo: FloatArray, width: FloatArray, start: float, step: float, n: int
) -> tuple[np.ndarray[Any, Any], np.ndarray[Any, Any]]:
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
    pose: Sequence[float] | FloatArray,
    angles_deg: FloatArray,
    segments: FloatArray,
    points: FloatArray,
    *,
    max_range: float,
    point_size: float = 20.0,
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
        t = np.clip(
            np.einsum("ij,ij->i", np.array([x0, y0]) - p1, d) / np.where(ll > 0, ll, 1), 0, 1
        )
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
