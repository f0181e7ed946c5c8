"""Small helpers shared by the raster tests."""

from __future__ import annotations

import numpy as np


def off_corners(g, xy: np.ndarray) -> np.ndarray:
    """Drop samples that sit exactly on a cell corner: a segment through a corner only touches
    the cells beside it at a point, it crosses none of them."""
    (ox, oy), r = g.origin_mm, g.resolution_mm
    u, v = (xy[:, 0] - ox) / r, (xy[:, 1] - oy) / r
    return xy[~((u == np.round(u)) & (v == np.round(v)))]


def dense(seg: np.ndarray, n: int = 4001) -> np.ndarray:
    """Points along each segment ``(M, 4)``, including both ends."""
    t = np.linspace(0.0, 1.0, n)[None, :, None]
    seg = np.asarray(seg, dtype=np.float64)
    a, b = seg[:, None, 0:2], seg[:, None, 2:4]
    return (a + t * (b - a)).reshape(-1, 2)


def covered(g, mask: np.ndarray, xy: np.ndarray, eps_cells: float = 1e-7) -> np.ndarray:
    """Whether each point's cell is marked, allowing float rounding at cell borders: a point
    within ``eps_cells`` of a border also counts when the cell across it is marked."""
    r = g.resolution_mm
    ok = np.zeros(len(xy), dtype=bool)
    for dx in (-eps_cells * r, 0.0, eps_cells * r):
        for dy in (-eps_cells * r, 0.0, eps_cells * r):
            rc = g.world_to_cell(xy + np.array([dx, dy]))
            inside = g.inside(rc)
            hit = np.zeros(len(xy), dtype=bool)
            hit[inside] = mask[rc[inside, 0], rc[inside, 1]]
            ok |= hit | ~inside
    return ok
