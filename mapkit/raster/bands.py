"""Rasterise maps of any size band by band, in working memory that grows with the band.

A 415 x 270 m warehouse at 2 cm is a 20,768 x 13,612 grid (282 M cells); the whole-grid
rasteriser (:func:`~mapkit.raster.rasterize.rasterize`) holds several bool and int32 arrays of
that shape. :class:`BandRaster` makes the same grid, cell for cell, one band of rows at a time
(about :data:`DEFAULT_BAND_CELLS` cells each), north to south as images are written, so a map of
any extent is written to a PGM or PNG (:mod:`mapkit.raster.image_stream`) without ever holding
the grid.

How each step stays exact:

* Walls (points, lines, forbidden zones drawn as walls) are drawn into each band with the
  primitives' ``row0`` argument: the cell of every point and segment is computed in the whole
  grid's coordinates and only the band's rows are kept. Points are sorted by y once so a band
  reads only its own points.
* ``free="flood"`` needs global connectivity: a first pass labels the open cells of every band
  (4-connected, :func:`scipy.ndimage.label`), joins the labels that touch across each band border
  and marks the ones holding a goal, dock or home; the second pass labels each band again (the
  same labels) and keeps the reached ones. The walls' convex hull is made from every row's first
  and last wall cell, collected in the first pass.
* Inflation reads the walls of a halo of ``ceil(radius) + 1`` rows around the band: every wall
  within the radius of a band cell is in the halo, so the distance test gives the same cells.
* Laser rays (``free="rays"``) are traced only in the bands their rows reach.

Examples:
    >>> from mapkit.model import MapData, MapObject, Scan
    >>> from mapkit.raster.rasterize import rasterize
    >>> walls = [[0, 0, 1000, 0], [1000, 0, 1000, 1000], [1000, 1000, 0, 1000], [0, 1000, 0, 0]]
    >>> m = MapData(scans=(Scan.from_arrays(lines=walls),),
    ...             objects=(MapObject("RobotHome", 500, 500),))
    >>> br = BandRaster(m, 0.1, margin_m=0.2, band_cells=30)
    >>> br.band_rows, [r0 for r0, _ in br.bands()]
    (2, [13, 11, 9, 7, 5, 3, 1, 0])
    >>> br.to_grid() == rasterize(m, 0.1, margin_m=0.2), br.counts()["free"]
    (True, 81)
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from mapkit.model import MapData
from mapkit.raster.cells import _unknown_cells, grid_for
from mapkit.raster.grid import FREE, OCCUPIED, UNKNOWN, OccupancyGrid
from mapkit.raster.primitives import (
    _convex_fill,
    _hull_polygon,
    _row_extremes,
    burn_points,
    burn_polygons,
    burn_segments,
    free_from_rays,
    inflate,
)
from mapkit.raster.rasterize import _forbidden, check_options, seed_points

__all__ = ["DEFAULT_BAND_CELLS", "BandRaster", "GridInfo", "band_spans", "halo_rows"]

log_ = logging.getLogger("mapkit.raster.rasterize")

#: Cells per band by default (4 M: a band's working arrays take some 60-100 MB).
DEFAULT_BAND_CELLS = 4_000_000

#: Called with the number of rows just finished (of :attr:`BandRaster.work_rows`).
Progress = Callable[[int], None]


@dataclass(frozen=True, slots=True)
class GridInfo:
    """The geometry and cell counts of a grid that was written, not kept.

    Has the parts of :class:`~mapkit.raster.grid.OccupancyGrid`'s API that need no cells:
    ``width``, ``height``, ``resolution``, ``origin``, ``bounds_mm()``, ``counts()`` and
    ``to_dict()``.
    """

    geometry: OccupancyGrid
    cell_counts: dict[str, int] = field(default_factory=dict)

    @property
    def width(self) -> int:
        """Number of columns."""
        return self.geometry.width

    @property
    def height(self) -> int:
        """Number of rows."""
        return self.geometry.height

    @property
    def resolution(self) -> float:
        """Metres per cell."""
        return self.geometry.resolution

    @property
    def origin(self) -> tuple[float, float]:
        """Lower-left corner of cell (0, 0) in metres."""
        return self.geometry.origin

    def bounds_mm(self) -> tuple[tuple[float, float], tuple[float, float]]:
        """The area covered, in millimetres."""
        return self.geometry.bounds_mm()

    def counts(self) -> dict[str, int]:
        """Number of occupied (> 50), free (0), unknown (< 0) and other cells."""
        return dict(self.cell_counts)

    def to_dict(self) -> dict[str, Any]:
        """Geometry and counts as JSON-ready data (as :meth:`OccupancyGrid.to_dict`)."""
        (x0, y0), (x1, y1) = self.bounds_mm()
        return {
            "width": self.width,
            "height": self.height,
            "resolution": self.resolution,
            "origin": [self.origin[0], self.origin[1], 0.0],
            "bounds_mm": [[x0, y0], [x1, y1]],
            **self.counts(),
        }


def band_spans(height: int, band_rows: int) -> list[tuple[int, int]]:
    """Row ranges ``[r0, r1)`` covering ``height`` rows, north (top rows) first.

    Examples:
        >>> band_spans(5, 2)
        [(3, 5), (1, 3), (0, 1)]
    """
    out = []
    r1 = height
    while r1 > 0:
        r0 = max(0, r1 - band_rows)
        out.append((r0, r1))
        r1 = r0
    return out


def halo_rows(inflate_mm: float, resolution: float) -> int:
    """Rows beyond a band that can hold a wall within ``inflate_mm`` of one of its cells."""
    if inflate_mm <= 0:
        return 0
    return math.ceil(inflate_mm / (resolution * 1000.0)) + 1


def count_cells(data: NDArray[np.int8], into: dict[str, int]) -> None:
    """Add a band's occupied / free / unknown / other cell counts to ``into``."""
    occ = int(np.count_nonzero(data > 50))
    free = int(np.count_nonzero(data == 0))
    unk = int(np.count_nonzero(data < 0))
    for key, n in (
        ("occupied", occ),
        ("free", free),
        ("unknown", unk),
        ("other", int(data.size) - occ - free - unk),
    ):
        into[key] = into.get(key, 0) + n


