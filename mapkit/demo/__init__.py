"""The whole job on the bundled samples, in one call: ``mapkit demo``.

From a bundled ``.2d`` laser log to a checked, edited map, its picture, its ROS map and keepout
mask, its 3D walls, and a verified round trip through a map server on loopback — with nothing to
set up. Each step reports progress through a callback, so the CLI can show it.

Examples:
    >>> [s.name for s in DEMO_STEPS][:3]
    ['build', 'edit', 'validate']
"""

from __future__ import annotations

import hashlib
import os
import secrets
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from mapkit._typing import PathLike
from mapkit.errors import MapkitError
from mapkit.formats.map import load, save
from mapkit.model import MapData
from mapkit.samples import sample_path

__all__ = ["DEMO_STEPS", "Artefact", "DemoResult", "DemoStep", "run_demo"]

#: ``progress(step, done, total)``: ``done`` of ``total`` units of ``step`` are finished.
Progress = Callable[[str, int, int], None]


@dataclass(frozen=True)
class DemoStep:
    """One step of the demo: a short name and what it does."""

    name: str
    title: str


DEMO_STEPS = (
    DemoStep("build", "build a map from the bundled laser log (scan registration, loop closure)"),
    DemoStep("edit", "add a goal and a forbidden area"),
    DemoStep("validate", "validate it (reachability for a 250 mm robot)"),
    DemoStep("render", "render it to PNG"),
    DemoStep("ros", "rasterise it for ROS (PGM + YAML + keepout mask)"),
    DemoStep("mesh", "export the walls as a 3D mesh with a Gazebo world"),
    DemoStep("transfer", "send it to a map server on loopback and fetch it back, verified"),
)


@dataclass(frozen=True)
class Artefact:
    """A file the demo made."""

    path: Path
    what: str
    sha256: str
    size: int


