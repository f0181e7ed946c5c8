"""A 2D pose graph and its Gauss-Newton optimisation (sparse, scipy).

Nodes are poses ``(x mm, y mm, theta radians)``; an edge says "pose j seen from pose i is z" with
a 3x3 information matrix (in the frame of the expected pose j, as the error is). Node 0 is held
fixed. Loop edges get a robust (Huber) weight so that one bad closure cannot bend the whole map.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

FloatArray = np.ndarray[Any, np.dtype[np.float64]]


def wrap(a: Any) -> Any:
    """Angles (radians) to [-pi, pi)."""
    return (np.asarray(a) + math.pi) % (2 * math.pi) - math.pi


def sigma_info(sx: float, sy: float, sth: float) -> FloatArray:
    """A diagonal information matrix from standard deviations (mm, mm, radians)."""
    return np.diag([1.0 / sx**2, 1.0 / sy**2, 1.0 / sth**2])


def between(a: FloatArray, b: FloatArray) -> FloatArray:
    """Pose b in a's frame (vectorised, radians)."""
    if a.shape == (3,) and b.shape == (3,):
        # One pair (most calls): plain floats, a fraction of numpy's per-call cost.
        (ax, ay, at), (bx, by, bt) = a.tolist(), b.tolist()
        co, si = math.cos(at), math.sin(at)
        ex, ey = bx - ax, by - ay
        tw = (bt - at + math.pi) % (2 * math.pi) - math.pi
        return np.array([co * ex + si * ey, -si * ex + co * ey, tw])
    c, s = np.cos(a[..., 2]), np.sin(a[..., 2])
    dx, dy = b[..., 0] - a[..., 0], b[..., 1] - a[..., 1]
    return np.stack([c * dx + s * dy, -s * dx + c * dy, wrap(b[..., 2] - a[..., 2])], axis=-1)


def plus_variance(info: FloatArray, var: FloatArray) -> FloatArray:
    """The diagonal information ``info`` with the variances ``var`` added to its own."""
    if not var.any():
        return info
    out: FloatArray = np.diag(1.0 / (1.0 / np.diag(info) + var))
    return out


def then(a: FloatArray, b: FloatArray) -> FloatArray:
    """The pose ``b`` (in ``a``'s frame) moved to the world: ``a`` followed by ``b`` (radians);
    :func:`between`'s inverse."""
    c, s = math.cos(a[2]), math.sin(a[2])
    return np.array(
        [a[0] + c * b[0] - s * b[1], a[1] + s * b[0] + c * b[1], wrap(a[2] + b[2])],
        dtype=np.float64,
    )


#: Rounds of the consistency check (each switches off one edge and optimises again).
_REJECT_ROUNDS = 6

#: Robust edges the check weighs against each other each round (those the poses miss most).
_SUSPECTS = 4

#: Gauss-Newton iterations a suspect's trial (the graph without it) is given.
_TRIAL_ITERATIONS = 8


def _chi_of(e: FloatArray, info: FloatArray) -> FloatArray:
    """Each edge's error in standard deviations: ``sqrt(e^T info e)``."""
    chi: FloatArray = np.sqrt(np.maximum(np.einsum("ea,eab,eb->e", e, info, e), 0.0))
    return chi


