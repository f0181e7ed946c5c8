"""Writing meshes (STL, OBJ, GLB, DAE) and their Gazebo world, and the writer registered for
``mapkit convert``."""

from __future__ import annotations

import os
from typing import TYPE_CHECKING, Any

import numpy as np

from mapkit._atomic import atomic_write
from mapkit._typing import PathLike
from mapkit.errors import UnsupportedFormatError
from mapkit.formats.registry import register_writer
from mapkit.mesh.base import MESH_FORMATS, MeshError, MeshExport
from mapkit.mesh.walls import _pick_source, home_pose, wall_mesh
from mapkit.mesh.world import world_sdf
from mapkit.model import MapData

if TYPE_CHECKING:
    import trimesh

__all__ = ["WALL_COLOR", "export_mesh"]


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
        fixed = text.replace(
            "<up_axis>Y_UP</up_axis>",
            '<unit name="meter" meter="1"/>\n    <up_axis>Z_UP</up_axis>',
            1,
        )
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
            f"{', '.join(MESH_FORMATS)}, not {suffix or '(no suffix)'!r}"
        )
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
        path=os.fspath(path),
        format=fmt,
        world=world_path,
        source=_pick_source(m, source),
        vertices=len(mesh.vertices),
        faces=len(mesh.faces),
        watertight=bool(mesh.is_watertight),
        volume=float(mesh.volume),
        bounds=bounds,  # type: ignore[arg-type]
        home=home,
    )


def _writer(m: MapData, path: PathLike) -> str:
    r = export_mesh(m, path)
    (x0, y0, _), (x1, y1, z1) = r.bounds
    return (
        f"wrote {r.path} ({r.format.upper()}, {r.faces} triangles, walls from {r.source}, "
        f"{x1 - x0:.2f} x {y1 - y0:.2f} x {z1:.2f} m)"
    )


for _suffix in MESH_FORMATS:
    register_writer(_suffix, _writer)
