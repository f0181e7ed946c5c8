"""A Gazebo SDF world with the wall mesh as a static model, a ground plane, a sun and the robot's
home pose."""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET

from mapkit.mesh.base import HomePose

__all__ = ["world_sdf"]


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
    world.append(
        ET.Comment(
            _comment_text(
                f" Made by mapkit{' from ' + source if source else ''}. Units: metres, radians; "
                f"the map's origin is the world's origin. "
            )
        )
    )
    if home is None:
        world.append(ET.Comment(" The map has no RobotHome or Dock: no start pose for the robot. "))
    else:
        pose = f"{home.x:.3f} {home.y:.3f} 0 0 0 {home.yaw:.4f}"
        world.append(
            ET.Comment(
                _comment_text(
                    f" Robot home: {home.type} {_quoted(home.name)} at x={home.x:.3f} m, "
                    f"y={home.y:.3f} m, "
                    f"yaw={home.yaw:.4f} rad ({math.degrees(home.yaw):.1f} deg). To start a robot "
                    f"there, add to this world:\n      <include>\n        <uri>model://YOUR_ROBOT</uri>"
                    f"\n        <pose>{pose}</pose>\n      </include>\n    "
                )
            )
        )
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
