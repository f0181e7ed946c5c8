"""The walls as a mesh: 2D footprint from lines or occupied cells, triangulated and extruded."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np

from mapkit._text import plural
from mapkit.mesh.base import HomePose, MeshError
from mapkit.model import MapData

if TYPE_CHECKING:
    import trimesh

__all__ = ["extrude", "footprint", "home_pose", "wall_mesh"]

#: How far (m) the merged footprint is grown so that parts touching at a single corner fuse: a
#: corner shared by two parts would make the mesh non-manifold there. 0.1 mm changes no wall.
_FUSE = 1e-4


def _check_positive(**values: float) -> None:
    for name, v in values.items():
        if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
            raise MeshError(f"{name} must be a positive number of metres, got {v!r}")


def _pick_source(m: MapData, source: str) -> str:
    if source not in ("auto", "lines", "points"):
        raise MeshError(f"source must be 'auto', 'lines' or 'points', got {source!r}")
    n_lines = sum(s.num_lines for s in m.scans)
    n_points = sum(s.num_points for s in m.scans)
    if source == "auto":
        source = "lines" if n_lines else "points"
    if (source == "lines" and not n_lines) or (source == "points" and not n_points):
        where = m.provenance.source if m.provenance else "the map"
        raise MeshError(
            f"{where} has no {source.upper() if source == 'lines' else source} "
            f"to make walls from ({plural(n_points, 'point')}, "
            f"{plural(n_lines, 'line')})"
        )
    return source


def _segment_boxes(lines_mm: np.ndarray[Any, Any], thickness: float) -> Any:
    """One rectangle per segment (metres), ``thickness`` wide with square ends (shapely)."""
    import shapely

    seg = lines_mm.astype(np.float64).reshape(-1, 2, 2) / 1000.0
    d = seg[:, 1] - seg[:, 0]
    length = np.hypot(d[:, 0], d[:, 1])
    # Zero-length segments become squares along x.
    u = np.where(length[:, None] > 0, d / np.where(length > 0, length, 1.0)[:, None], [1.0, 0.0])
    n = np.stack([-u[:, 1], u[:, 0]], axis=1)
    h = thickness / 2.0
    a = seg[:, 0] - u * h
    b = seg[:, 1] + u * h
    ring = np.stack([a - n * h, b - n * h, b + n * h, a + n * h], axis=1)
    return shapely.polygons(ring)


def _cell_boxes(points_mm: np.ndarray[Any, Any], resolution: float) -> Any:
    """The occupied cells of the occupancy grid at ``resolution`` (m) that ``mapkit.raster``
    makes from the points (the same cells ``mapkit rasterize`` marks), merged into one rectangle
    per run of occupied cells along each row, as shapely polygons in metres."""
    import shapely

    from mapkit.raster import burn_points, grid_for_bounds

    lo, hi = points_mm.min(axis=0), points_mm.max(axis=0)
    grid = grid_for_bounds(
        ((float(lo[0]), float(lo[1])), (float(hi[0]), float(hi[1]))), resolution, 0.0
    )
    occ = burn_points(grid, points_mm)
    padded = np.zeros((occ.shape[0], occ.shape[1] + 2), dtype=np.int8)
    padded[:, 1:-1] = occ
    step = np.diff(padded, axis=1)
    rows, starts = np.nonzero(step == 1)
    _, ends = np.nonzero(step == -1)  # same order: both scan the rows in turn
    (ox, oy), r = grid.origin_mm, grid.resolution_mm
    return shapely.box(
        (ox + starts * r) / 1000.0,
        (oy + rows * r) / 1000.0,
        (ox + ends * r) / 1000.0,
        (oy + (rows + 1) * r) / 1000.0,
    )


def footprint(
    m: MapData, *, thickness: float = 0.1, source: str = "auto", resolution: float = 0.05
) -> Any:
    """The walls seen from above: a shapely (Multi)Polygon in metres.

    Args:
        m: The map.
        thickness: Wall thickness in metres (LINES only).
        source: ``"lines"``, ``"points"`` or ``"auto"`` (LINES when the map has any, else points).
        resolution: Grid cell size in metres (points only).

    Returns:
        The union of the wall boxes.

    Raises:
        MeshError: When the map has nothing to make walls from, or a size is not positive.
        RasterError: When the grid for walls from points would be too large.
    """
    import shapely

    _check_positive(thickness=thickness, resolution=resolution)
    src = _pick_source(m, source)
    if src == "lines":
        boxes = _segment_boxes(np.concatenate([s.lines for s in m.scans]), thickness)
    else:
        boxes = _cell_boxes(np.concatenate([s.points for s in m.scans]), resolution)
    merged = shapely.union_all(boxes)
    return merged.buffer(_FUSE, join_style="mitre")


def extrude(shape: Any, height: float) -> trimesh.Trimesh:
    """Extrude a shapely (Multi)Polygon from z = 0 to ``height`` into a closed mesh.

    The polygon is triangulated with GEOS's constrained Delaunay triangulation (holes kept), the
    triangles form the floor and the top, and every boundary edge gets a wall quad.

    Args:
        shape: A Polygon or MultiPolygon (metres).
        height: Extrusion height in metres.

    Returns:
        The mesh (watertight when the polygon is valid and no two parts touch at a corner).

    Raises:
        MeshError: When the height is not positive or the polygon is empty.

    Examples:
        >>> from shapely.geometry import box
        >>> m = extrude(box(0, 0, 2, 1).difference(box(0.5, 0.25, 1.5, 0.75)), 3.0)
        >>> m.is_watertight, round(float(m.volume), 6)  # (2 x 1 - 1 x 0.5) x 3
        (True, 4.5)
    """
    import shapely
    import trimesh

    _check_positive(height=height)
    if shape.is_empty:
        raise MeshError("nothing to extrude: the footprint is empty")
    tris = shapely.constrained_delaunay_triangles(shape)
    corners = shapely.get_coordinates(tris).reshape(-1, 4, 2)[:, :3]  # closed rings: drop 4th
    verts, inverse = np.unique(corners.reshape(-1, 2), axis=0, return_inverse=True)
    faces = inverse.reshape(-1, 3)
    a, b, c = verts[faces[:, 0]], verts[faces[:, 1]], verts[faces[:, 2]]
    cross = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
    faces = np.where((cross < 0)[:, None], faces[:, ::-1], faces)  # all counter-clockwise
    # Boundary edges: directed edges whose reverse is not in any triangle. With every triangle
    # counter-clockwise, the material lies to the left of each, so the outside is to the right.
    n = len(verts)
    edges = faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    key = edges[:, 0] * n + edges[:, 1]
    boundary = edges[~np.isin(key, edges[:, 1] * n + edges[:, 0])]
    i, j = boundary[:, 0], boundary[:, 1]
    walls = np.concatenate([np.stack([i, j, j + n], axis=1), np.stack([i, j + n, i + n], axis=1)])
    vertices = np.concatenate(
        [np.column_stack([verts, np.zeros(n)]), np.column_stack([verts, np.full(n, float(height))])]
    )
    all_faces = np.concatenate([faces[:, ::-1], faces + n, walls])
    return trimesh.Trimesh(vertices=vertices, faces=all_faces, process=False)


def wall_mesh(
    m: MapData,
    *,
    height: float = 2.0,
    thickness: float = 0.1,
    source: str = "auto",
    resolution: float = 0.05,
) -> trimesh.Trimesh:
    """The map's walls as a closed mesh in metres (z up, floor at z = 0).

    Args:
        m: The map.
        height: Wall height in metres.
        thickness: Wall thickness in metres (walls from LINES).
        source: ``"lines"``, ``"points"`` or ``"auto"`` (LINES when there are any, else points).
        resolution: Grid cell size in metres (walls from points).

    Returns:
        A :class:`trimesh.Trimesh`.

    Raises:
        MeshError: When the map has nothing to make walls from, or a size is not positive.
    """
    _check_positive(height=height)
    return extrude(footprint(m, thickness=thickness, source=source, resolution=resolution), height)


def home_pose(m: MapData) -> HomePose | None:
    """The robot's start pose: the first ``RobotHome``, else the first ``Dock`` (MobileSim's rule).

    A ``RobotHome`` area gives its centre and its angle.

    Examples:
        >>> from mapkit.model import MapObject
        >>> home_pose(MapData(objects=(MapObject("Dock", 1500, -500, 90, name="D"),)))
        HomePose(type='Dock', name='D', x=1.5, y=-0.5, yaw=1.5707963267948966)
    """
    for wanted in ("RobotHome", "Dock"):
        for o in m.objects:
            if o.base_type != wanted or not all(map(math.isfinite, (o.x, o.y, o.theta))):
                continue
            if o.from_to is not None:
                cx, cy = np.mean(np.asarray(o.corners()), axis=0)
            else:
                cx, cy = o.x, o.y
            return HomePose(
                o.type, o.name, float(cx) / 1000.0, float(cy) / 1000.0, math.radians(o.theta)
            )
    return None
