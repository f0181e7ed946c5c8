"""Map → occupancy grid, and the vectorised drawing primitives it is made of.

Everything here takes millimetres (ARIA's unit) and produces :class:`OccupancyGrid` values in
ROS's layout (metres, row 0 south). No Python loop runs per point, per line or per cell: points,
segments and polygons are drawn with numpy in one pass each.

The primitives draw into boolean masks shaped like a grid (``(height, width)``, row 0 south):

* :func:`grid_for` / :func:`grid_for_bounds`: the empty (all unknown) grid covering a map.
* :func:`burn_points`: the cell under each point.
* :func:`burn_segments`: every cell a segment passes through (a "supercover": no gap at any
  angle, both end cells included).
* :func:`burn_polygons`: every cell whose centre lies in a convex polygon (rotated rectangles such
  as forbidden areas, see :func:`object_polygons`), plus every cell its outline crosses.
* :func:`inflate`: cells within a distance of a mask.
* :func:`flood_fill`: the 4-connected regions of a free mask that contain seed cells.
* :func:`hull_mask`: the cells inside the convex hull of a mask.

Examples:
    >>> from mapkit.model import MapData, MapObject, Scan
    >>> walls = [[0, 0, 1000, 0], [1000, 0, 1000, 1000], [1000, 1000, 0, 1000], [0, 1000, 0, 0]]
    >>> m = MapData(scans=(Scan.from_arrays(lines=walls),),
    ...             objects=(MapObject("RobotHome", 500, 500),))
    >>> g = rasterize(m, 0.1, margin_m=0.2)
    >>> g.width, g.height, g.origin
    (15, 15, (-0.2, -0.2))
    >>> g.counts()["occupied"], g.counts()["free"]
    (40, 81)
"""

from __future__ import annotations

import logging
import math
from collections.abc import Iterable
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from mapkit.model import MapData
from mapkit.raster.cells import (
    MAX_SIDE,
    _unknown_cells,
    grid_for,
    grid_for_bounds,
    map_bounds,
)
from mapkit.raster.errors import RasterError
from mapkit.raster.grid import FREE, OCCUPIED, UNKNOWN, OccupancyGrid
from mapkit.raster.primitives import (
    burn_points,
    burn_polygons,
    burn_segments,
    flood_fill,
    free_from_rays,
    hull_mask,
    inflate,
    object_polygons,
    segment_cells,
)

__all__ = [
    "MAX_CELLS",
    "MAX_SIDE",
    "FreeMode",
    "burn_points",
    "burn_polygons",
    "burn_segments",
    "check_options",
    "flood_fill",
    "free_from_rays",
    "grid_for",
    "grid_for_bounds",
    "hull_mask",
    "inflate",
    "map_bounds",
    "object_polygons",
    "rasterize",
    "rays_from_log",
    "seed_points",
    "segment_cells",
    "wall_mask",
]

log_ = logging.getLogger(__name__)


#: How to decide which cells are free (see :func:`rasterize`).
FreeMode = Literal["flood", "hull", "all", "none", "rays"]

#: The largest grid :func:`rasterize` makes as one whole-grid computation (cells); a larger one is
#: made band by band (:mod:`mapkit.raster.bands`, the same cells in bounded working memory).
MAX_CELLS = 100_000_000


# -- the map -----------------------------------------------------------------------------------

_SEED_TYPES = ("Goal", "Dock", "RobotHome")


def seed_points(m: MapData) -> NDArray[np.float64]:
    """Where the robot can be: goals, docks and homes (positions, or centres of home rectangles).

    Point objects of the built-in types ``Goal``/``GoalWithHeading``/``Dock``/``RobotHome`` and
    of any type declared as ``GoalType`` or ``DockType`` in ``MapInfo:``.

    Returns:
        ``(N, 2)`` x, y in mm.
    """
    declared = {k for k, v in m.declared_types().items() if v in ("GoalType", "DockType")}
    out = []
    for o in m.objects:
        if o.base_type in _SEED_TYPES or o.type in declared or o.base_type in declared:
            if o.from_to is None:
                out.append((o.x, o.y))
            else:
                c = np.array(o.corners())
                out.append(tuple(c.mean(axis=0)))
    arr = np.array(out, dtype=np.float64).reshape(-1, 2)
    return arr[np.all(np.isfinite(arr), axis=1)]


