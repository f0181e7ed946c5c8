"""The build's fast paths against plain references: each computes what the plainer code it
replaced computes (to rounding, or bit for bit where the code says so)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st
from scipy.spatial import cKDTree

from mapkit.build import _match
from mapkit.build._graph import PoseGraph, _blocks, _Pattern, between, sigma_info, wrap
from mapkit.build._match import MatchResult, icp, scan_normals_many, transform

seeds = st.integers(min_value=0, max_value=2**31)


def _solve3_ref(H: np.ndarray, g: np.ndarray) -> np.ndarray | None:
    H = H + np.diag([1e-9, 1e-9, 1e-6])
    if not np.isfinite(np.linalg.det(H)) or np.linalg.det(H) == 0:
        return None
    return -np.linalg.solve(H, g)


def icp_ref(src, tree, tgt_pts, tgt_nrm, init, *, schedule, max_iter=12, huber=20.0,
            min_points=20, prior=None, prior_info=None, sigma=15.0, cauchy=None):  # fmt: skip
    """Point-to-line ICP as first written: masks, ``J^T W J`` and a 3x3 solve per iteration."""
    pose = np.array(init, dtype=np.float64)
    n_src = len(src)
    if n_src < min_points or len(tgt_pts) < min_points:
        return MatchResult(pose, False, 0.0, math.inf, 0, 0.0)
    nn = r = J = None
    cnt = 0
    for it in range(max_iter):
        dmax = schedule[min(it, len(schedule) - 1)]
        v = transform(src, np.array([0.0, 0.0, pose[2]]))
        p = v + pose[:2]
        d, idx = tree.query(p, k=1, distance_upper_bound=dmax, eps=0.2)
        ok = d < dmax
        cnt = int(ok.sum())
        if cnt < min_points:
            return MatchResult(pose, False, cnt / n_src, math.inf, cnt, 0.0)
        nn, q, v = tgt_nrm[idx[ok]], tgt_pts[idx[ok]], v[ok]
        r = np.sum((p[ok] - q) * nn, axis=1)
        J = np.stack([nn[:, 0], nn[:, 1], nn[:, 1] * v[:, 0] - nn[:, 0] * v[:, 1]], axis=1)
        if cauchy is not None:
            w = 1.0 / (1.0 + (r / cauchy) ** 2) / sigma**2
        else:
            w = np.minimum(1.0, huber / np.maximum(np.abs(r), 1e-9)) / sigma**2
        H = (J * w[:, None]).T @ J
        g = (J * w[:, None]).T @ r
        if prior is not None and prior_info is not None:
            dp = pose - prior
            dp[2] = wrap(dp[2])
            H = H + prior_info
            g = g + prior_info @ dp
        delta = _solve3_ref(H, g)
        if delta is None:
            return MatchResult(pose, False, cnt / n_src, math.inf, cnt, 0.0)
        pose += delta
        small = abs(delta[0]) + abs(delta[1]) < 0.5 and abs(delta[2]) < 5e-5
        if it >= len(schedule) - 1 and small:
            break
    info = nn.T @ nn / cnt
    weakest = float(np.linalg.eigvalsh(info)[0])
    return MatchResult(
        pose, True, cnt / n_src, float(np.sqrt(np.mean(r * r))), cnt, weakest, J.T @ J, info
    )


def _scene(seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Walls of a room (points and normals), a scan of them from a pose near the origin (with
    stray points that match nothing), and that pose."""
    rng = np.random.default_rng(seed)
    walls, normals = [], []
    for _ in range(int(rng.integers(3, 7))):
        a = rng.uniform(-4000, 4000, 2)
        ang = rng.uniform(0, math.pi)
        t = np.arange(0, rng.uniform(800, 5000), 40.0)
        walls.append(a + t[:, None] * [math.cos(ang), math.sin(ang)])
        normals.append(np.tile([-math.sin(ang), math.cos(ang)], (len(t), 1)))
    pts, nrm = np.concatenate(walls), np.concatenate(normals)
    true = np.array([rng.uniform(-200, 200), rng.uniform(-200, 200), rng.uniform(-0.1, 0.1)])
    k = rng.choice(len(pts), size=min(len(pts), int(rng.integers(40, 200))), replace=False)
    world = pts[k] + rng.normal(0, 5, (len(k), 2))
    stray = rng.uniform(-20000, 20000, (int(rng.integers(0, 20)), 2))
    c, s = math.cos(true[2]), math.sin(true[2])
    src = (np.concatenate([world, stray]) - true[:2]) @ np.array([[c, -s], [s, c]])
    return src, pts, nrm, true


