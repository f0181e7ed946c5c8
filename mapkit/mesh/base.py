"""What a mesh export is: formats, the robot's home pose, the result and the error."""

from __future__ import annotations

from dataclasses import dataclass

from mapkit.errors import MapkitError

__all__ = ["MESH_FORMATS", "HomePose", "MeshError", "MeshExport"]


#: Mesh formats by file suffix (trimesh's exporters; ``.dae`` uses pycollada).
MESH_FORMATS = {".stl": "stl", ".obj": "obj", ".glb": "glb", ".dae": "dae"}


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