@dataclass
class DemoResult:
    """What the demo made and found."""

    folder: Path
    artefacts: list[Artefact] = field(default_factory=list)
    summary: dict[str, Any] = field(default_factory=dict)
    seconds: dict[str, float] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready form."""
        return {
            "folder": str(self.folder),
            "artefacts": [
                {"path": str(a.path), "what": a.what, "sha256": a.sha256, "size": a.size}
                for a in self.artefacts
            ],
            "summary": self.summary,
            "seconds": {k: round(v, 3) for k, v in self.seconds.items()},
        }


def _sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def run_demo(
    folder: PathLike, *, log: PathLike | None = None, progress: Progress | None = None
) -> DemoResult:
    """Run the demo into ``folder`` (created if needed).

    Args:
        folder: Where the artefacts go.
        log: A ``.2d`` log to build from (default: the bundled ``office-loop.2d``).
        progress: Called as ``progress(step, done, total)``.

    Returns:
        The artefacts with their SHA-256, and a summary of each step.

    Raises:
        MapkitError: When a step fails (the message names the step).
    """
    import mapkit.edit as edit
    from mapkit.build import build_map
    from mapkit.mesh import export_mesh
    from mapkit.raster.export import export_ros
    from mapkit.render import render
    from mapkit.transfer import MapServer, fetch_file, send_file
    from mapkit.validate import validate

    out = Path(folder).resolve()
    out.mkdir(parents=True, exist_ok=True)
    result = DemoResult(out.resolve())

    def tick(step: str, done: int, total: int) -> None:
        if progress is not None:
            progress(step, done, total)

    def add(path: Path, what: str) -> None:
        result.artefacts.append(Artefact(path, what, _sha256(path), path.stat().st_size))

    def timed(step: str) -> Callable[[], None]:
        start = time.perf_counter()
        tick(step, 0, 1)

        def done() -> None:
            result.seconds[step] = time.perf_counter() - start
            tick(step, 1, 1)

        return done

    # 1. build
    log_path = Path(log) if log is not None else sample_path("office-loop.2d")
    finish = timed("build")
    built = build_map(log_path, progress=lambda d, t: tick("build", d, t) if d < t else None)
    built_path = out / "built.map"
    save(built.map, built_path)
    add(built_path, f"map built from {log_path.name}")
    result.summary["build"] = {
        k: v for k, v in built.summary.items() if isinstance(v, (int, float, str))
    }
    finish()

    # 2. edit: a goal a metre ahead of home, a forbidden area a few metres from it
    finish = timed("edit")
    m = built.map
    home = next((o for o in m.objects if o.type == "RobotHome"), None)
    hx, hy = (home.x, home.y) if home is not None else (0.0, 0.0)
    m = edit.add_goal(
        m, "Demo goal", hx + 1000, hy, heading=0.0, description="added by mapkit demo"
    )
    m = edit.forbid_area(
        m,
        hx + 3000,
        hy - 5000,
        hx + 4200,
        hy - 4200,
        name="Demo keep-out",
        angle=15.0,
        rotate_about_centre=True,
    )
    edited_path = out / "office.map"
    md5 = save(m, edited_path)
    add(edited_path, "the edited map (ARIA .map)")
    result.summary["edit"] = {"objects": len(m.objects), "md5": md5}
    finish()

    # 3. validate
    finish = timed("validate")
    report = validate(edited_path)
    result.summary["validate"] = {
        "errors": len(report.errors),
        "warnings": len(report.warnings),
        "findings": [str(i) for i in report.issues],
    }
    finish()

    # 4. render
    finish = timed("render")
    png = out / "office.png"
    render(m, png, title="mapkit demo: built from a laser log")
    add(png, "picture of the map")
    finish()

    # 5. ROS map + keepout mask
    finish = timed("ros")
    ros = export_ros(m, out / "office.yaml", keepout=True)
    for p in ros.files():
        add(Path(p), "ROS map_server / Nav2 file")
    grid = ros.grid
    result.summary["ros"] = {
        "width": grid.width,
        "height": grid.height,
        "resolution_m": grid.resolution,
        "origin_m": list(grid.origin),
    }
    finish()

    # 6. mesh
    finish = timed("mesh")
    mesh = export_mesh(m, out / "walls.stl", world=out / "walls.sdf")
    add(out / "walls.stl", "3D walls (STL)")
    add(out / "walls.sdf", "Gazebo world")
    if not mesh.watertight:
        raise MapkitError("demo: the wall mesh is not watertight")
    result.summary["mesh"] = {
        "watertight": mesh.watertight,
        "faces": mesh.faces,
        "source": mesh.source,
    }
    finish()

    # 7. transfer over loopback, authenticated, and back
    finish = timed("transfer")
    secret = secrets.token_bytes(32)
    robot = Path(tempfile.mkdtemp(prefix="robot-", dir=out))
    with MapServer(robot, host="127.0.0.1", port=0, secret=secret).start() as server:
        host, port = server.address[:2]
        sent = send_file(
            edited_path,
            host,
            port,
            secret=secret,
            load=True,
            progress=lambda d, t: tick("transfer", d, 2 * t),
        )
        fetched = out / "fetched.map"
        fetch_file(
            host,
            sent["name"],
            fetched,
            port,
            secret=secret,
            progress=lambda d, t: tick("transfer", t + d, 2 * t),
        )
    if _sha256(fetched) != _sha256(edited_path):
        raise MapkitError("demo: the fetched map's SHA-256 differs from the sent one")
    add(fetched, "the map fetched back from the server (SHA-256 verified)")
    if load(fetched).md5 != md5:
        raise MapkitError("demo: the fetched map's MD5 differs from the sent one")
    result.summary["transfer"] = {
        "server": f"{host}:{port}",
        "name": sent["name"],
        "loaded": bool(sent.get("loaded")),
        "verified": True,
    }
    for p in sorted(robot.rglob("*")):
        if p.is_file():
            os.unlink(p)
    for p in sorted(robot.rglob("*"), reverse=True):
        p.rmdir()
    robot.rmdir()
    finish()
    return result


def built_map_of(result: DemoResult) -> MapData:
    """The edited map the demo made (read back from its folder)."""
    return load(result.folder / "office.map")