def _forbidden(m: MapData) -> tuple[list[NDArray[np.float64]], NDArray[np.float64]]:
    """Forbidden areas (polygons) and forbidden lines (segments) of a map."""
    areas = [o for o in m.objects if o.type == "ForbiddenArea" and m.object_shape(o) == "rect"]
    lines = [o.from_to for o in m.objects if o.type == "ForbiddenLine" and o.from_to is not None]
    return object_polygons(areas), np.array(lines, dtype=np.float64).reshape(-1, 4)


def wall_mask(
    m: MapData, grid: OccupancyGrid, *, forbidden_as_walls: bool = False
) -> NDArray[np.bool_]:
    """Cells holding a point or crossed by a line of any scan (and, optionally, forbidden zones)."""
    walls = np.zeros(grid.data.shape, dtype=bool)
    for scan in m.scans:
        burn_points(grid, scan.points, out=walls)
        burn_segments(grid, scan.lines, out=walls)
    if forbidden_as_walls:
        polys, segs = _forbidden(m)
        burn_polygons(grid, polys, out=walls)
        burn_segments(grid, segs, out=walls)
    return walls


def rays_from_log(log: Any, *, max_range: float = 16000.0) -> NDArray[np.float64]:
    """The beams of a ``.2d`` log as ``(K, 4)`` rays: laser origin and hit point, world mm.

    Each scan is placed at its ``robotGlobal:`` pose when the log has one (the localised pose),
    else at its odometry pose, so the log must be in the map's frame: recorded while the robot
    was localised on this map, or simulated from it. Beams without a return give no ray.

    Args:
        log: A path, the log's bytes, or a :class:`~mapkit.model.scan.LaserLog`.
        max_range: Readings farther than this (mm) are left out.

    Returns:
        The rays.

    Raises:
        LogFormatError: When the log cannot be read.
    """
    from mapkit.formats.laser2d import iter_log
    from mapkit.model.scan import LaserLog, LaserScan, LogRecord, laser_to_robot, robot_to_world

    records: Iterable[LogRecord]
    if isinstance(log, LaserLog):
        header, records = log.header, log.records
    else:
        reader = iter_log(log)
        header, records = reader.header, reader
    out: list[NDArray[np.float64]] = []
    for rec in records:
        if not isinstance(rec, LaserScan) or rec.xy is None:
            continue
        laser = header.laser(rec.laser)
        pose = rec.robot_global if rec.robot_global is not None else rec.robot
        hits = rec.global_points(laser, pose=pose, max_range=max_range)
        if len(hits) == 0:
            continue
        origin = robot_to_world(laser_to_robot(np.zeros((1, 2)), laser.pose), pose)[0]
        out.append(np.column_stack([np.broadcast_to(origin, hits.shape), hits]))
    return np.concatenate(out) if out else np.zeros((0, 4))


def check_options(
    free: str, inflate_mm: float, *, log: Any = None, rays_mm: ArrayLike | None = None
) -> tuple[FreeMode, NDArray[np.float64] | None]:
    """Check :func:`rasterize`'s free-space options; returns the free mode and the rays.

    A ``.2d`` ``log`` is read into rays (the mode is then ``"rays"``).

    Raises:
        RasterError: For a bad or inconsistent option.
    """
    if free not in ("flood", "hull", "all", "none", "rays"):
        raise RasterError(f"free must be one of flood, hull, all, none, rays; got {free!r}")
    if log is None and (free == "rays") != (rays_mm is not None):
        raise RasterError('free="rays" and rays_mm go together: give both or neither')
    if log is not None:
        if rays_mm is not None:
            raise RasterError("give a .2d log or rays_mm, not both")
        rays_mm, free = rays_from_log(log), "rays"
    if not (math.isfinite(inflate_mm) and inflate_mm >= 0):
        raise RasterError(f"inflation must be zero or more millimetres, got {inflate_mm!r}")
    rays = None if rays_mm is None else np.asarray(rays_mm, dtype=np.float64).reshape(-1, 4)
    return free, rays  # type: ignore[return-value]


