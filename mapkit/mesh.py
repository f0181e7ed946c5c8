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

import math
import os
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from mapkit._atomic import atomic_write
from mapkit._text import plural
from mapkit._typing import PathLike
from mapkit.errors import MapkitError, UnsupportedFormatError
from mapkit.formats.registry import register_writer
from mapkit.model import MapData

if TYPE_CHECKING:
    import trimesh

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

#: Mesh formats by file suffix (trimesh's exporters; ``.dae`` uses pycollada).
MESH_FORMATS = {".stl": "stl", ".obj": "obj", ".glb": "glb", ".dae": "dae"}

#: How far (m) the merged footprint is grown so that parts touching at a single corner fuse: a
#: corner shared by two parts would make the mesh non-manifold there. 0.1 mm changes no wall.
_FUSE = 1e-4


class MeshError(MapkitError, ValueError):
    """A mesh could not be made: nothing to extrude, or a bad height, thickness or resolution."""


@dataclass(frozen=True, slots=True)
class HomePose:
    """Where the robot starts, in metres and radians (ROS/Gazebo units).

    Attributes:
        type: The object's type (``RobotHome`` or ``Dock``).
        name: Its name.
        x: X in metres.
        y: Y in metres.
        yaw: Heading in radians.
    """

    type: str
    name: str
    x: float
    y: float
    yaw: float


@dataclass(frozen=True, slots=True)
class MeshExport:
    """What :func:`export_mesh` wrote.

    Attributes:
        path: The mesh file.
        format: ``stl``, ``obj``, ``glb`` or ``dae``.
        world: The SDF world file, or ``None``.
        source: What the walls were made from: ``"lines"`` or ``"points"``.
        vertices: Number of vertices.
        faces: Number of triangles.
        watertight: The mesh is closed.
        volume: Wall volume in cubic metres.
        bounds: ``((xmin, ymin, zmin), (xmax, ymax, zmax))`` in metres.
        home: The robot's home pose noted in the world file, if the map has one.
    """

    path: str
    format: str
    world: str | None
    source: str
    vertices: int
    faces: int
    watertight: bool
    volume: float
    bounds: tuple[tuple[float, float, float], tuple[float, float, float]]
    home: HomePose | None


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
        raise MeshError(f"{where} has no {source.upper() if source == 'lines' else source} "
                        f"to make walls from ({plural(n_points, 'point')}, "
                        f"{plural(n_lines, 'line')})")
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
    grid = grid_for_bounds(((float(lo[0]), float(lo[1])), (float(hi[0]), float(hi[1]))),
                           resolution, 0.0)
    occ = burn_points(grid, points_mm)
    padded = np.zeros((occ.shape[0], occ.shape[1] + 2), dtype=np.int8)
    padded[:, 1:-1] = occ
    step = np.diff(padded, axis=1)
    rows, starts = np.nonzero(step == 1)
    _, ends = np.nonzero(step == -1)  # same order: both scan the rows in turn
    (ox, oy), r = grid.origin_mm, grid.resolution_mm
    return shapely.box((ox + starts * r) / 1000.0, (oy + rows * r) / 1000.0,
                       (ox + ends * r) / 1000.0, (oy + (rows + 1) * r) / 1000.0)


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
    vertices = np.concatenate([np.column_stack([verts, np.zeros(n)]),
                               np.column_stack([verts, np.full(n, float(height))])])
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
            return HomePose(o.type, o.name, float(cx) / 1000.0, float(cy) / 1000.0,
                            math.radians(o.theta))
    return None


def _comment_text(s: str) -> str:
    """Text safe inside an XML comment (no ``--``, no undecodable bytes, no control chars)."""
    s = s.encode("utf-8", "surrogateescape").decode("utf-8", "replace")
    s = "".join(ch if ch >= " " or ch in "\t\n" else " " for ch in s)
    while "--" in s:
        s = s.replace("--", "- -")
    return s.rstrip("-")


def _quoted(name: str) -> str:
    return f'"{name}"' if name else "(unnamed)"


def _sub(parent: ET.Element, tag: str, text: str | None = None, **attrib: str) -> ET.Element:
    el = ET.SubElement(parent, tag, attrib)
    if text is not None:
        el.text = text
    return el


def _mesh_geometry(parent: ET.Element, uri: str) -> None:
    _sub(_sub(_sub(parent, "geometry"), "mesh"), "uri", uri)


