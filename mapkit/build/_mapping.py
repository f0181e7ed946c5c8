"""Free space seen by the laser: how often each map cell was looked *through*.

A wall is hit whenever it is in view; a person walking by, or a spurious reading, is hit once or
twice in a cell that other beams pass through many times. Counting, per cell of the map's lattice,
the beams that passed through it (from the laser to a little short of the hit) lets the map keep
only the cells whose hits are consistent with what the other scans saw.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

FloatArray = np.ndarray[Any, np.dtype[np.float64]]

#: At most this many beam samples are counted (beams are subsampled evenly beyond it).
MAX_SAMPLES = 4_000_000
#: Samples stop this many cells short of the hit (a wall seen at a glancing angle is not free).
STOP_CELLS = 2.5


def pass_counts(
    hits: FloatArray,
    origins: FloatArray,
    res: float,
    cells: np.ndarray[Any, Any],
    *,
    max_samples: int = MAX_SAMPLES,
    chunk: int = 2_000_000,
) -> FloatArray:
    """How many beams passed through each of ``cells`` (estimated when beams are subsampled).

    Args:
        hits: ``(N, 2)`` world hit points.
        origins: ``(N, 2)`` the laser's world position for each hit.
        res: Cell size (mm); cells are ``rint(xy / res)``.
        cells: ``(K, 2)`` integer cells to report.
        max_samples: Budget of samples along beams; beyond it every k-th beam is used and the
            counts scaled by k.
        chunk: Samples handled at once (memory).

    Returns:
        ``(K,)`` beams through each cell.
    """
    if len(hits) == 0 or len(cells) == 0:
        return np.zeros(len(cells))
    v = hits - origins
    length = np.hypot(v[:, 0], v[:, 1])
    m = np.maximum(np.floor(length / res - STOP_CELLS).astype(np.int64), 0)
    total = int(m.sum())
    every = max(1, math.ceil(total / max_samples))
    sel = np.arange(0, len(hits), every)
    sel = sel[m[sel] > 0]
    lo = cells.min(axis=0) - 1
    hi = cells.max(axis=0) + 1
    w, h = int(hi[0] - lo[0] + 1), int(hi[1] - lo[1] + 1)
    counts = np.zeros(w * h, dtype=np.int64)
    # Beams in batches of about `chunk` samples.
    cum = np.cumsum(m[sel])
    start = 0
    while start < len(sel):
        base = cum[start - 1] if start else 0
        stop = int(np.searchsorted(cum, base + chunk, side="right"))
        stop = max(stop, start + 1)
        b = sel[start:stop]
        mb = m[b]
        idx = np.repeat(np.arange(len(b)), mb)
        t = (np.arange(int(mb.sum())) - np.repeat(np.cumsum(mb) - mb, mb) + 1).astype(np.float64)
        u = v[b] / length[b, None]
        pts = origins[b][idx] + u[idx] * (t * res)[:, None]
        c = np.rint(pts / res).astype(np.int64)
        ok = (c[:, 0] >= lo[0]) & (c[:, 0] <= hi[0]) & (c[:, 1] >= lo[1]) & (c[:, 1] <= hi[1])
        flat = (c[ok, 0] - lo[0]) * h + (c[ok, 1] - lo[1])
        counts += np.bincount(flat, minlength=w * h)
        start = stop
    out: FloatArray = counts[(cells[:, 0] - lo[0]) * h + (cells[:, 1] - lo[1])].astype(np.float64)
    return out * every