@settings(max_examples=60, deadline=None)
@given(seeds, st.sampled_from(["cauchy", "huber"]), st.booleans(), st.booleans(), st.booleans())
def test_icp_equals_the_plain_reference(
    seed: int, weights: str, prior: bool, balanced: bool, table: bool
) -> None:
    """Both ways of gathering the target (one table of a local map; the large target's own
    arrays) give the reference's answer."""
    src, pts, nrm, true = _scene(seed)
    rng = np.random.default_rng(seed + 1)
    init = true + np.array([rng.normal(0, 80), rng.normal(0, 80), rng.normal(0, 0.03)])
    tree = cKDTree(pts, balanced_tree=balanced, compact_nodes=balanced)
    kw = {
        "schedule": (250.0, 100.0, 40.0),
        "cauchy": 25.0 if weights == "cauchy" else None,
        "prior": init if prior else None,
        "prior_info": sigma_info(300.0, 300.0, 0.2) if prior else None,
    }
    saved = _match._TABLE_MAX
    try:
        _match._TABLE_MAX = len(pts) if table else len(pts) - 1
        got = icp(src, tree, pts, nrm, init, **kw)
    finally:
        _match._TABLE_MAX = saved
    want = icp_ref(src, tree, pts, nrm, init, **kw)
    assert (got.ok, got.n) == (want.ok, want.n)
    # Equal up to the order of floating-point sums, which differs between the two and adds up
    # over the iterations (a micrometre at most).
    assert np.allclose(got.pose[:2], want.pose[:2], rtol=0, atol=1e-5)
    assert got.pose[2] == pytest.approx(want.pose[2], rel=0, abs=1e-9)
    assert got.inliers == want.inliers
    if want.ok:
        assert got.rms == pytest.approx(want.rms, rel=1e-9)
        assert got.weakest == pytest.approx(want.weakest, rel=1e-9, abs=1e-12)
        assert np.allclose(got.hessian, want.hessian, rtol=1e-9, atol=1e-9)
        assert np.allclose(got.normals, want.normals, rtol=1e-12, atol=1e-12)


@settings(max_examples=200, deadline=None)
@given(
    st.floats(0.0, 1.0),
    st.floats(-1.0, 1.0),
    st.floats(0.0, 1.0),
    st.floats(0.0, 0.5),
)
def test_weak_direction_equals_eigh(a: float, b: float, d: float, floor: float) -> None:
    N = np.array([[a, b], [b, d]])
    r = MatchResult(np.zeros(3), True, 1.0, 1.0, 1, 0.0, np.eye(3), N)
    w, v = np.linalg.eigh(N)
    got = r.weak_direction(floor)
    if abs(w[0] - floor) < 1e-12:
        return  # on the threshold: either answer is right
    assert (got is None) == (w[0] >= floor)
    if got is not None:
        assert abs(np.linalg.norm(got) - 1.0) < 1e-12
        if w[1] - w[0] > 1e-9:  # a distinct eigenvalue: the vector is unique up to sign
            assert abs(abs(float(got @ v[:, 0])) - 1.0) < 1e-9
        else:
            assert np.allclose(N @ got, w[0] * got, atol=1e-9)


@settings(max_examples=100, deadline=None)
@given(st.lists(st.floats(-1e6, 1e6), min_size=6, max_size=6))
def test_between_of_one_pair_equals_the_vectorised_form(v: list[float]) -> None:
    a = np.array([v[0], v[1], v[2] / 1e5])  # angles within about +-10 radians
    b = np.array([v[3], v[4], v[5] / 1e5])
    many = between(np.stack([a, a]), np.stack([b, b]))
    assert np.array_equal(between(a, b), many[0])


