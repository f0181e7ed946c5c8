"""Nearest-obstacle queries for a few positions against many points and segments (vectorised)."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = ["nearest_points", "nearest_segments", "point_segment_distance"]

_F = NDArray[np.float64]


def nearest_points(
    points: NDArray[Any], queries: NDArray[Any], radius: float
) -> tuple[_F, NDArray[np.int64]]:
    """For each query, the distance to and index of the nearest point within ``radius``.

    Points are bucketed once in cells of ``radius`` (one vectorised pass); each query then looks
    at its 3 x 3 neighbouring cells only, so the cost is about one pass over the points whatever
    the number of queries.

    Args:
        points: ``(N, 2)`` coordinates.
        queries: ``(Q, 2)`` coordinates.
        radius: Search radius (> 0).

    Returns:
        ``(distance, index)``: ``inf`` and ``-1`` where no point lies within ``radius``.

    Examples:
        >>> d, i = nearest_points(np.array([[0, 0], [10, 0]]), np.array([[9, 1], [100, 100]]), 5)
        >>> d.round(3).tolist(), i.tolist()
        ([1.414, inf], [1, -1])
    """
    q = np.asarray(queries, dtype=np.float64).reshape(-1, 2)
    dist = np.full(len(q), np.inf)
    idx = np.full(len(q), -1, dtype=np.int64)
    if len(points) == 0 or len(q) == 0:
        return dist, idx
    size = max(float(radius), 1.0)
    pc = np.floor(points / size).astype(np.int64)
    qc = np.floor(q / size).astype(np.int64)
    lo = np.minimum(pc.min(axis=0), qc.min(axis=0)) - 1
    span = np.maximum(pc.max(axis=0), qc.max(axis=0)) + 2 - lo
    pkey = (pc[:, 0] - lo[0]) * span[1] + (pc[:, 1] - lo[1])
    offs = np.array([(dx, dy) for dx in (-1, 0, 1) for dy in (-1, 0, 1)])
    nbr = qc[:, None, :] + offs[None, :, :]  # (Q, 9, 2)
    nkey = (nbr[..., 0] - lo[0]) * span[1] + (nbr[..., 1] - lo[1])
    keep = np.isin(pkey, np.unique(nkey))
    cand = np.flatnonzero(keep)
    if len(cand) == 0:
        return dist, idx
    ckey = pkey[cand]
    order = np.argsort(ckey, kind="stable")
    ckey, cand = ckey[order], cand[order]
    starts = np.searchsorted(ckey, nkey, side="left")
    ends = np.searchsorted(ckey, nkey, side="right")
    for k in range(len(q)):
        sel = np.concatenate(
            [cand[s:e] for s, e in zip(starts[k], ends[k], strict=True) if e > s] or [cand[:0]]
        )
        if len(sel) == 0:
            continue
        d = np.hypot(points[sel, 0] - q[k, 0], points[sel, 1] - q[k, 1])
        j = int(np.argmin(d))
        if d[j] <= radius:
            dist[k], idx[k] = d[j], sel[j]
    return dist, idx


def point_segment_distance(q: NDArray[Any], seg: NDArray[Any]) -> _F:
    """Distance from one point ``q`` (2,) to each segment ``seg`` (M, 4)."""
    s = np.asarray(seg, dtype=np.float64)
    ax, ay, bx, by = s[:, 0], s[:, 1], s[:, 2], s[:, 3]
    dx, dy = bx - ax, by - ay
    ll = dx * dx + dy * dy
    with np.errstate(invalid="ignore", divide="ignore"):
        t = np.where(ll > 0, ((q[0] - ax) * dx + (q[1] - ay) * dy) / np.where(ll > 0, ll, 1), 0.0)
    t = np.clip(t, 0.0, 1.0)
    return np.asarray(np.hypot(ax + t * dx - q[0], ay + t * dy - q[1]), dtype=np.float64)


def nearest_segments(
    segments: NDArray[Any], queries: NDArray[Any], radius: float
) -> tuple[_F, NDArray[np.int64]]:
    """For each query, the distance to and index of the nearest segment within ``radius``.

    Examples:
        >>> d, i = nearest_segments(np.array([[0, 0, 10, 0]]), np.array([[5, 3], [50, 0]]), 10)
        >>> d.tolist(), i.tolist()
        ([3.0, inf], [0, -1])
    """
    q = np.asarray(queries, dtype=np.float64).reshape(-1, 2)
    dist = np.full(len(q), np.inf)
    idx = np.full(len(q), -1, dtype=np.int64)
    if len(segments) == 0:
        return dist, idx
    s = np.asarray(segments, dtype=np.float64)
    xmin, xmax = np.minimum(s[:, 0], s[:, 2]), np.maximum(s[:, 0], s[:, 2])
    ymin, ymax = np.minimum(s[:, 1], s[:, 3]), np.maximum(s[:, 1], s[:, 3])
    for k in range(len(q)):
        x, y = q[k]
        near = np.flatnonzero(
            (xmin <= x + radius)
            & (xmax >= x - radius)
            & (ymin <= y + radius)
            & (ymax >= y - radius)
        )
        if len(near) == 0:
            continue
        d = point_segment_distance(q[k], s[near])
        j = int(np.argmin(d))
        if d[j] <= radius:
            dist[k], idx[k] = d[j], near[j]
    return dist, idx
