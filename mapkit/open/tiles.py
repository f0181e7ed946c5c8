"""Image tiles of a scan for the map view: 256 px PNGs of points and lines, made with numpy.

The page's map (Leaflet, ``L.CRS.Simple``) counts one unit per millimetre: at zoom ``z`` a
millimetre is ``2**z`` pixels, x to the right and y up, so tile ``(z, tx, ty)`` covers
``x`` in ``[tx, tx + 1) * 256 / 2**z`` and ``y`` in ``(-(ty + 1), -ty] * 256 / 2**z``. A
million points cost one ``searchsorted`` and one ``bincount`` per tile.

Examples:
    >>> import numpy as np
    >>> t = TileSource(np.array([[0, 0], [100, -100]]), np.zeros((0, 4), dtype=np.int64))
    >>> png = t.render(0, 0, -1)
    >>> png[:8] == b"\\x89PNG\\r\\n\\x1a\\n"
    True
    >>> tile_bounds(0, 0, -1)
    (0.0, 0.0, 256.0, 256.0)
"""

from __future__ import annotations

import struct
import zlib
from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = ["TILE", "TileSource", "png_rgba", "tile_bounds"]

TILE = 256
POINT_RGBA = (25, 25, 25, 255)
LINE_RGBA = (30, 70, 190, 255)


def tile_bounds(z: int, tx: int, ty: int) -> tuple[float, float, float, float]:
    """World box ``(x0, y0, x1, y1)`` in mm that tile ``(z, tx, ty)`` covers."""
    size = TILE / 2.0**z
    return (tx * size, -(ty + 1) * size, (tx + 1) * size, -ty * size)


def png_rgba(rgba: NDArray[np.uint8]) -> bytes:
    """An ``(h, w, 4)`` uint8 image as PNG bytes (fast compression)."""
    h, w = rgba.shape[:2]
    raw = np.zeros((h, w * 4 + 1), dtype=np.uint8)
    raw[:, 1:] = rgba.reshape(h, w * 4)

    def chunk(kind: bytes, data: bytes) -> bytes:
        return (
            struct.pack(">I", len(data))
            + kind
            + data
            + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)
        )

    head = struct.pack(">IIBBBBB", w, h, 8, 6, 0, 0, 0)
    return (
        b"\x89PNG\r\n\x1a\n"
        + chunk(b"IHDR", head)
        + chunk(b"IDAT", zlib.compress(raw.tobytes(), 1))
        + chunk(b"IEND", b"")
    )


class TileSource:
    """Points and lines of one scan, indexed for drawing tiles.

    Args:
        points: ``(N, 2)`` mm.
        lines: ``(M, 4)`` mm.
        resolution: The scan's resolution in mm (points are drawn that wide, 1..4 px).
    """

    def __init__(self, points: NDArray[Any], lines: NDArray[Any], resolution: int = 20) -> None:
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        order = np.argsort(pts[:, 0], kind="stable")
        self._px = np.ascontiguousarray(pts[order, 0])
        self._py = np.ascontiguousarray(pts[order, 1])
        self._lines = np.asarray(lines, dtype=np.float64).reshape(-1, 4)
        self._lo = np.minimum(self._lines[:, [0, 1]], self._lines[:, [2, 3]])
        self._hi = np.maximum(self._lines[:, [0, 1]], self._lines[:, [2, 3]])
        self.resolution = max(1, int(resolution))

    def _point_mask(self, z: int, tx: int, ty: int) -> NDArray[np.bool_]:
        x0, y0, x1, y1 = tile_bounds(z, tx, ty)
        s = 2.0**z
        dot = int(min(4, max(1, round(self.resolution * s))))
        pad = dot / s
        a, b = np.searchsorted(self._px, [x0 - pad, x1])
        xs, ys = self._px[a:b], self._py[a:b]
        keep = (ys > y0) & (ys <= y1 + pad)
        col = np.floor(xs[keep] * s - tx * TILE).astype(np.int64)
        row = np.floor(-ys[keep] * s - ty * TILE).astype(np.int64)
        big = TILE + dot
        ok = (col >= -dot) & (col < TILE) & (row >= -dot) & (row < TILE)
        flat = (row[ok] + dot) * big + (col[ok] + dot)
        grid = np.bincount(flat, minlength=big * big).reshape(big, big) > 0
        out = np.zeros((TILE, TILE), dtype=np.bool_)
        for dy in range(dot):  # a dot `dot` px wide: OR of shifted copies
            for dx in range(dot):
                out |= grid[dot - dy : dot - dy + TILE, dot - dx : dot - dx + TILE]
        return out

    def _line_mask(self, z: int, tx: int, ty: int) -> NDArray[np.bool_]:
        x0, y0, x1, y1 = tile_bounds(z, tx, ty)
        s = 2.0**z
        sel = (
            (self._hi[:, 0] >= x0)
            & (self._lo[:, 0] <= x1)
            & (self._hi[:, 1] >= y0)
            & (self._lo[:, 1] <= y1)
        )
        out = np.zeros((TILE, TILE), dtype=np.bool_)
        segs = self._lines[sel]
        if not len(segs):
            return out
        # Clip each segment to the tile (grown a little) so a long wall costs only its visible part.
        c = (segs * np.array([s, -s, s, -s])) - np.array([tx, ty, tx, ty]) * TILE
        ax, ay, bx, by = c[:, 0], c[:, 1], c[:, 2], c[:, 3]
        dx, dy = bx - ax, by - ay
        t0, t1 = np.zeros(len(c)), np.ones(len(c))
        for p, q in ((-dx, ax + 1), (dx, TILE + 1 - ax), (-dy, ay + 1), (dy, TILE + 1 - ay)):
            with np.errstate(divide="ignore", invalid="ignore"):
                r = q / p
            t0 = np.where(p < 0, np.maximum(t0, r), t0)
            t1 = np.where(p > 0, np.minimum(t1, r), t1)
            t0 = np.where((p == 0) & (q < 0), 2.0, t0)
        vis = t0 <= t1
        ax, ay, dx, dy, t0, t1 = ax[vis], ay[vis], dx[vis], dy[vis], t0[vis], t1[vis]
        n = np.ceil(np.hypot(dx, dy) * (t1 - t0) * 2).astype(np.int64) + 1
        seg = np.repeat(np.arange(len(n)), n)
        first = np.cumsum(n) - n
        k = np.arange(int(n.sum())) - np.repeat(first, n)
        t = t0[seg] + (t1 - t0)[seg] * k / np.maximum(n[seg] - 1, 1)
        col = np.floor(ax[seg] + dx[seg] * t).astype(np.int64)
        row = np.floor(ay[seg] + dy[seg] * t).astype(np.int64)
        ok = (col >= 0) & (col < TILE) & (row >= 0) & (row < TILE)
        out[row[ok], col[ok]] = True
        return out

    def render(self, z: int, tx: int, ty: int) -> bytes:
        """The PNG of tile ``(z, tx, ty)``: points dark grey, lines blue, the rest transparent."""
        img = np.zeros((TILE, TILE, 4), dtype=np.uint8)
        img[self._point_mask(z, tx, ty)] = POINT_RGBA
        img[self._line_mask(z, tx, ty)] = LINE_RGBA
        return png_rgba(img)