@settings(max_examples=30, deadline=None)
@given(
    st.lists(st.integers(min_value=0, max_value=80), min_size=1, max_size=8),
    st.integers(min_value=1, max_value=40),
    seeds,
)
def test_scan_normals_in_chunks_are_bit_for_bit_one_pass(
    sizes: list[int], chunk: int, seed: int
) -> None:
    rng = np.random.default_rng(seed)
    scans = [np.cumsum(rng.normal(0, 30, (n, 2)), axis=0) + np.array([3000.0, 0.0]) for n in sizes]
    whole = scan_normals_many(scans)
    saved = _match._CHUNK
    try:
        _match._CHUNK = chunk
        parts = scan_normals_many(scans)
    finally:
        _match._CHUNK = saved
    for a, b in zip(whole, parts, strict=True):
        assert np.array_equal(a, b, equal_nan=True)


@settings(max_examples=40, deadline=None)
@given(st.integers(min_value=2, max_value=30), st.integers(min_value=0, max_value=60), seeds)
def test_pose_graph_pattern_equals_plain_assembly(n: int, extra: int, seed: int) -> None:
    """The CSC matrix and right-hand side from the block pattern against a dense sum of every
    edge's blocks (node 0 left out), repeated edges and nodes without edges included."""
    rng = np.random.default_rng(seed)
    I = np.concatenate([np.arange(n - 1), rng.integers(0, n, extra)])  # noqa: E741
    J = np.concatenate([np.arange(1, n), rng.integers(0, n, extra)])
    keep = rng.random(len(I)) < 0.8  # some nodes may end up with no edge at all
    I, J = I[keep], J[keep]  # noqa: E741
    hii, hij, hjj = rng.normal(size=(3, len(I), 3, 3))
    bi, bj = rng.normal(size=(2, len(I), 3))
    pat = _Pattern(I, J, n)
    dense = np.zeros((3 * n, 3 * n))
    rhs = np.zeros(3 * n)
    for k, (i, j) in enumerate(zip(I, J, strict=True)):
        for blk, r, c in ((hii[k], i, i), (hij[k], i, j), (hij[k].T, j, i), (hjj[k], j, j)):
            dense[3 * r : 3 * r + 3, 3 * c : 3 * c + 3] += blk
        rhs[3 * i : 3 * i + 3] += bi[k]
        rhs[3 * j : 3 * j + 3] += bj[k]
    dense += np.eye(3 * n) * 1e-9
    H = pat.matrix(hii, hij, hjj)
    H.check_format(full_check=True)
    assert np.allclose(H.toarray(), dense[3:, 3:], rtol=1e-12, atol=1e-12)
    assert np.allclose(pat.vector(bi, bj), rhs[3:], rtol=1e-12, atol=1e-12)


def test_pose_graph_arrays_follow_new_edges() -> None:
    g = PoseGraph()
    rng = np.random.default_rng(5)
    x = np.cumsum(rng.normal(0, 100, (40, 3)), axis=0)
    x[:, 2] = wrap(x[:, 2] / 100)
    for k in range(1, 20):
        g.add(k - 1, k, between(x[k - 1], x[k]), sigma_info(10, 10, 0.01))
    g.optimize(x)
    for k in range(20, 40):
        g.add(k - 1, k, between(x[k - 1], x[k]), sigma_info(10, 10, 0.01), robust=k % 2 == 0)
    have = g._arrays()
    plain = (np.array(g.i), np.array(g.j), np.array(g.z), np.array(g.info), np.array(g.robust))
    for a, b in zip(have, plain, strict=True):
        assert a.dtype == b.dtype and np.array_equal(a, b)


@settings(max_examples=30, deadline=None)
@given(seeds, st.integers(min_value=1, max_value=6))
def test_correlative_search_equals_the_plain_gather(seed: int, k: int) -> None:
    rng = np.random.default_rng(seed)
    like = rng.random((int(rng.integers(5, 40)), int(rng.integers(5, 40)))).astype(np.float32)
    lo, cell = np.array([-500.0, -300.0]), 50.0
    src = rng.uniform(-1500, 1500, (int(rng.integers(1, 60)), 2))
    center = np.array([rng.uniform(0, 800), rng.uniform(0, 800), rng.uniform(-3, 3)])
    ths = center[2] + np.radians(np.arange(-4.0, 4.01, 2.0))
    got = _match._search(src, lo, like, cell, center, k, ths)
    # The plain form: a 2D gather per angle.
    offs = np.arange(-k, k + 1)
    best_sc, best = -1.0, center.copy()
    for th in ths:
        base = np.floor((transform(src, np.array([*center[:2], th])) - lo) / cell).astype(int)
        ix = np.clip(base[:, 0][None, :] + offs[:, None], 0, like.shape[0] - 1)
        iy = np.clip(base[:, 1][None, :] + offs[:, None], 0, like.shape[1] - 1)
        score = like[ix[:, None, :], iy[None, :, :]].sum(axis=2)
        a, b = np.unravel_index(int(np.argmax(score)), score.shape)
        if float(score[a, b]) > best_sc:
            best_sc = float(score[a, b])
            best = np.array([center[0] + offs[a] * cell, center[1] + offs[b] * cell, th])
    assert np.array_equal(got[0], best) and got[1] == best_sc / len(src)


