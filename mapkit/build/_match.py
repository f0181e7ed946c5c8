"""Scan matching: point-to-line ICP against a KD-tree, and a correlative search for loop closures.

Poses here are ``(x mm, y mm, theta radians)`` numpy arrays.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

FloatArray = np.ndarray[Any, np.dtype[np.float64]]


def transform(pts: FloatArray, pose: FloatArray) -> FloatArray:
    """Points through a pose (theta in radians)."""
    c, s = math.cos(pose[2]), math.sin(pose[2])
    out: FloatArray = pts @ np.array([[c, s], [-s, c]])
    out[:, 0] += pose[0]
    out[:, 1] += pose[1]
    return out


def rotate(v: FloatArray, th: float) -> FloatArray:
    """Vectors rotated by ``th`` radians."""
    c, s = math.cos(th), math.sin(th)
    return v @ np.array([[c, s], [-s, c]])  # type: ignore[no-any-return]


def surface_noise(scans: list[FloatArray], most: int = 400, reach: float = 300.0) -> float:
    """How far (mm, a standard deviation) the scans' points scatter about the surfaces they hit,
    along the surfaces' normals: what a point-to-line match sees of the laser's range noise.

    Each point's distance from the chord between its neighbours about a degree either side
    (``len // 180`` beams: a dense laser's next beams are closer than its noise, and the chord's
    own direction would be noise) counts, where both lie within ``reach``; the median's robust
    standard deviation, over the chord's own share (the ends' noise: a half), keeps corners and
    edges out. At most ``most`` scans, evenly spread, are looked at. On simulated logs of 181 to
    683 beams it reads 5.0-6.0 mm for a 5 mm laser, 9.1-10.5 for 10 mm, 12.5-14.4 for 15 and
    20.6-23.6 for 30 (at a slant, a beam's range noise is less across the wall). 0.0: no scans
    to tell."""
    step = max(1, len(scans) // most)
    found = []
    for p in scans[::step]:
        k = max(1, round(len(p) / 180))
        if len(p) < 2 * k + 1:
            continue
        a, b, c = p[: -2 * k], p[k:-k], p[2 * k :]
        chord = c - a
        length = np.hypot(chord[:, 0], chord[:, 1])
        ok = (length > 0) & (np.hypot(*(b - a).T) < reach) & (np.hypot(*(c - b).T) < reach)
        ab = b[ok] - a[ok]
        found.append(np.abs(ab[:, 0] * chord[ok, 1] - ab[:, 1] * chord[ok, 0]) / length[ok])
    d = np.concatenate(found) if found else np.zeros(0)
    return scatter(d) / math.sqrt(1.5) if len(d) else 0.0


def scatter(x: FloatArray) -> float:
    """A robust standard deviation of ``x`` about none: its median absolute value, scaled to a
    normal distribution's."""
    return 1.4826 * float(np.median(np.abs(x)))


#: The laser's scatter about the walls (mm, :func:`surface_noise`) up to which the matches'
#: reaches, residual bars and claims hold as they are set (for the 10-15 mm lasers they were
#: measured on): 2.5 of its standard deviations fit within registration's last reach, 40 mm.
_NOISE_HELD = 16.0


def widened(noise: float) -> float:
    """How many times further than set a match reaches, how much more residual it allows and
    how much more noise it claims, for a laser that scatters ``noise`` (mm) about the walls: 1
    up to ``_NOISE_HELD``, in proportion beyond. Every match's last reach and residual bar take
    it (registration's, the lag's pairs', the calibration's, the refinement's), but for the loop
    closures' reach (see :func:`~mapkit.build._loops._close`); the refinement's claims (twice
    over, :func:`~mapkit.build._refine.claim`) and the loop closures' too (registration's and
    the calibration's take no residual as less than the scatter itself,
    :func:`~mapkit.build._loops.match_info`).

    A 30 mm laser's points (23 mm about the walls) fell out of registration's 40 mm: 15 % of a
    slipping robot's matches failed, where 4 % of a 10 mm one's did. Widened there alone, the
    refinement's 20 mm reach and 10 mm claims were still a 15 mm laser's, and a slipping robot's
    map still came out 110-230 mm from the truth (docs/logs.md, rounds 22 and 23)."""
    return max(1.0, noise / _NOISE_HELD)


def scan_normals(pts: FloatArray, window: int = 3) -> FloatArray:
    """Unit normals of beam-ordered scan points by PCA over ``2*window+1`` neighbours.

    NaN where the neighbourhood is not a straight, continuous piece of wall. Window sums come from
    cumulative sums, so the cost is a few passes over the points.
    """
    return scan_normals_many([pts], window)[0]


def scan_normals_many(scans: list[FloatArray], window: int = 3) -> list[FloatArray]:
    """:func:`scan_normals` of many scans at once (one pass over all their points together)."""
    if not scans:
        return []
    w = 2 * window + 1
    sizes = np.array([len(p) for p in scans], dtype=np.int64)
    total = int(sizes.sum())
    out = np.full((total, 2), np.nan)
    if total < w:
        return np.split(out, np.cumsum(sizes)[:-1])
    pts = np.concatenate(scans).astype(np.float64, copy=False)
    starts = np.concatenate(([0], np.cumsum(sizes)[:-1]))
    # Each scan centred on its own mean (the sums of squares stay precise).
    sums = np.add.reduceat(pts, starts[sizes > 0], axis=0)
    means = np.zeros((len(scans), 2))
    means[sizes > 0] = sums / sizes[sizes > 0, None]
    scan_of = np.repeat(np.arange(len(scans)), sizes)
    # Window k covers points k .. k + w - 1 and sets the normal of point k + window. The windows
    # go in chunks (small temporaries, no page faults for fresh gigabytes); the running sums
    # carry over from chunk to chunk, so every figure is what one pass over all would give.
    carry = np.zeros(5)
    n_win = total - w + 1
    for k0 in range(0, n_win, _CHUNK):
        k1 = min(k0 + _CHUNK, n_win)
        _normals_chunk(pts, means, scan_of, k0, k1, w, carry, out[window + k0 : window + k1])
    return np.split(out, np.cumsum(sizes)[:-1])


#: Windows per chunk in :func:`scan_normals_many`.
_CHUNK = 1 << 15


def _normals_chunk(
    pts: FloatArray,
    means: FloatArray,
    scan_of: np.ndarray[Any, Any],
    k0: int,
    k1: int,
    w: int,
    carry: FloatArray,
    body: FloatArray,
) -> None:
    """The normals of windows ``k0 .. k1 - 1`` into ``body``; ``carry`` holds the running sums
    of x, y, xx, yy, xy of the points before ``k0`` and moves on to ``k1``."""
    e = k1 + w - 1  # points k0 .. e - 1
    p = pts[k0:e]
    mean_at = means[scan_of[k0:e]]
    x = p[:, 0] - mean_at[:, 0]
    y = p[:, 1] - mean_at[:, 1]
    m = k1 - k0

    sums = []  # over each window, as differences of running sums
    for j, v in enumerate((x, y, x * x, y * y, x * y)):
        c = np.concatenate((carry[j : j + 1], v))
        np.cumsum(c, out=c)
        carry[j] = c[m]
        sums.append(c[w:] - c[:-w])
    sx, sy, sxx, syy, sxy = sums
    mx, my = sx / w, sy / w
    cxx = sxx / w - mx * mx
    cyy = syy / w - my * my
    cxy = sxy / w - mx * my
    dxy = cxx - cyy
    tr = cxx + cyy
    disc = np.sqrt(np.maximum(dxy**2 / 4 + cxy * cxy, 0))
    l1, l2 = tr / 2 + disc, tr / 2 - disc
    step = np.hypot(np.diff(p[:, 0]), np.diff(p[:, 1]))
    gaps = step[:m].copy()  # the widest step within each window
    for k in range(1, w - 1):
        np.maximum(gaps, step[k : k + m], out=gaps)
    span = np.hypot(p[w - 1 :, 0] - p[:m, 0], p[w - 1 :, 1] - p[:m, 1])
    first = mean_at[:m]
    rng = np.hypot(mx + first[:, 0], my + first[:, 1])
    # A window that runs over the end of a scan into the next is no neighbourhood.
    same = scan_of[k0:k1] == scan_of[k0 + w - 1 : e]
    good = same & (l2 < 0.05 * np.maximum(l1, 1e-9)) & (gaps < 0.08 * rng + 60.0) & (span > 20.0)
    # The line's direction, and the normal from it, of the windows that have one.
    body[good] = _principal_normal(cxx[good], cyy[good], cxy[good])


def _principal_normal(cxx: FloatArray, cyy: FloatArray, cxy: FloatArray) -> FloatArray:
    """Unit normals of the principal axes of point sets with second moments ``cxx``, ``cyy``,
    ``cxy`` (the normal of the line each set lies along)."""
    ang = 0.5 * np.arctan2(2 * cxy, cxx - cyy)
    return np.column_stack([-np.sin(ang), np.cos(ang)])


def local_planes(pts: FloatArray, nrm: FloatArray, m: int = 8) -> tuple[FloatArray, FloatArray]:
    """Points of several scans smoothed into local planes: each point moved to the centroid of its
    ``m`` nearest (itself among them) and given their principal axis's normal, turned to face as
    its own normal did. A wall seen by many scans becomes one line through their mean, not a band
    of their range noise. Fewer than ``m`` points come back as they are.

    >>> x = np.arange(10.0) * 10.0
    >>> p, n = local_planes(np.column_stack([x, np.tile([2.0, -2.0], 5)]),
    ...                     np.tile([0.0, 1.0], (10, 1)), m=4)
    >>> bool(np.all(np.abs(p[:, 1]) <= 1.0)), bool(np.all(n[:, 1] > 0.99))
    (True, True)
    """
    from scipy.spatial import cKDTree

    if len(pts) < m:
        return pts, nrm
    _, idx = cKDTree(pts).query(pts, k=m)
    near = pts[idx]
    centre = near.mean(axis=1)
    d = near - centre[:, None, :]
    cxx = np.einsum("ij,ij->i", d[..., 0], d[..., 0])
    cyy = np.einsum("ij,ij->i", d[..., 1], d[..., 1])
    cxy = np.einsum("ij,ij->i", d[..., 0], d[..., 1])
    out = _principal_normal(cxx, cyy, cxy)
    out *= np.where(np.einsum("ij,ij->i", out, nrm) < 0.0, -1.0, 1.0)[:, None]
    return centre, out


def _smaller_eigenvalue(a: float, b: float, d: float) -> float:
    """The smaller eigenvalue of the symmetric 2x2 matrix ``[[a, b], [b, d]]`` (closed form)."""
    return 0.5 * (a + d) - math.hypot(0.5 * (a - d), b)


@dataclass
class MatchResult:
    """What a registration found."""

    pose: FloatArray
    ok: bool
    inliers: float  # fraction of source points within the final distance
    rms: float  # RMS point-to-line residual of the inliers (mm)
    n: int
    weakest: float  # smallest eigenvalue of the normalised translation information
    hessian: FloatArray | None = None  # sum of J^T J of the final fit (world frame)
    normals: FloatArray | None = None  # mean n n^T of the matched target normals (2x2)

    def holds(
        self, inliers: float, residual: float, widen: float = 1.0, share: float | None = None
    ) -> bool:
        """Whether the match found enough to go by: it converged, more than ``inliers`` (a
        fraction) of its points lie within its last reach (or found the target as ``share``
        counts them, see :func:`~mapkit.build._loops._share`), and their residual is under
        ``residual`` mm, ``widen`` times that for a noisy laser (:func:`widened`)."""
        found = self.inliers if share is None else share
        return bool(self.ok and found > inliers and self.rms < residual * widen)

    def weak_direction(self, floor: float = 0.12) -> FloatArray | None:
        """Unit vector along which the match tells nothing (a corridor's axis), or None."""
        if self.normals is None:
            return None
        (a, b), (_, d) = self.normals.tolist()
        low = _smaller_eigenvalue(a, b, d)
        if low >= floor:
            return None
        # Its eigenvector: the larger of two equivalent forms (the other may vanish).
        u, v = (b, low - a), (low - d, b)
        x, y = u if abs(u[0]) + abs(u[1]) >= abs(v[0]) + abs(v[1]) else v
        big = max(abs(x), abs(y))
        if big == 0:
            return np.array([1.0, 0.0])
        x, y = x / big, y / big  # (tiny entries keep their precision)
        n = math.hypot(x, y)
        return np.array([x / n, y / n])

    def info(self, sigma: float = 15.0, points: float = 10.0) -> FloatArray:
        """Information of the match in the world frame, as if from ``points`` points of ``sigma``.

        A direction the matched walls do not constrain (a corridor's axis) gets none, however
        many points happen to face it, so a closure in a corridor cannot pull along it.
        """
        if self.hessian is None or self.n == 0:
            return np.zeros((3, 3))
        info = self.hessian * (points / (self.n * sigma * sigma))
        weak = self.weak_direction()
        if weak is not None:
            P = np.eye(3)
            P[:2, :2] -= np.outer(weak, weak)
            info = P.T @ info @ P
        return info


def _solve3(
    h: tuple[tuple[float, ...], ...], g0: float, g1: float, g2: float
) -> tuple[float, float, float] | None:
    """``-H^-1 g`` for a symmetric 3x3 H (upper triangle given; Cramer's rule; None when
    singular). Plain floats: for a 3x3 system numpy's per-call overhead is most of the cost."""
    (a, b, c), (_, d, e), (_, _, f) = h
    a += 1e-9
    d += 1e-9
    f += 1e-6
    A = d * f - e * e
    B = c * e - b * f
    C = b * e - c * d
    det = a * A + b * B + c * C
    if not det or not math.isfinite(det):
        return None
    D = a * f - c * c
    E = b * c - a * e
    F = a * d - b * b
    return (
        -(A * g0 + B * g1 + C * g2) / det,
        -(B * g0 + D * g1 + E * g2) / det,
        -(C * g0 + E * g1 + F * g2) / det,
    )


#: Largest target (points) :func:`icp` copies into one table with its normals.
_TABLE_MAX = 20_000


def icp(
    src: FloatArray,
    tree: Any,
    tgt_pts: FloatArray,
    tgt_nrm: FloatArray,
    init: FloatArray,
    *,
    schedule: tuple[float, ...] = (250.0, 100.0, 50.0),
    max_iter: int = 12,
    huber: float = 20.0,
    min_points: int = 20,
    prior: FloatArray | None = None,
    prior_info: FloatArray | None = None,
    sigma: float = 15.0,
    cauchy: float | None = None,
) -> MatchResult:
    """Point-to-line ICP of ``src`` (robot frame) against a target with normals.

    Args:
        src: ``(n, 2)`` source points in the robot frame.
        tree: ``scipy.spatial.cKDTree`` of ``tgt_pts``.
        tgt_pts: ``(m, 2)`` target points (world).
        tgt_nrm: ``(m, 2)`` unit normals of the target points.
        init: Initial pose (x, y, theta radians).
        schedule: Correspondence distance per iteration (the last one repeats).
        max_iter: Most iterations.
        huber: Residual (mm) above which a point's weight falls (Huber).
        min_points: Fewest matched points for a result.
        prior: A pose the result should stay near (e.g. the odometry prediction), with
            ``prior_info`` its 3x3 information (world frame): it fills the directions the
            scan does not constrain (a corridor's length).
        prior_info: See ``prior``.
        sigma: Range noise assumed for the points (mm), weighting them against the prior.
        cauchy: Use Cauchy weights ``1 / (1 + (r / cauchy)^2)`` instead of Huber's (stronger
            down-weighting of outliers: people, spurious readings).

    Returns:
        The refined pose and fit statistics.
    """
    pose = np.array(init, dtype=np.float64)
    n_src = len(src)
    if n_src < min_points or len(tgt_pts) < min_points:
        return MatchResult(pose, False, 0.0, math.inf, 0, 0.0)
    src = np.asarray(src, dtype=np.float64)
    x, y, th = pose.tolist()
    inv_s2 = 1.0 / (sigma * sigma)
    P = None
    if prior is not None and prior_info is not None:
        px, py, pth = np.asarray(prior, dtype=np.float64).tolist()
        P = np.asarray(prior_info, dtype=np.float64).tolist()
    R = np.empty((2, 2))
    t = np.empty(2)
    # A local map's points and normals go in one table with a last row of zeros for the source
    # points that find no target within reach (the tree answers its size for them): one gather
    # per iteration, and a zero normal adds nothing to the sums. A large target (the whole map)
    # is not copied: the index is clamped and those points' rows zeroed instead.
    tab = None
    if len(tgt_pts) <= _TABLE_MAX:
        tab = np.zeros((len(tgt_pts) + 1, 4))
        tab[:-1, :2] = tgt_pts
        tab[:-1, 2:] = tgt_nrm
    last_tgt = len(tgt_pts) - 1
    K = None
    cnt = 0
    last = len(schedule) - 1
    query = tree.query
    for it in range(max_iter):
        dmax = schedule[min(it, last)]
        c, s = math.cos(th), math.sin(th)
        R[0, 0] = c
        R[0, 1] = s
        R[1, 0] = -s
        R[1, 1] = c
        v = src @ R  # point minus robot position
        t[0] = x
        t[1] = y
        p = v + t
        d, idx = query(p, k=1, distance_upper_bound=dmax, eps=0.2)
        ok = d < dmax
        cnt = int(np.count_nonzero(ok))
        if cnt < min_points:
            pose[:] = (x, y, th)
            return MatchResult(pose, False, cnt / n_src, math.inf, cnt, 0.0)
        if tab is not None:
            T = tab[idx]
            p -= T[:, :2]
            nn = T[:, 2:]
        else:
            if cnt < n_src:
                np.minimum(idx, last_tgt, out=idx)  # any valid index: the row is zeroed below
            nn = tgt_nrm[idx]
            p -= tgt_pts[idx]
        K = np.empty((n_src, 4))
        K[:, :2] = nn
        nx, ny = nn[:, 0], nn[:, 1]
        # K = [nx, ny, ny vx - nx vy, r]: the Jacobian and the residual of each point.
        np.multiply(ny, v[:, 0], out=K[:, 2])
        K[:, 2] -= nx * v[:, 1]
        r = K[:, 3]
        np.multiply(p[:, 0], nx, out=r)
        r += p[:, 1] * ny
        if tab is None and cnt < n_src:
            K[~ok] = 0.0
        if cauchy is not None:
            w = r / cauchy
            w *= w
            w += 1.0
            w = inv_s2 / w
        else:
            w = np.minimum(1.0, huber / np.maximum(np.abs(r), 1e-9)) * inv_s2
        M = (K.T * w) @ K
        (h0, h1, h2, g0), (_, h4, h5, g1), (_, _, h8, g2), _ = M.tolist()
        if P is not None:
            dx, dy = x - px, y - py
            dth = (th - pth + math.pi) % (2 * math.pi) - math.pi
            (a, b, cc), (d_, e, f), (gg, hh, ii) = P
            H = ((h0 + a, h1 + b, h2 + cc), (0, h4 + e, h5 + f), (0, 0, h8 + ii))
            g0 += a * dx + b * dy + cc * dth
            g1 += d_ * dx + e * dy + f * dth
            g2 += gg * dx + hh * dy + ii * dth
        else:
            H = ((h0, h1, h2), (0, h4, h5), (0, 0, h8))
        delta = _solve3(H, g0, g1, g2)
        if delta is None:
            pose[:] = (x, y, th)
            return MatchResult(pose, False, cnt / n_src, math.inf, cnt, 0.0)
        x += delta[0]
        y += delta[1]
        th += delta[2]
        if it >= last and abs(delta[0]) + abs(delta[1]) < 0.5 and abs(delta[2]) < 5e-5:
            break
    assert K is not None
    pose[:] = (x, y, th)
    M = K.T @ K
    info = M[:2, :2] / cnt
    (a, b), (_, d2) = info.tolist()
    weakest = _smaller_eigenvalue(a, b, d2)
    return MatchResult(
        pose, True, cnt / n_src, math.sqrt(M[3, 3] / cnt), cnt, weakest, M[:3, :3].copy(), info
    )


def _likelihood(tgt_pts: FloatArray, cell: float) -> tuple[FloatArray, np.ndarray[Any, Any]]:
    from scipy import ndimage

    lo = tgt_pts.min(axis=0) - cell * 4
    hi = tgt_pts.max(axis=0) + cell * 4
    shape = (int((hi[0] - lo[0]) / cell) + 1, int((hi[1] - lo[1]) / cell) + 1)
    occ = np.zeros(shape, dtype=bool)
    ij = ((tgt_pts - lo) / cell).astype(np.int64)
    occ[ij[:, 0], ij[:, 1]] = True
    dist = ndimage.distance_transform_edt(~occ) * cell
    return lo, np.exp(-0.5 * (dist / cell) ** 2).astype(np.float32)


def _search(
    src: FloatArray,
    lo: FloatArray,
    like: np.ndarray[Any, Any],
    cell: float,
    center: FloatArray,
    k: int,
    ths: FloatArray,
) -> tuple[FloatArray, float]:
    shape = like.shape
    flat = like.ravel()
    offs = np.arange(-k, k + 1)
    best_sc, best = -1.0, center.copy()
    for th in ths:
        p = transform(src, np.array([center[0], center[1], th]))
        base = np.floor((p - lo) / cell).astype(np.int64)
        ix = np.clip(base[:, 0][None, :] + offs[:, None], 0, shape[0] - 1)  # (K, n)
        iy = np.clip(base[:, 1][None, :] + offs[:, None], 0, shape[1] - 1)
        # like[ix[:, None, :], iy[None, :, :]] as one gather from the flat grid (faster).
        score = flat.take((ix * shape[1])[:, None, :] + iy[None, :, :]).sum(axis=2)  # (K, K)
        a, b = np.unravel_index(int(np.argmax(score)), score.shape)
        sc = float(score[a, b])
        if sc > best_sc:
            best_sc = sc
            best = np.array([center[0] + offs[a] * cell, center[1] + offs[b] * cell, th])
    return best, best_sc / max(len(src), 1)


def correlative(
    src: FloatArray,
    tgt_pts: FloatArray,
    center: FloatArray,
    *,
    xy_window: float,
    th_window: float,
    cell: float = 50.0,
) -> tuple[FloatArray, float]:
    """Brute-force search of the pose that best lays ``src`` on ``tgt_pts``, coarse to fine.

    Scores poses on a grid within the windows around ``center`` by the likelihood of each source
    point under a blurred occupancy grid of the target: first with cells 4 x ``cell`` and 2 degree
    steps, then with ``cell`` and 0.5 degrees around the best coarse pose.

    Returns:
        ``(best pose, score)``; the score is the mean per-point likelihood in [0, 1].
    """
    if len(src) == 0 or len(tgt_pts) == 0:
        return center.copy(), 0.0
    coarse = 4 * cell
    lo, like = _likelihood(tgt_pts, coarse)
    k = max(1, round(float(xy_window / coarse)))
    step = math.radians(2.0)
    ths = center[2] + np.arange(-th_window, th_window + 1e-12, step)
    best, _ = _search(src, lo, like, coarse, center, k, ths)
    lo, like = _likelihood(tgt_pts, cell)
    ths = best[2] + np.radians(np.arange(-2.0, 2.01, 0.5))
    return _search(src, lo, like, cell, best, 5, ths)


def voxel_keep(pts: FloatArray, size: float) -> np.ndarray[Any, Any]:
    """Indices of one point per ``size`` mm cell (the first one met)."""
    if len(pts) == 0:
        return np.zeros(0, dtype=np.int64)
    k = np.floor(pts / size).astype(np.int64)
    key = (k[:, 0] << 32) + (k[:, 1] & 0xFFFFFFFF)
    # np.unique(key, return_index=True)'s indices, without its extra passes: a stable sort
    # puts each cell's first point first.
    order = np.argsort(key, kind="stable")
    sk = key[order]
    first = np.empty(len(sk), dtype=bool)
    first[0] = True
    np.not_equal(sk[1:], sk[:-1], out=first[1:])
    idx = order[first]
    idx.sort()
    return idx