def rasterize(
    m: MapData,
    resolution: float = 0.05,
    *,
    margin_m: float = 0.5,
    free: FreeMode = "flood",
    inflate_mm: float = 0,
    forbidden_as_walls: bool = False,
    log: Any = None,
    like: OccupancyGrid | None = None,
    rays_mm: ArrayLike | None = None,
) -> OccupancyGrid:
    """A map as an occupancy grid: walls occupied, reachable space free, the rest unknown.

    Occupied cells are those holding a point or crossed by a line of any scan (plus forbidden
    areas and lines with ``forbidden_as_walls``), grown by ``inflate_mm``. Free cells depend on
    ``free``:

    * ``"flood"`` (default): the 4-connected space reachable from the goals, docks and homes
      without crossing a wall, kept inside the convex hull of the walls (so a gap in a scanned
      wall does not make the whole margin free). A map without any such object falls back to
      ``"hull"`` (logged as a warning).
    * ``"hull"``: everything inside the convex hull of the walls.
    * ``"all"``: every cell that is not a wall.
    * ``"none"``: nothing (only walls and unknown).
    * ``"rays"``: the cells laser beams ``rays_mm`` pass through (see :func:`free_from_rays`).

    Args:
        m: The map.
        resolution: Metres per cell.
        margin_m: Unknown border added around the map's bounds, in metres.
        free: How free space is decided (see above).
        inflate_mm: Grow occupied cells by this radius (mm).
        forbidden_as_walls: Also mark forbidden areas and lines occupied.
        log: A ``.2d`` laser log (path or :class:`~mapkit.model.scan.LaserLog`) whose beams
            give the free space (``free`` is then ``"rays"``); see :func:`rays_from_log`.
        rays_mm: ``(K, 4)`` beams (sensor x, y, end x, y in mm) for ``free="rays"``, each ending
            on an obstacle.
        like: Use this grid's geometry (shape, resolution, origin) instead of one fitted to the
            map (``resolution`` and ``margin_m`` are then ignored); e.g. to compare two maps
            cell by cell, or to draw a mask on the same grid as a map.

    Returns:
        The grid (see :func:`grid_for` for its geometry). A grid of more than :data:`MAX_CELLS`
        cells is made band by band (:class:`mapkit.raster.bands.BandRaster`, the same cells):
        then only the result (one byte a cell) grows with the map.

    Raises:
        RasterError: For a bad option or a grid too large.
    """
    free, rays_mm = check_options(free, inflate_mm, log=log, rays_mm=rays_mm)
    if like is not None:
        grid = like.with_data(_unknown_cells(like.height, like.width))
    else:
        grid = grid_for(m, resolution, margin_m)
    if grid.width * grid.height > MAX_CELLS:
        from mapkit.raster.bands import BandRaster

        return BandRaster(
            m,
            free=free,
            inflate_mm=inflate_mm,
            rays_mm=rays_mm,
            like=grid,
            forbidden_as_walls=forbidden_as_walls,
        ).to_grid()
    walls = wall_mask(m, grid, forbidden_as_walls=forbidden_as_walls)
    open_ = ~walls
    if free == "flood":
        seeds = grid.world_to_cell(seed_points(m))
        reach = flood_fill(open_, seeds)
        if reach.any():
            space = reach & hull_mask(walls, seeds[grid.inside(seeds)])
        else:
            log_.warning("no goal, dock or home in free space to flood from: using the walls' hull")
            space = hull_mask(walls) & open_
    elif free == "hull":
        space = hull_mask(walls) & open_
    elif free == "all":
        space = open_
    elif free == "rays":
        space = free_from_rays(grid, np.asarray(rays_mm)) & open_
    else:
        space = np.zeros_like(walls)
    occupied = inflate(walls, inflate_mm, grid.resolution) if inflate_mm else walls
    data = np.full(walls.shape, UNKNOWN, dtype=np.int8)
    data[space] = FREE
    data[occupied] = OCCUPIED
    return grid.with_data(data)