def world_sdf(
    mesh_uri: str,
    *,
    bounds: tuple[tuple[float, float, float], tuple[float, float, float]] | None = None,
    home: HomePose | None = None,
    name: str = "mapkit",
    source: str | None = None,
) -> str:
    """A Gazebo SDF 1.7 world with the walls mesh as a static model.

    The world has a sun, a ground plane (sized to ``bounds`` when given) and the walls model
    whose collision and visual both use ``mesh_uri``. A relative URI is resolved against the
    world file's folder by Gazebo classic (11.2 and later) and Gazebo Sim. The robot's home pose
    is written as a comment with an ``<include>`` block ready to paste.

    Args:
        mesh_uri: The mesh's URI as the world should name it (``walls.stl``,
            ``file:///abs/walls.dae``, ``model://...``).
        bounds: The mesh's bounds in metres, for the ground plane's size and position.
        home: The robot's home pose, if known.
        name: The world's name.
        source: Where the map came from (noted in a comment).

    Returns:
        The SDF document.

    Examples:
        >>> import xml.etree.ElementTree as ET
        >>> doc = ET.fromstring(world_sdf("walls.stl", home=HomePose("RobotHome", "Home", 1, 2, 0)))
        >>> doc.find("world/model[@name='walls']/link/collision/geometry/mesh/uri").text
        'walls.stl'
    """
    root = ET.Element("sdf", {"version": "1.7"})
    world = _sub(root, "world", name=name)
    world.append(ET.Comment(_comment_text(
        f" Made by mapkit{' from ' + source if source else ''}. Units: metres, radians; "
        f"the map's origin is the world's origin. ")))
    if home is None:
        world.append(ET.Comment(" The map has no RobotHome or Dock: no start pose for the robot. "))
    else:
        pose = f"{home.x:.3f} {home.y:.3f} 0 0 0 {home.yaw:.4f}"
        world.append(ET.Comment(_comment_text(
            f" Robot home: {home.type} {_quoted(home.name)} at x={home.x:.3f} m, y={home.y:.3f} m, "
            f"yaw={home.yaw:.4f} rad ({math.degrees(home.yaw):.1f} deg). To start a robot "
            f"there, add to this world:\n      <include>\n        <uri>model://YOUR_ROBOT</uri>"
            f"\n        <pose>{pose}</pose>\n      </include>\n    ")))
    sun = _sub(world, "light", type="directional", name="sun")
    _sub(sun, "cast_shadows", "true")
    _sub(sun, "pose", "0 0 10 0 0 0")
    _sub(sun, "diffuse", "0.8 0.8 0.8 1")
    _sub(sun, "specular", "0.2 0.2 0.2 1")
    _sub(sun, "direction", "-0.5 0.1 -0.9")
    if bounds is not None:
        (x0, y0, _), (x1, y1, _) = bounds
        cx, cy = (x0 + x1) / 2, (y0 + y1) / 2
        size = f"{x1 - x0 + 10:.3f} {y1 - y0 + 10:.3f}"
    else:
        cx = cy = 0.0
        size = "100 100"
    ground = _sub(world, "model", name="ground_plane")
    _sub(ground, "static", "true")
    _sub(ground, "pose", f"{cx:.3f} {cy:.3f} 0 0 0 0")
    link = _sub(ground, "link", name="link")
    for kind in ("collision", "visual"):
        el = _sub(link, kind, name=kind)
        plane = _sub(_sub(el, "geometry"), "plane")
        _sub(plane, "normal", "0 0 1")
        _sub(plane, "size", size)
        if kind == "visual":
            mat = _sub(el, "material")
            _sub(mat, "ambient", "0.8 0.8 0.8 1")
            _sub(mat, "diffuse", "0.8 0.8 0.8 1")
    walls = _sub(world, "model", name="walls")
    _sub(walls, "static", "true")
    _sub(walls, "pose", "0 0 0 0 0 0")
    link = _sub(walls, "link", name="link")
    _mesh_geometry(_sub(link, "collision", name="collision"), mesh_uri)
    visual = _sub(link, "visual", name="visual")
    _mesh_geometry(visual, mesh_uri)
    mat = _sub(visual, "material")
    _sub(mat, "ambient", "0.6 0.6 0.65 1")
    _sub(mat, "diffuse", "0.7 0.7 0.75 1")
    ET.indent(root, space="  ")
    return '<?xml version="1.0" ?>\n' + ET.tostring(root, encoding="unicode") + "\n"


#: The walls' colour in the mesh files that carry one (GLB, DAE), RGBA.
WALL_COLOR = (178, 178, 188, 255)


