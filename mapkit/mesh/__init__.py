"""3D walls for simulators: the map's walls as a watertight mesh, and a Gazebo world that loads it.

Walls come from the LINES (each segment a box ``thickness`` wide, with square ends) or, for maps
with points only, from the occupied cells of the occupancy grid at ``resolution`` that
:mod:`mapkit.raster` makes (the cells ``mapkit rasterize`` marks). The boxes are merged in 2D
(shapely's union), triangulated (GEOS's constrained Delaunay triangulation, so no triangulation or
boolean engine is needed) and extruded to ``height``. The mesh is closed (watertight), its
outward normals point away from the wall material, and its units are metres, z up, with the
map's origin at (0, 0, 0).

:func:`world_sdf` writes a Gazebo SDF world (Gazebo classic 11 and Gazebo Sim) with the mesh as
a static model, a ground plane and a sun, and a note of the robot's home pose.

trimesh is imported inside the functions that use it.

Examples:
    >>> from mapkit.model import MapData, Scan
    >>> m = MapData(scans=(Scan.from_arrays(lines=[[0, 0, 4000, 0], [4000, 0, 4000, 3000]]),))
    >>> mesh = wall_mesh(m, height=2.0, thickness=0.1)
    >>> mesh.is_watertight, mesh.bounds[1].round(2).tolist()
    (True, [4.05, 3.05, 2.0])
"""

from __future__ import annotations

from mapkit.mesh.base import (
    MESH_FORMATS,
    HomePose,
    MeshError,
    MeshExport,
)
from mapkit.mesh.export import (
    WALL_COLOR as WALL_COLOR,
    export_mesh,
)
from mapkit.mesh.walls import (
    extrude,
    footprint,
    home_pose,
    wall_mesh,
)
from mapkit.mesh.world import (
    world_sdf,
)

__all__ = [
    "MESH_FORMATS",
    "HomePose",
    "MeshError",
    "MeshExport",
    "export_mesh",
    "extrude",
    "footprint",
    "home_pose",
    "wall_mesh",
    "world_sdf",
]