@settings(max_examples=40, deadline=None)
@given(seeds, st.integers(min_value=1, max_value=50))
def test_pose_graph_blocks_equal_the_jacobian_products(seed: int, m: int) -> None:
    """The normal equations' blocks written out against ``A^T Om A`` etc. from the Jacobians."""
    rng = np.random.default_rng(seed)
    L = rng.normal(size=(m, 3, 3)) * [1.0, 1.0, 100.0]
    om = L @ L.transpose(0, 2, 1)  # symmetric, positive semi-definite
    e = rng.normal(size=(m, 3)) * [50.0, 50.0, 0.05]
    ti, tz = rng.uniform(-4, 4, m), rng.uniform(-4, 4, m)
    ci, si, cz, sz = np.cos(ti), np.sin(ti), np.cos(tz), np.sin(tz)
    dx, dy = rng.normal(size=(2, m)) * 3000.0
    RiT = np.stack([np.stack([ci, si], 1), np.stack([-si, ci], 1)], 1)
    RzT = np.stack([np.stack([cz, sz], 1), np.stack([-sz, cz], 1)], 1)
    dRiT = np.stack([np.stack([-si, ci], 1), np.stack([-ci, -si], 1)], 1)
    M = RzT @ RiT
    A, B = np.zeros((m, 3, 3)), np.zeros((m, 3, 3))
    A[:, :2, :2], B[:, :2, :2] = -M, M
    A[:, :2, 2] = (RzT @ (dRiT @ np.stack([dx, dy], 1)[:, :, None]))[:, :, 0]
    A[:, 2, 2], B[:, 2, 2] = -1.0, 1.0
    At, Bt = A.transpose(0, 2, 1), B.transpose(0, 2, 1)
    want = (At @ om @ A, At @ om @ B, Bt @ om @ B, (At @ om @ e[:, :, None])[:, :, 0])
    want = (*want, (Bt @ om @ e[:, :, None])[:, :, 0])
    got = _blocks(om, e, ci, si, cz, sz, dx, dy)
    for g, w in zip(got, want, strict=True):
        scale = np.abs(w).max() + 1e-300
        assert np.allclose(g, w, rtol=1e-10, atol=1e-12 * scale)


def test_pose_graph_with_a_broken_edge_leaves_the_poses() -> None:
    """A system that cannot be factored (here: an edge whose information is NaN) stops the
    optimisation with the poses as they were, as the general solver's non-finite answer did."""
    g = PoseGraph()
    x = np.array([[0.0, 0.0, 0.0], [1000.0, 0.0, 0.0], [2000.0, 10.0, 0.1]])
    g.add(0, 1, np.array([1000.0, 0.0, 0.0]), np.full((3, 3), np.nan))
    g.add(1, 2, np.array([1000.0, 0.0, 0.0]), sigma_info(10, 10, 0.01))
    with np.errstate(all="ignore"):
        assert np.array_equal(g.optimize(x), x)


@settings(max_examples=60, deadline=None)
@given(seeds, st.integers(min_value=1, max_value=2000), st.sampled_from([30.0, 500.0, 1e6]))
def test_voxel_keep_equals_unique(seed: int, n: int, spread: float) -> None:
    """The first point of each cell, as ``np.unique(..., return_index=True)`` finds them."""
    rng = np.random.default_rng(seed)
    pts = rng.normal(0, spread, (n, 2))
    k = np.floor(pts / 40.0).astype(np.int64)
    _, idx = np.unique((k[:, 0] << 32) + (k[:, 1] & 0xFFFFFFFF), return_index=True)
    assert np.array_equal(_match.voxel_keep(pts, 40.0), np.sort(idx))