class PoseGraph:
    """Edges collected while mapping; :meth:`optimize` moves the nodes."""

    def __init__(self) -> None:
        self.i: list[int] = []
        self.j: list[int] = []
        self.z: list[FloatArray] = []
        self.info: list[FloatArray] = []
        self.robust: list[bool] = []
        #: Indices of the edges the consistency check switched off.
        self.rejected: set[int] = set()
        self._have: tuple[Any, ...] | None = None

    def add(self, i: int, j: int, z: FloatArray, info: FloatArray, *, robust: bool = False) -> None:
        """Add an edge with a 3x3 information matrix (see :func:`sigma_info`)."""
        self.i.append(i)
        self.j.append(j)
        self.z.append(np.asarray(z, dtype=np.float64))
        self.info.append(np.asarray(info, dtype=np.float64).reshape(3, 3))
        self.robust.append(robust)

    def __len__(self) -> int:
        return len(self.i)

    def optimize(
        self,
        x: FloatArray,
        *,
        iterations: int = 10,
        huber: float = 3.0,
        reject: float | None = None,
    ) -> FloatArray:
        """Gauss-Newton on all nodes but node 0; returns the new ``(N, 3)`` poses.

        With ``reject``, the graph is also checked for consistency: while a robust edge (a loop
        closure) is missed by the optimised poses by more than ``reject`` standard deviations,
        some closure disagrees with the rest of the evidence (caught on the wrong wall, a wrong
        revisit). One edge per round is switched off (:meth:`_least_consistent`) and the graph
        optimised again, for a few rounds; switched-off edges stay off (:attr:`rejected`).
        """
        x = np.array(x, dtype=np.float64)
        if len(x) < 2 or not self.i:
            return x
        edges = self._arrays()
        x = self._gauss_newton(x, edges, iterations, huber)
        if reject is None:
            return x
        for _ in range(_REJECT_ROUNDS):
            chi = self._chi(x, edges)
            live = edges[4] & self._active(len(chi))
            if not (live & (chi > reject)).any():
                break
            k, x = self._least_consistent(x, edges, chi, live, huber)
            self.rejected.add(k)
            x = self._gauss_newton(x, edges, iterations, huber)
        return x

    def _least_consistent(
        self,
        x: FloatArray,
        edges: tuple[Any, ...],
        chi: FloatArray,
        live: np.ndarray[Any, Any],
        huber: float,
    ) -> tuple[int, FloatArray]:
        """Of the ``_SUSPECTS`` robust edges the poses ``x`` miss most (``chi``: by how many
        standard deviations; ``live``: not switched off), the one without which the graph fits
        the rest best (its cost, optimised from ``x``), and the poses so optimised.

        The edge missed most is not always the wrong one. Where a wrong closure came first and
        moved the estimate, a surer right one after it is missed by more standard deviations:
        on an office log from a slipping robot with a 30 mm laser the right one was missed by 11
        and the wrong one, 194 mm out, by 2.8. Switching off the one missed most kept the wrong
        one, which bent the map (141.1 mm RMS; 14.9 with this choice, docs/logs.md, round
        25)."""
        suspects = np.flatnonzero(live)
        suspects = suspects[np.argsort(-chi[suspects], kind="stable")][:_SUSPECTS]
        best: tuple[float, int, FloatArray] | None = None
        for k in suspects.tolist():
            self.rejected.add(k)
            trial = self._gauss_newton(x.copy(), edges, _TRIAL_ITERATIONS, huber)
            cost = self.cost(trial, huber)
            self.rejected.discard(k)
            if best is None or cost < best[0]:
                best = (cost, k, trial)
        assert best is not None  # live has an edge the poses miss
        return best[1], best[2]

    def cost(self, x: FloatArray, huber: float = 3.0) -> float:
        """What :meth:`optimize` minimises, at poses ``x``: each edge's chi-square (Huber's
        beyond ``huber`` standard deviations for a robust edge), switched-off edges left out."""
        edges = self._arrays()
        chi = self._chi(np.asarray(x, dtype=np.float64), edges)
        rho = np.where(edges[4] & (chi > huber), 2.0 * huber * chi - huber * huber, chi * chi)
        return float(np.sum(rho * self._active(len(chi))))

    def _active(self, m: int) -> np.ndarray[Any, Any]:
        act = np.ones(m, dtype=bool)
        if self.rejected:
            act[list(self.rejected)] = False
        return act

    def _arrays(self) -> tuple[Any, ...]:
        # The edges as arrays; those of an earlier call are kept, only new edges are converted.
        have = self._have
        m = len(self.i)
        if have is None or len(have[0]) > m:
            have = tuple(np.zeros((0, *shape)) for shape in ((), (), (3,), (3, 3), ()))
        k = len(have[0])
        new = (self.i[k:], self.j[k:], self.z[k:], self.info[k:], self.robust[k:])
        types = (np.int64, np.int64, np.float64, np.float64, bool)
        self._have = tuple(
            np.concatenate(
                [h.astype(t, copy=False), np.array(v, dtype=t).reshape(-1, *h.shape[1:])]
            )
            for h, v, t in zip(have, new, types, strict=True)
        )
        return self._have

    @staticmethod
    def _errors(x: FloatArray, edges: tuple[Any, ...]) -> tuple[FloatArray, ...]:
        I, J, Z = edges[0], edges[1], edges[2]  # noqa: E741
        cz, sz = np.cos(Z[:, 2]), np.sin(Z[:, 2])
        xi, xj = x[I], x[J]
        ci, si = np.cos(xi[:, 2]), np.sin(xi[:, 2])
        dx, dy = xj[:, 0] - xi[:, 0], xj[:, 1] - xi[:, 1]
        # e = Rz^T (Ri^T (tj - ti) - tz), theta_j - theta_i - theta_z
        ux = ci * dx + si * dy - Z[:, 0]
        uy = -si * dx + ci * dy - Z[:, 1]
        e = np.stack(
            [cz * ux + sz * uy, -sz * ux + cz * uy, wrap(xj[:, 2] - xi[:, 2] - Z[:, 2])], axis=1
        )
        return e, ci, si, cz, sz, dx, dy

    def _chi(self, x: FloatArray, edges: tuple[Any, ...]) -> FloatArray:
        return _chi_of(self._errors(x, edges)[0], edges[3])

    def _gauss_newton(
        self, x: FloatArray, edges: tuple[Any, ...], iterations: int, huber: float
    ) -> FloatArray:
        from scipy.sparse.linalg import splu

        n = len(x)
        I, J, _, OM, RB = edges  # noqa: E741 (I, J: the edges' node indices, as in the maths)
        active = self._active(len(I)).astype(np.float64)
        pattern = _Pattern(I, J, n)
        for _ in range(iterations):
            e, ci, si, cz, sz, dx, dy = self._errors(x, edges)
            chi = _chi_of(e, OM)
            scale = np.where(RB & (chi > huber), huber / np.maximum(chi, 1e-12), 1.0) * active
            om = OM * scale[:, None, None]
            hii, hij, hjj, bi, bj = _blocks(om, e, ci, si, cz, sz, dx, dy)
            H = pattern.matrix(hii, hij, hjj)
            b = pattern.vector(bi, bj)
            # Symmetric positive definite: no pivoting, a fill-reducing ordering of A + A^T; no
            # supernodes to speak of (a chain with a few loop edges), so none are looked for.
            try:
                lu = splu(
                    H,
                    permc_spec="MMD_AT_PLUS_A",
                    diag_pivot_thresh=0.0,
                    relax=1,
                    panel_size=1,
                    options={"SymmetricMode": True},
                )
            except RuntimeError:  # singular (as spsolve's non-finite answer before)
                break
            delta = lu.solve(-b)
            if not np.all(np.isfinite(delta)):
                break
            x[1:] += delta.reshape(-1, 3)
            x[:, 2] = wrap(x[:, 2])
            if np.max(np.abs(delta[0::3])) < 0.1 and np.max(np.abs(delta[2::3])) < 1e-5:
                break
        return x


