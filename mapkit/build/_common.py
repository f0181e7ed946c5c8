"""What the stages of a build share: pose units, submaps of recent scans, points in the world
frame."""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from typing import Any

import numpy as np

from mapkit.build._match import transform, voxel_keep

FloatArray = np.ndarray[Any, np.dtype[np.float64]]
#: progress(done, total): called as scans are registered.
Progress = Callable[[int, int], None]


def _deg(p: FloatArray) -> FloatArray:
    out = np.array(p, dtype=np.float64)
    out[..., 2] = np.degrees(out[..., 2])
    return out


def _rad(p: Any) -> FloatArray:
    out = np.array(p, dtype=np.float64)
    out[..., 2] = np.radians(out[..., 2])
    return out


class _Submap:
    """The local map scans are registered against: recent scans, thinned, with normals."""

    def __init__(self, voxel: float) -> None:
        self.voxel = voxel
        self.tree: Any = None
        self.pts = np.zeros((0, 2))
        self.nrm = np.zeros((0, 2))
        self._cache: dict[int, tuple[tuple[float, ...], FloatArray, FloatArray]] = {}

    def rebuild(
        self, idx: Iterable[int], pts: list[FloatArray], nrm: list[FloatArray], poses: FloatArray
    ) -> None:
        from scipy.spatial import cKDTree

        cache: dict[int, tuple[tuple[float, ...], FloatArray, FloatArray]] = {}
        for k in idx:
            key = tuple(poses[k].tolist())
            hit = self._cache.get(k)
            if hit is None or hit[0] != key:
                hit = (key, *_world(pts[k], nrm[k], poses[k]))
            cache[k] = hit
        self._cache = cache
        self.pts, self.nrm = _thinned(
            [h[1] for h in cache.values()], [h[2] for h in cache.values()], self.voxel
        )
        self.tree = (
            cKDTree(self.pts, balanced_tree=False, compact_nodes=False) if len(self.pts) else None
        )


def _world(pts: FloatArray, nrm: FloatArray, pose: FloatArray) -> tuple[FloatArray, FloatArray]:
    """A scan's points that have a normal, and the normals, in the world through ``pose``."""
    good = np.isfinite(nrm[:, 0])
    c, s = math.cos(pose[2]), math.sin(pose[2])
    return transform(pts[good], pose), nrm[good] @ np.array([[c, s], [-s, c]])


def _thinned(
    P: list[FloatArray], N: list[FloatArray], voxel: float
) -> tuple[FloatArray, FloatArray]:
    """Points (and normals) of several scans together, one per ``voxel`` cell."""
    if not P:
        return np.zeros((0, 2)), np.zeros((0, 2))
    p, n = np.concatenate(P), np.concatenate(N)
    keep = voxel_keep(p, voxel)
    return p[keep], n[keep]
