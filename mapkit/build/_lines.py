"""Line segments from map points: split by direction and offset, split at gaps and corners, merge.

1. Each point gets a local direction (PCA of its neighbours within a few cells).
2. Points are grouped by (direction, offset from the origin) bins, like a Hough transform.
3. Inside a group, points are ordered along the direction and split where a gap opens
   (split), each run is fitted (total least squares) and split again at its worst point while the
   fit is poor (split-and-merge's split step).
4. Collinear segments that touch or overlap (also across bin borders) are merged.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

FloatArray = np.ndarray[Any, np.dtype[np.float64]]


def _fit(p: FloatArray) -> tuple[FloatArray, FloatArray, float]:
    """Total least squares: (centre, unit direction, RMS distance)."""
    c = p.mean(axis=0)
    d = p - c
    cov = d.T @ d / len(p)
    w, v = np.linalg.eigh(cov)
    direction = v[:, 1]
    return c, direction, float(math.sqrt(max(w[0], 0.0)))


def _split(p: FloatArray, tol: float, min_pts: int, min_len: float, out: list[FloatArray]) -> None:
    """Recursive split of points ordered along a line; appends (x1, y1, x2, y2) segments."""
    stack = [p]
    while stack:
        q = stack.pop()
        if len(q) < min_pts:
            continue
        c, d, rms = _fit(q)
        t = (q - c) @ d
        a, b = c + t.min() * d, c + t.max() * d
        if np.hypot(*(b - a)) < min_len:
            continue
        nrm = np.array([-d[1], d[0]])
        dev = np.abs((q - c) @ nrm)
        k = int(np.argmax(dev))
        if dev[k] > tol and 2 <= k <= len(q) - 3:
            stack.append(q[: k + 1])
            stack.append(q[k:])
            continue
        if rms > tol:
            continue
        out.append(np.array([a[0], a[1], b[0], b[1]]))


def extract_lines(
    pts: FloatArray,
    *,
    resolution: float = 20.0,
    min_length: float = 300.0,
    tolerance: float | None = None,
    gap: float | None = None,
) -> FloatArray:
    """Line segments fitted to map points.

    Args:
        pts: ``(N, 2)`` points (mm).
        resolution: The points' grid (mm); sets neighbourhoods and tolerances.
        min_length: Shortest segment kept (mm).
        tolerance: Largest distance of a point from its segment (default 1.5 x resolution).
        gap: Largest gap inside a segment (default 5 x resolution).

    Returns:
        ``(M, 4)`` float segments ``x1 y1 x2 y2``.

    Examples:
        >>> x = np.arange(0, 2000, 20.0)
        >>> wall = np.stack([x, np.zeros_like(x)], axis=1)
        >>> extract_lines(wall).round().tolist()
        [[0.0, 0.0, 1980.0, 0.0]]
    """
    from scipy.spatial import cKDTree

    res = max(float(resolution), 1.0)
    tol = 1.5 * res if tolerance is None else tolerance
    gap = 5.0 * res if gap is None else gap
    pts = np.asarray(pts, dtype=np.float64)
    if len(pts) < 5:
        return np.zeros((0, 4))
    tree = cKDTree(pts)
    k = min(12, len(pts))
    d, idx = tree.query(pts, k=k, distance_upper_bound=4 * res)
    valid = np.isfinite(d)
    idx = np.where(valid, idx, np.arange(len(pts))[:, None])
    nb = pts[idx]  # (N, k, 2)
    cnt = valid.sum(axis=1)
    w = valid.astype(np.float64)
    mean = (nb * w[..., None]).sum(axis=1) / np.maximum(cnt, 1)[:, None]
    dd = (nb - mean[:, None, :]) * w[..., None]
    cxx = (dd[..., 0] ** 2).sum(axis=1)
    cyy = (dd[..., 1] ** 2).sum(axis=1)
    cxy = (dd[..., 0] * dd[..., 1]).sum(axis=1)
    phi = np.mod(0.5 * np.arctan2(2 * cxy, cxx - cyy), math.pi)  # line direction in [0, pi)
    tr = cxx + cyy
    disc = np.sqrt(np.maximum((cxx - cyy) ** 2 / 4 + cxy**2, 0))
    lin = np.where(tr > 0, 2 * disc / np.maximum(tr, 1e-12), 0.0)
    ok = (cnt >= 4) & (lin > 0.6)
    step = math.radians(4.0)
    segs: list[FloatArray] = []
    for shift in (0.0, 0.5):
        # Two staggered binnings so that a wall on a bin border is whole in one of them.
        ab = np.floor(phi / step + shift).astype(np.int64) % round(math.pi / step)
        ang = (ab - shift + 0.5) * step
        nx, ny = -np.sin(ang), np.cos(ang)
        rho = pts[:, 0] * nx + pts[:, 1] * ny
        rb = np.floor(rho / (3 * tol) + shift).astype(np.int64)
        key = ab * 10_000_000 + rb
        sel = np.flatnonzero(ok)
        order = sel[np.argsort(key[sel], kind="stable")]
        ks = key[order]
        bounds = np.flatnonzero(np.diff(ks)) + 1
        for grp in np.split(order, bounds):
            if len(grp) < 5:
                continue
            g = pts[grp]
            a = ang[grp[0]]
            t = g[:, 0] * math.cos(a) + g[:, 1] * math.sin(a)
            o = np.argsort(t)
            g, t = g[o], t[o]
            cut = np.flatnonzero(np.diff(t) > gap) + 1
            for run in np.split(g, cut):
                _split(run, tol, 5, min_length, segs)
    if not segs:
        return np.zeros((0, 4))
    return merge_segments(np.array(segs), tol=tol, gap=gap)


def merge_segments(
    segs: FloatArray, *, tol: float, gap: float, max_angle: float = math.radians(4.0)
) -> FloatArray:
    """Merge collinear segments that overlap or nearly touch (longest first)."""
    segs = np.asarray(segs, dtype=np.float64)
    length = np.hypot(segs[:, 2] - segs[:, 0], segs[:, 3] - segs[:, 1])
    order = np.argsort(-length)
    segs = segs[order]
    alive = np.ones(len(segs), dtype=bool)
    changed = True
    while changed:
        changed = False
        for i in range(len(segs)):
            if not alive[i]:
                continue
            s = segs[i]
            p1, p2 = s[:2], s[2:]
            d = p2 - p1
            ln = float(np.hypot(*d))
            if ln == 0:
                alive[i] = False
                continue
            u = d / ln
            nrm = np.array([-u[1], u[0]])
            others = np.flatnonzero(alive)
            others = others[others != i]
            if len(others) == 0:
                break
            o = segs[others]
            q1, q2 = o[:, :2], o[:, 2:]
            e1 = np.abs((q1 - p1) @ nrm)
            e2 = np.abs((q2 - p1) @ nrm)
            od = q2 - q1
            oang = np.arctan2(od[:, 1], od[:, 0])
            dang = np.abs(
                np.mod(oang - math.atan2(u[1], u[0]) + math.pi / 2, math.pi) - math.pi / 2
            )
            t1 = (q1 - p1) @ u
            t2 = (q2 - p1) @ u
            lo = np.minimum(t1, t2)
            hi = np.maximum(t1, t2)
            close = (e1 < tol) & (e2 < tol) & (dang < max_angle) & (lo < ln + gap) & (hi > -gap)
            if not close.any():
                continue
            js = others[close]
            allp = np.concatenate([segs[[i]].reshape(-1, 2), segs[js].reshape(-1, 2)])
            wts = np.concatenate(
                [[ln, ln], np.repeat(np.hypot(*(segs[js][:, 2:] - segs[js][:, :2]).T), 2)]
            )
            c = (allp * wts[:, None]).sum(axis=0) / wts.sum()
            dd = (allp - c) * np.sqrt(wts)[:, None]
            _, v = np.linalg.eigh(dd.T @ dd)
            dirn = v[:, 1]
            tt = (allp - c) @ dirn
            segs[i] = np.concatenate([c + tt.min() * dirn, c + tt.max() * dirn])
            alive[js] = False
            changed = True
    return segs[alive]