def _blocks(
    om: FloatArray,
    e: FloatArray,
    ci: FloatArray,
    si: FloatArray,
    cz: FloatArray,
    sz: FloatArray,
    dx: FloatArray,
    dy: FloatArray,
) -> tuple[FloatArray, ...]:
    """Each edge's blocks of the normal equations, ``A^T Om A``, ``A^T Om B``, ``B^T Om B``,
    ``A^T Om e`` and ``B^T Om e``, written out on (E,) columns (a few dozen passes instead of
    batched 3x3 products).

    With ``M = Rz^T Ri^T``, the Jacobians of the error are ``B = [[M, 0], [0, 1]]`` (pose j)
    and ``A = -B + a e3^T`` (pose i), ``a = (Rz^T dRi^T/dth (tj - ti), 0)``. So with
    ``u = Om a``, ``c = B^T u``: ``A^T Om B = -B^T Om B + e3 c^T``, ``A^T Om A = B^T Om B -
    c e3^T - e3 c^T + (a.u) e3 e3^T``, and ``A^T Om e = -B^T Om e + (a.Om e) e3``.
    """
    m00, m01 = cz * ci - sz * si, cz * si + sz * ci
    m10, m11 = -sz * ci - cz * si, -sz * si + cz * ci
    ux, uy = -si * dx + ci * dy, -ci * dx - si * dy  # dRi^T/dth (tj - ti)
    a0, a1 = cz * ux + sz * uy, -sz * ux + cz * uy
    w00, w01, w02 = om[:, 0, 0], om[:, 0, 1], om[:, 0, 2]
    w10, w11, w12 = om[:, 1, 0], om[:, 1, 1], om[:, 1, 2]
    w20, w21, w22 = om[:, 2, 0], om[:, 2, 1], om[:, 2, 2]
    # B^T Om B = [[M^T W M, M^T w], [w'^T M, om22]] with W the top left 2x2 of Om.
    t00, t01 = w00 * m00 + w01 * m10, w00 * m01 + w01 * m11  # W M
    t10, t11 = w10 * m00 + w11 * m10, w10 * m01 + w11 * m11
    hjj = np.empty((len(om), 3, 3))
    hjj[:, 0, 0] = m00 * t00 + m10 * t10
    hjj[:, 0, 1] = m00 * t01 + m10 * t11
    hjj[:, 1, 0] = m01 * t00 + m11 * t10
    hjj[:, 1, 1] = m01 * t01 + m11 * t11
    hjj[:, 0, 2] = m00 * w02 + m10 * w12
    hjj[:, 1, 2] = m01 * w02 + m11 * w12
    hjj[:, 2, 0] = w20 * m00 + w21 * m10
    hjj[:, 2, 1] = w20 * m01 + w21 * m11
    hjj[:, 2, 2] = w22
    u0, u1, u2 = w00 * a0 + w01 * a1, w10 * a0 + w11 * a1, w20 * a0 + w21 * a1
    c0, c1 = m00 * u0 + m10 * u1, m01 * u0 + m11 * u1  # c = B^T u, c2 = u2
    hij = -hjj
    hij[:, 2, 0] += c0
    hij[:, 2, 1] += c1
    hij[:, 2, 2] += u2
    hii = hjj.copy()
    hii[:, 0, 2] -= c0
    hii[:, 1, 2] -= c1
    hii[:, 2, 0] -= c0
    hii[:, 2, 1] -= c1
    hii[:, 2, 2] += a0 * u0 + a1 * u1 - 2.0 * u2
    q = (om @ e[:, :, None])[:, :, 0]  # Om e
    bj = np.empty((len(om), 3))
    bj[:, 0] = m00 * q[:, 0] + m10 * q[:, 1]
    bj[:, 1] = m01 * q[:, 0] + m11 * q[:, 1]
    bj[:, 2] = q[:, 2]
    bi = -bj
    bi[:, 2] += a0 * q[:, 0] + a1 * q[:, 1]
    return hii, hij, hjj, bi, bj


