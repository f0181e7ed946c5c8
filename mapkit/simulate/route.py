"""Route planning on a coarse grid of the map, and driving the route with a robot's speed and
turn rate."""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from mapkit.errors import MapkitError
from mapkit.model import MapData
from mapkit.simulate.rays import FloatArray, segment_samples

# -- route planning on a coarse grid ---------------------------------------------------------------


@dataclass
class _Grid:
    origin: tuple[float, float]
    cell: float
    clearance: np.ndarray[Any, Any]  # mm to the nearest obstacle, per cell

    def index(self, xy: Sequence[float]) -> tuple[int, int]:
        i = round(float((xy[1] - self.origin[1]) / self.cell))
        j = round(float((xy[0] - self.origin[0]) / self.cell))
        h, w = self.clearance.shape
        return min(max(i, 0), h - 1), min(max(j, 0), w - 1)

    def center(self, i: int, j: int) -> tuple[float, float]:
        return self.origin[0] + j * self.cell, self.origin[1] + i * self.cell

    def clear_at(self, xy: FloatArray) -> FloatArray:
        i = np.clip(
            np.rint((xy[:, 1] - self.origin[1]) / self.cell).astype(int),
            0,
            self.clearance.shape[0] - 1,
        )
        j = np.clip(
            np.rint((xy[:, 0] - self.origin[0]) / self.cell).astype(int),
            0,
            self.clearance.shape[1] - 1,
        )
        return self.clearance[i, j]  # type: ignore[no-any-return]


def _obstacles(m: MapData) -> FloatArray:
    """Points along every wall (lines sampled every 50 mm) and the map's points."""
    parts = [m.points.astype(np.float64)]
    lines = m.lines.astype(np.float64)
    if len(lines):
        parts.append(segment_samples(lines, 50.0)[0])
    return np.concatenate(parts) if parts else np.zeros((0, 2))


def _grid(m: MapData, cell: float) -> _Grid:
    from scipy import ndimage

    obs = _obstacles(m)
    if len(obs) == 0:
        raise MapkitError(
            "the map has neither points nor lines: there is nothing to simulate a laser against"
        )
    lo = obs.min(axis=0) - 2000.0
    hi = obs.max(axis=0) + 2000.0
    shape = (int((hi[1] - lo[1]) / cell) + 2, int((hi[0] - lo[0]) / cell) + 2)
    occ = np.zeros(shape, dtype=bool)
    i = np.rint((obs[:, 1] - lo[1]) / cell).astype(int)
    j = np.rint((obs[:, 0] - lo[0]) / cell).astype(int)
    occ[i, j] = True
    clearance = ndimage.distance_transform_edt(~occ) * cell
    return _Grid((float(lo[0]), float(lo[1])), cell, clearance)


def _plan(
    grid: _Grid, a: Sequence[float], b: Sequence[float], radius: float
) -> list[tuple[float, float]]:
    """Shortest safe path from a to b (grid Dijkstra, then line-of-sight shortcuts)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import dijkstra

    free = grid.clearance > radius
    h, w = free.shape
    si, sj = _nearest_free(grid, free, a)
    gi, gj = _nearest_free(grid, free, b)
    ids = np.full(free.shape, -1, dtype=np.int64)
    ids[free] = np.arange(int(free.sum()))
    # Cost favours the middle of corridors: 1 at 1 m clearance or more, up to 3 near walls.
    cost = 1.0 + 2.0 * np.clip(1.0 - grid.clearance / 1000.0, 0.0, 1.0)
    rows, cols, vals = [], [], []
    for di, dj in ((0, 1), (1, 0), (1, 1), (1, -1)):
        sl_src = (slice(0, h - di), slice(max(0, -dj), w - max(0, dj)))
        sl_dst = (slice(di, h), slice(max(0, dj), w + min(0, dj)))
        src = free[sl_src]
        dst = free[sl_dst]
        both = src & dst
        rows.append(ids[sl_src][both])
        cols.append(ids[sl_dst][both])
        c = (cost[sl_src][both] + cost[sl_dst][both]) / 2.0
        vals.append(c * math.hypot(di, dj) * grid.cell)
    n = int(free.sum())
    graph = coo_matrix(
        (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(n, n)
    ).tocsr()
    start, goal = int(ids[si, sj]), int(ids[gi, gj])
    dist, pred = dijkstra(graph, directed=False, indices=start, return_predecessors=True)
    if not np.isfinite(dist[goal]):
        raise MapkitError(
            f"no path for the robot from ({a[0]:.0f}, {a[1]:.0f}) to "
            f"({b[0]:.0f}, {b[1]:.0f}) with {radius:.0f} mm clearance"
        )
    chain = [goal]
    while chain[-1] != start:
        chain.append(int(pred[chain[-1]]))
    chain.reverse()
    flat = np.flatnonzero(free.ravel())[chain]
    cells = np.stack(
        [grid.origin[0] + (flat % w) * grid.cell, grid.origin[1] + (flat // w) * grid.cell], axis=1
    )
    cells[0] = a[:2]
    cells[-1] = b[:2]
    # Greedy line-of-sight shortcuts.
    out = [tuple(cells[0])]
    k = 0
    while k < len(cells) - 1:
        nxt = k + 1
        for j in range(k + 2, len(cells)):
            if _visible(grid, cells[k], cells[j], radius):
                nxt = j
            elif j - nxt > 20:
                break
        out.append(tuple(cells[nxt]))
        k = nxt
    return [(float(x), float(y)) for x, y in out]


def _nearest_free(grid: _Grid, free: np.ndarray[Any, Any], xy: Sequence[float]) -> tuple[int, int]:
    i, j = grid.index(xy)
    if free[i, j]:
        return i, j
    fi, fj = np.nonzero(free)
    if len(fi) == 0:
        raise MapkitError("the map leaves no room for the robot to drive")
    k = int(np.argmin((fi - i) ** 2 + (fj - j) ** 2))
    return int(fi[k]), int(fj[k])


def _visible(grid: _Grid, a: FloatArray, b: FloatArray, radius: float) -> bool:
    n = max(int(math.hypot(b[0] - a[0], b[1] - a[1]) / (grid.cell / 2)), 2)
    t = np.linspace(0.0, 1.0, n)[:, None]
    pts = a[None, :] * (1 - t) + b[None, :] * t
    return bool(np.all(grid.clear_at(pts) > radius))


def _drive(
    path: list[tuple[float, float]], start_th: float, speed: float, turn_rate: float, dt: float
) -> Iterator[tuple[float, float, float]]:
    """True poses every ``dt``: turn in place towards each leg, then drive it."""
    x, y = path[0]
    th = start_th
    yield x, y, th
    for nx, ny in path[1:]:
        length = math.hypot(nx - x, ny - y)
        if length < 1.0:
            continue
        target = math.degrees(math.atan2(ny - y, nx - x))
        turn = (target - th + 180.0) % 360.0 - 180.0
        steps = int(abs(turn) / (turn_rate * dt))
        for _ in range(steps):
            th += math.copysign(turn_rate * dt, turn)
            yield x, y, th
        th = target
        steps = max(int(length / (speed * dt)), 1)
        x0, y0 = x, y
        for k in range(1, steps + 1):
            x = x0 + (nx - x0) * k / steps
            y = y0 + (ny - y0) * k / steps
            yield x, y, th