class _Walls:
    """The map's wall geometry, indexed by rows so each band draws only what reaches it."""

    def __init__(self, m: MapData, grid: OccupancyGrid, forbidden_as_walls: bool) -> None:
        self.grid = grid
        (_, self._oy), self._r = grid.origin_mm, grid.resolution_mm
        pts = [s.points for s in m.scans if len(s.points)]
        if pts:
            p = np.concatenate(pts) if len(pts) > 1 else pts[0]
            self.points = p[np.argsort(p[:, 1], kind="stable")]
        else:
            self.points = np.zeros((0, 2), dtype=np.int64)
        segs: list[NDArray[Any]] = [s.lines for s in m.scans if len(s.lines)]
        self.polys: list[NDArray[np.float64]] = []
        if forbidden_as_walls:
            self.polys, fsegs = _forbidden(m)
            segs.append(fsegs)
        seg = np.concatenate(segs).astype(np.float64) if segs else np.zeros((0, 4))
        self.segments = seg
        self._seg_lo, self._seg_hi = self._row_span(seg[:, 1], seg[:, 3])

    def _row_span(self, y1: NDArray[Any], y2: NDArray[Any]) -> tuple[NDArray[Any], NDArray[Any]]:
        lo = (np.minimum(y1, y2) - self._oy) / self._r
        hi = (np.maximum(y1, y2) - self._oy) / self._r
        return lo, hi

    def band(self, r0: int, r1: int) -> NDArray[np.bool_]:
        """The wall mask of rows ``[r0, r1)``, exactly as the whole grid's."""
        g = self.grid
        mask = np.zeros((r1 - r0, g.width), dtype=bool)
        ys = self.points[:, 1]
        i = int(np.searchsorted(ys, self._oy + (r0 - 1) * self._r, side="left"))
        j = int(np.searchsorted(ys, self._oy + (r1 + 1) * self._r, side="right"))
        burn_points(g, self.points[i:j], out=mask, row0=r0)
        near = (self._seg_hi >= r0 - 1) & (self._seg_lo < r1 + 1)
        if near.any():
            burn_segments(g, self.segments[near], out=mask, row0=r0)
        if self.polys:
            burn_polygons(g, self.polys, out=mask, row0=r0)
        return mask