class _Pattern:
    """Where the 3x3 blocks of the edges go in the system of all nodes but node 0 (which is held
    fixed), worked out once per optimisation (on blocks, not entries): each iteration then only
    sums the values into place."""

    def __init__(self, I: np.ndarray[Any, Any], J: np.ndarray[Any, Any], n: int) -> None:  # noqa: E741
        nodes = np.arange(n)
        # The blocks (row node, column node) of H_ii, H_ij, H_ji, H_jj of each edge, and each
        # node's own diagonal block (the damping).
        br = np.concatenate([I, I, J, J, nodes])
        bc = np.concatenate([I, J, I, J, nodes])
        self._keep = (br > 0) & (bc > 0)
        uniq, slot = np.unique(bc[self._keep] * n + br[self._keep], return_inverse=True)
        ub = len(uniq)
        col, row = uniq // n - 1, uniq % n - 1  # block column major, then row (nodes 1..n-1)
        # Every node has its diagonal block: each block column holds at least one block.
        g0 = np.searchsorted(col, np.arange(n - 1))
        cnt = np.diff(np.append(g0, ub))
        r3 = np.arange(3)
        gc, cc = g0[col][:, None, None], cnt[col][:, None, None]
        # Entry (block u, r, c) sits at 9 g0 + 3 c cnt + 3 (u - g0) + r of the CSC data.
        pos = 9 * gc + 3 * r3[None, None, :] * cc + 3 * (np.arange(ub)[:, None, None] - gc)
        pos = pos + r3[None, :, None]
        self._order = np.empty(9 * ub, dtype=np.int64)
        self._order[pos.ravel()] = np.arange(9 * ub)
        self._slot = (slot[:, None] * 9 + np.arange(9)).ravel()
        self._indices = np.empty(9 * ub, dtype=np.int32)
        self._indices[pos.ravel()] = np.broadcast_to(
            3 * row[:, None, None] + r3[None, :, None], (ub, 3, 3)
        ).ravel()
        starts = 9 * g0[:, None] + 3 * r3[None, :] * cnt[:, None]
        self._indptr = np.append(starts.ravel(), 9 * ub).astype(np.int32)
        # A tiny damping on the diagonal keeps disconnected pieces solvable.
        self._damping = np.broadcast_to(np.eye(3) * 1e-9, (n, 3, 3))
        self._size = 9 * ub
        self._m = 3 * (n - 1)
        vi = (3 * I[:, None] + r3).ravel() - 3
        vj = (3 * J[:, None] + r3).ravel() - 3
        self._v = np.concatenate([vi, vj])
        self._vkeep = self._v >= 0

    def matrix(self, hii: FloatArray, hij: FloatArray, hjj: FloatArray) -> Any:
        """The ``csc_matrix`` of the blocks (E, 3, 3) of each edge (i, j) and the damping."""
        from scipy.sparse import csc_matrix

        vals = np.concatenate([hii, hij, hij.transpose(0, 2, 1), hjj, self._damping])[self._keep]
        sums = np.bincount(self._slot, weights=vals.ravel(), minlength=self._size)
        return csc_matrix(
            (sums[self._order], self._indices, self._indptr), shape=(self._m, self._m)
        )

    def vector(self, bi: FloatArray, bj: FloatArray) -> FloatArray:
        """The right-hand side from each edge's (E, 3) parts at node i and node j."""
        vals = np.concatenate([bi.ravel(), bj.ravel()])
        out = np.bincount(self._v[self._vkeep], weights=vals[self._vkeep], minlength=self._m)
        return np.asarray(out, dtype=np.float64)