def _mesh_bytes(mesh: trimesh.Trimesh, fmt: str) -> bytes:
    """The mesh file's bytes.

    STL, OBJ and GLB keep the welded (watertight) vertices; OBJ and GLB carry no normals, so
    viewers shade each triangle flat (glTF requires it). COLLADA always carries vertex normals,
    so each triangle gets its own vertices there (flat shading again), and the file says its
    units are metres and z is up (trimesh writes y up, which would stand the walls on their side).
    """
    from trimesh.visual import ColorVisuals

    data: Any
    if fmt == "stl":
        data = mesh.export(file_type="stl")
        return bytes(data)
    if fmt == "obj":  # no colour: OBJ would get non-standard per-vertex colours
        data = mesh.export(file_type="obj", include_normals=False)
        return data.encode("utf-8") if isinstance(data, str) else bytes(data)
    mesh = mesh.copy()
    mesh.visual = ColorVisuals(mesh, face_colors=np.tile(WALL_COLOR, (len(mesh.faces), 1)))
    if fmt == "dae":
        mesh.unmerge_vertices()
        data = mesh.export(file_type="dae")
        text = data.decode("utf-8") if isinstance(data, bytes) else data
        fixed = text.replace("<up_axis>Y_UP</up_axis>",
                             '<unit name="meter" meter="1"/>\n    <up_axis>Z_UP</up_axis>', 1)
        if fixed == text:
            raise MeshError("cannot write COLLADA: the exporter's <up_axis> was not found")
        return fixed.encode("utf-8")
    data = mesh.export(file_type="glb", include_normals=False)
    return bytes(data)


def _mesh_format(path: PathLike) -> str:
    suffix = os.path.splitext(os.fspath(path))[1].lower()
    fmt = MESH_FORMATS.get(suffix)
    if fmt is None:
        raise UnsupportedFormatError(
            f"cannot write a mesh to {os.fspath(path)!r}: meshes are "
            f"{', '.join(MESH_FORMATS)}, not {suffix or '(no suffix)'!r}")
    return fmt


def export_mesh(
    m: MapData,
    path: PathLike,
    *,
    height: float = 2.0,
    thickness: float = 0.1,
    source: str = "auto",
    resolution: float = 0.05,
    world: PathLike | None = None,
) -> MeshExport:
    """Write the map's walls as STL, OBJ, GLB or DAE (by suffix), and optionally a Gazebo world.

    Files are written atomically. The world names the mesh by its path relative to the world
    file's folder.

    Args:
        m: The map.
        path: The mesh file (``.stl``, ``.obj``, ``.glb`` or ``.dae``).
        height: Wall height in metres.
        thickness: Wall thickness in metres (walls from LINES).
        source: ``"lines"``, ``"points"`` or ``"auto"``.
        resolution: Grid cell size in metres (walls from points).
        world: Where to write the SDF world (``None``: no world).

    Returns:
        What was written.

    Raises:
        UnsupportedFormatError: When the suffix is not a mesh format.
        MeshError: When the map has nothing to make walls from, or a size is not positive.
        OSError: When a file cannot be written.
    """
    fmt = _mesh_format(path)
    mesh = wall_mesh(m, height=height, thickness=thickness, source=source, resolution=resolution)
    atomic_write(path, _mesh_bytes(mesh, fmt))
    bounds = tuple(tuple(float(v) for v in row) for row in mesh.bounds)
    home = home_pose(m)
    world_path = None
    if world is not None:
        world_path = os.fspath(world)
        folder = os.path.dirname(os.path.abspath(world_path))
        uri = os.path.relpath(os.path.abspath(os.fspath(path)), folder).replace(os.sep, "/")
        src = os.path.basename(m.provenance.source) if m.provenance else None
        stem = os.path.splitext(os.path.basename(world_path))[0] or "mapkit"
        text = world_sdf(uri, bounds=bounds, home=home, name=stem, source=src)  # type: ignore[arg-type]
        atomic_write(world_path, text.encode("utf-8"))
    return MeshExport(
        path=os.fspath(path), format=fmt, world=world_path, source=_pick_source(m, source),
        vertices=len(mesh.vertices), faces=len(mesh.faces), watertight=bool(mesh.is_watertight),
        volume=float(mesh.volume), bounds=bounds, home=home,  # type: ignore[arg-type]
    )


def _writer(m: MapData, path: PathLike) -> str:
    r = export_mesh(m, path)
    (x0, y0, _), (x1, y1, z1) = r.bounds
    return (f"wrote {r.path} ({r.format.upper()}, {r.faces} triangles, walls from {r.source}, "
            f"{x1 - x0:.2f} x {y1 - y0:.2f} x {z1:.2f} m)")


for _suffix in MESH_FORMATS:
    register_writer(_suffix, _writer)