class BandRaster:
    """A map's occupancy grid made band by band: the same cells as ``rasterize`` gives.

    Args:
        m: The map.
        resolution: Metres per cell.
        margin_m: Unknown border around the map's bounds, in metres.
        free: ``flood``, ``hull``, ``all``, ``none`` or ``rays`` (as :func:`rasterize`).
        inflate_mm: Grow occupied cells by this radius (mm).
        forbidden_as_walls: Also mark forbidden areas and lines occupied.
        log: A ``.2d`` laser log whose beams give the free space.
        rays_mm: ``(K, 4)`` beams for ``free="rays"``.
        like: Use this grid's geometry instead of one fitted to the map.
        band_cells: About how many cells a band holds (at least one row).

    Raises:
        RasterError: For a bad option.
    """

    def __init__(
        self,
        m: MapData,
        resolution: float = 0.05,
        *,
        margin_m: float = 0.5,
        free: str = "flood",
        inflate_mm: float = 0.0,
        forbidden_as_walls: bool = False,
        log: Any = None,
        rays_mm: ArrayLike | None = None,
        like: OccupancyGrid | None = None,
        band_cells: int = DEFAULT_BAND_CELLS,
    ) -> None:
        self.free, self._rays = check_options(free, inflate_mm, log=log, rays_mm=rays_mm)
        if like is not None:
            grid = like.with_data(_unknown_cells(like.height, like.width))
        else:
            grid = grid_for(m, resolution, margin_m)
        self.grid = grid
        self.inflate_mm = float(inflate_mm)
        self.band_rows = max(1, min(grid.height, int(band_cells) // grid.width))
        self._halo = halo_rows(self.inflate_mm, grid.resolution)
        self._walls = _Walls(m, grid, forbidden_as_walls)
        self._seeds = grid.world_to_cell(seed_points(m)) if self.free == "flood" else None
        self._prepared = False
        self._hull: NDArray[np.float64] | None = None
        self._reach: NDArray[np.bool_] | None = None  # per global label: reached by the flood
        self._offsets: list[int] = []
        self._counts: dict[str, int] = {}

    @property
    def spans(self) -> list[tuple[int, int]]:
        """The bands' row ranges ``[r0, r1)``, north first."""
        return band_spans(self.grid.height, self.band_rows)

    @property
    def work_rows(self) -> int:
        """Rows processed in all (for a progress bar): two passes for ``flood`` and ``hull``."""
        passes = 2 if self.free in ("flood", "hull") else 1
        return passes * self.grid.height

    def band_bytes(self) -> int:
        """An upper bound of the bytes one band's working arrays take (for tests and docs).

        The band with its inflation halo: bool walls, open and free masks (1 byte a cell each),
        int32 labels (4), the int8 result (1) and, when inflating, scipy's distance transform
        (float64 distances plus its int32 feature transform: 16 bytes a cell).
        """
        rows = self.band_rows + 2 * self._halo
        per_cell = 3 + 4 + 1 + (16 + 1 if self.inflate_mm > 0 else 0)
        return rows * self.grid.width * per_cell

    # -- pass 1: what needs the whole map (flood connectivity, the walls' hull) -------------------

    def _prepare(self, progress: Progress | None) -> None:
        if self._prepared:
            return
        self._prepared = True
        if self.free not in ("flood", "hull"):
            return
        from scipy import ndimage

        flood = self.free == "flood"
        extremes: list[NDArray[np.int64]] = []
        pairs: list[NDArray[np.int64]] = []
        seed_labels: list[NDArray[np.int64]] = []
        seeds = self._seeds if self._seeds is not None else np.zeros((0, 2), dtype=np.int64)
        on_grid = self.grid.inside(seeds)
        below: NDArray[np.int64] | None = None  # global labels of the previous band's south row
        offset = 0
        for r0, r1 in self.spans:
            walls = self._walls.band(r0, r1)
            extremes.append(_row_extremes(walls, r0))
            if flood:
                labels, n = ndimage.label(~walls)
                top = np.where(labels[-1] > 0, labels[-1] + offset, 0)
                if below is not None:
                    both = (top > 0) & (below > 0)
                    pairs.append(np.stack([top[both], below[both]], axis=1))
                below = np.where(labels[0] > 0, labels[0] + offset, 0)
                s = seeds[on_grid & (seeds[:, 0] >= r0) & (seeds[:, 0] < r1)]
                found = labels[s[:, 0] - r0, s[:, 1]]
                seed_labels.append(found[found > 0].astype(np.int64) + offset)
                self._offsets.append(offset)
                offset += int(n)
            del walls
            if progress is not None:
                progress(r1 - r0)
        seeded = np.concatenate(seed_labels) if seed_labels else np.zeros(0, dtype=np.int64)
        if flood and len(seeded):
            self._hull = _hull_polygon(extremes, seeds[on_grid])
            self._reach = _reached(offset, pairs, seeded)
        else:
            if flood:
                log_.warning(
                    "no goal, dock or home in free space to flood from: using the walls' hull"
                )
            self._hull = _hull_polygon(extremes)

    # -- pass 2: the cells -------------------------------------------------------------------

    def _space(self, k: int, r0: int, walls: NDArray[np.bool_]) -> NDArray[np.bool_]:
        """Free cells of band ``k`` (rows from ``r0``) before walls are put on top."""
        open_ = ~walls
        if self.free in ("flood", "hull"):
            hull = np.zeros_like(walls)
            if self._hull is not None:
                _convex_fill(hull, self._hull[None], r0)
            if self._reach is not None:
                from scipy import ndimage

                labels, n = ndimage.label(open_)
                off = self._offsets[k]
                lut = self._reach[off : off + n + 1].copy()
                lut[0] = False
                reach: NDArray[np.bool_] = lut[labels]
                return reach & hull
            return hull & open_
        if self.free == "all":
            return open_
        if self.free == "rays":
            rays = self._rays if self._rays is not None else np.zeros((0, 4))
            return free_from_rays(self.grid, rays, out=np.zeros_like(walls), row0=r0) & open_
        return np.zeros_like(walls)

    def bands(self, progress: Progress | None = None) -> Iterator[tuple[int, NDArray[np.int8]]]:
        """The grid's cells band by band, north first: ``(row0, data)``.

        ``data`` is ``(rows, width)`` int8 in the grid's layout (``data[0]`` is row ``row0``, the
        band's southern row). Cell counts are summed as the bands go (:meth:`counts`).
        """
        self._prepare(progress)
        h, halo = self.grid.height, self._halo
        self._counts = {}
        for k, (r0, r1) in enumerate(self.spans):
            a, b = max(0, r0 - halo), min(h, r1 + halo)
            window = self._walls.band(a, b)
            walls = window[r0 - a : r1 - a]
            space = self._space(k, r0, walls)
            if self.inflate_mm:
                occupied = inflate(window, self.inflate_mm, self.grid.resolution)[r0 - a : r1 - a]
            else:
                occupied = walls
            data = np.full(walls.shape, UNKNOWN, dtype=np.int8)
            data[space] = FREE
            data[occupied] = OCCUPIED
            del window, walls, space, occupied
            count_cells(data, self._counts)
            if progress is not None:
                progress(r1 - r0)
            yield r0, data

    def counts(self) -> dict[str, int]:
        """Cell counts of the bands made so far (all of them after :meth:`bands` ran through)."""
        return dict(self._counts)

    def info(self) -> GridInfo:
        """The geometry and the counts (after :meth:`bands` ran through)."""
        return GridInfo(self.grid, self.counts())

    def to_grid(self, progress: Progress | None = None) -> OccupancyGrid:
        """The whole grid in memory (one byte a cell plus one band's working arrays)."""
        g = self.grid
        data = np.empty((g.height, g.width), dtype=np.int8)
        for r0, band in self.bands(progress):
            data[r0 : r0 + len(band)] = band
        data.flags.writeable = False  # OccupancyGrid keeps a read-only array without a copy
        return OccupancyGrid(data, g.resolution, g.origin)


def _reached(
    n_labels: int, pairs: list[NDArray[np.int64]], seeded: NDArray[np.int64]
) -> NDArray[np.bool_]:
    """Per global label (0..n_labels): whether its joined region holds a seed."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    edges = np.concatenate(pairs) if pairs else np.zeros((0, 2), dtype=np.int64)
    size = n_labels + 1
    graph = coo_matrix(
        (np.ones(len(edges), dtype=np.int8), (edges[:, 0], edges[:, 1])), shape=(size, size)
    )
    _, comp = connected_components(graph, directed=False)
    hit = np.zeros(int(comp.max()) + 1, dtype=bool)
    hit[comp[seeded]] = True
    reach: NDArray[np.bool_] = hit[comp]
    reach[0] = False
    return reach
