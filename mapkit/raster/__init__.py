"""Occupancy grids: rasterise ARIA maps, write/read ROS map_server maps, Nav2 filter masks.

The stable API other packages use:

* :class:`OccupancyGrid` (``mapkit.raster.grid``): int8 cells in ROS's layout (row 0 south),
  ``resolution`` in m, ``origin`` of the lower-left corner in m, ``world_to_cell`` /
  ``cell_to_world`` in mm.
* :func:`rasterize` and its primitives (``mapkit.raster.rasterize``): :func:`grid_for`,
  :func:`burn_points`, :func:`burn_segments`, :func:`burn_polygons`, :func:`inflate`,
  :func:`flood_fill`, :func:`hull_mask`, :func:`free_from_rays`.
* ``mapkit.raster.ros`` (map_server YAML + image, both ways), ``mapkit.raster.masks`` (Nav2
  keepout/speed masks), ``mapkit.raster.import_ros`` (ROS map → ARIA map),
  ``mapkit.raster.export`` (one call for ``mapkit rasterize``; registers ``.yaml``/``.pgm``).
* ``mapkit.raster.bands`` (:class:`~mapkit.raster.bands.BandRaster`: the same grid made band by
  band, for maps of any size) and ``mapkit.raster.image_stream`` (PGM/PNG written band by band).

Note: ``mapkit.raster.rasterize`` names the function (re-exported here), not the module; import
the module's names with ``from mapkit.raster.rasterize import ...``.
"""

from mapkit.raster.errors import RasterError, RosMapError
from mapkit.raster.grid import FREE, OCCUPIED, UNKNOWN, OccupancyGrid
from mapkit.raster.rasterize import (
    burn_points,
    burn_polygons,
    burn_segments,
    flood_fill,
    free_from_rays,
    grid_for,
    grid_for_bounds,
    hull_mask,
    inflate,
    map_bounds,
    object_polygons,
    rasterize,
    seed_points,
    segment_cells,
    wall_mask,
)

__all__ = [
    "FREE",
    "OCCUPIED",
    "UNKNOWN",
    "OccupancyGrid",
    "RasterError",
    "RosMapError",
    "burn_points",
    "burn_polygons",
    "burn_segments",
    "flood_fill",
    "free_from_rays",
    "grid_for",
    "grid_for_bounds",
    "hull_mask",
    "inflate",
    "map_bounds",
    "object_polygons",
    "rasterize",
    "seed_points",
    "segment_cells",
    "wall_mask",
]
