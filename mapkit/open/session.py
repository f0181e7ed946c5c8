"""One editing session on one file: the map, its undo history, saving, and what the page shows.

No I/O beyond the file being edited (and its ``.bak``/mask siblings); no HTTP here (see
:mod:`mapkit.open.api` and :mod:`mapkit.open.server`). Edits arrive in the ``mapkit edit
--script`` vocabulary and are applied by :func:`mapkit.edit.apply_script`, so the file a
session saves is byte for byte the file ``mapkit edit FILE --script`` writes for the same edits.

Two kinds of file:

* an ARIA ``.map``: every script operation but ``merge`` (which reads another file);
* a ROS map YAML: the scan is the image's occupied cells (read only); keepout zones (the mask
  beside the map, ``NAME_keepout.yaml``, or the one given) are edited as ``ForbiddenArea`` /
  ``ForbiddenLine`` objects and saved as the keepout mask plus Nav2's filter parameters.

Examples:
    >>> import os, tempfile
    >>> d = tempfile.mkdtemp(); p = os.path.join(d, "a.map")
    >>> _ = open(p, "w").write("2D-Map\\nDATA\\n0 0\\n")
    >>> s = MapSession.open(p)
    >>> s.edit([{"add-goal": {"name": "A", "x": 0, "y": 0}}])["summary"]
    ["added Goal 'A' at (0, 0)"]
    >>> s.undo()["summary"], s.redo()["summary"]
    (["removed Goal 'A' at (0, 0)"], ["added Goal 'A' at (0, 0)"])
    >>> s.save()["written"] == [p]
    True
"""

from __future__ import annotations

import hashlib
import json
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from mapkit._typing import PathLike
from mapkit.edit import apply_script, diff, list_objects, parse_script
from mapkit.edit.declared import shape_of_class, type_args
from mapkit.errors import EditError, MapkitError
from mapkit.formats.map import load, save
from mapkit.model import MapData

__all__ = ["ROS_OPERATIONS", "ConflictError", "MapSession", "OpenError"]

#: What a ROS map's session can do: its image is read only, its keepout zones are objects.
ROS_OPERATIONS = ("forbid", "remove", "rename", "move")
#: Operations the editor refuses: ``merge`` reads a file other than the one opened.
REFUSED = {"merge": "merge reads another file; use `mapkit merge` for it"}


class OpenError(MapkitError):
    """The editor cannot do what was asked (nothing to undo, a file it may not touch, ...)."""


class ConflictError(OpenError):
    """The file changed on disk since it was opened or last saved; saving would lose that."""


@dataclass(frozen=True)
class _State:
    """One point in the history: the map, the script edits that led here, the data version."""

    m: MapData
    edits: tuple[dict[str, Any], ...]
    data_version: int


def _digest(paths: list[Path]) -> str:
    h = hashlib.sha256()
    for p in paths:
        h.update(os.fsencode(p))
        try:
            h.update(p.read_bytes())
        except FileNotFoundError:
            h.update(b"\0missing")
    return h.hexdigest()


class MapSession:
    """An open file: the current map, undo/redo, save (refusing external changes).

    Build with :meth:`open`. Thread safety is the caller's (the HTTP driver holds a lock).
    """

    def __init__(
        self,
        path: Path,
        m: MapData,
        *,
        kind: str = "aria",
        grid: Any = None,
        keepout: Path | None = None,
    ) -> None:
        self.path = path
        self.kind = kind
        self.grid = grid
        self.keepout = keepout
        self._history: list[_State] = [_State(m, (), 0)]
        self._at = 0
        self._saved_at = 0
        self._versions = 0
        self._disk = _digest(self._watched())

    # -- opening -------------------------------------------------------------------------------

    @classmethod
    def open(cls, path: PathLike, *, keepout: PathLike | None = None) -> MapSession:
        """Open an ARIA ``.map`` or a ROS map YAML (with its keepout mask when there is one).

        Raises:
            MapkitError: The file is not a map (message names file and line).
            OSError: It cannot be read.
        """
        p = Path(os.fspath(path)).resolve()
        if p.suffix.lower() not in (".yaml", ".yml"):
            if keepout is not None:
                raise OpenError(f"{p}: --keepout is for a ROS map YAML, not an ARIA map")
            return cls(p, load(p))
        from mapkit.raster.import_ros import grid_to_map, keepout_objects
        from mapkit.raster.ros import image_to_grid, read_image, read_ros_map, read_ros_yaml

        grid = read_ros_map(p)
        default = Path(f"{p.with_suffix('')}_keepout.yaml")
        k = Path(os.fspath(keepout)).resolve() if keepout else default
        m = grid_to_map(grid, yaw=read_ros_yaml(p).origin[2])
        if k.exists():
            info = read_ros_yaml(k)
            mask = image_to_grid(read_image(info.image_path), info)
            m = m.replace(objects=tuple(keepout_objects(mask, yaw=info.origin[2])))
        elif keepout:
            raise OpenError(f"{k}: no such keepout mask")
        return cls(p, m, kind="ros", grid=grid, keepout=k)

    # -- state ---------------------------------------------------------------------------------

    @property
    def map(self) -> MapData:
        """The map as edited so far."""
        return self._history[self._at].m

    @property
    def data_version(self) -> int:
        """Changes when the scan data (points, lines) changes: the tiles' cache key."""
        return self._history[self._at].data_version

    @property
    def edits(self) -> list[dict[str, Any]]:
        """The script edits from the opened file to now (what `mapkit edit --script` replays)."""
        return list(self._history[self._at].edits)

    @property
    def dirty(self) -> bool:
        """Whether the map differs from the file on disk (as last opened or saved)."""
        if self._at == self._saved_at:
            return False
        return not diff(self._history[self._saved_at].m, self.map).equal

    def _watched(self) -> list[Path]:
        if self.kind == "ros" and self.keepout is not None:
            return [self.path, self.keepout]
        return [self.path]

    # -- editing -------------------------------------------------------------------------------

    def edit(self, edits: Any) -> dict[str, Any]:
        """Apply a list of script edits as one undo step.

        Returns:
            ``{"summary": [diff lines]}``.

        Raises:
            EditError: A refused edit (the map is unchanged), with the script's message.
        """
        if not isinstance(edits, list) or not edits:
            raise EditError('give "edits": a non-empty list of edit-script operations')
        parsed = parse_script(json.dumps(edits), source="edit", yaml=False)
        for e in parsed:
            if e.op in REFUSED:
                raise EditError(f"{e.where}: {REFUSED[e.op]}")
            if self.kind == "ros" and e.op not in ROS_OPERATIONS:
                raise EditError(
                    f"{e.where}: a ROS map's image is read only here; its keepout "
                    f"zones take {', '.join(ROS_OPERATIONS)}"
                )
        before = self.map
        after = apply_script(before, parsed, base_dir=self.path.parent)
        if self.kind == "ros":
            bad = [
                o.type for o in after.objects if o.type not in ("ForbiddenArea", "ForbiddenLine")
            ]
            if bad:
                raise EditError(
                    f"edit: a keepout mask holds forbidden areas and lines, not {bad[0]}"
                )
        version = self.data_version
        if after.scans is not before.scans:
            self._versions += 1
            version = self._versions
        state = _State(after, (*self._history[self._at].edits, *edits), version)
        del self._history[self._at + 1 :]
        self._history.append(state)
        self._at += 1
        return {"summary": diff(before, after).summary()}

    def undo(self) -> dict[str, Any]:
        """Step back one edit batch. Raises :class:`OpenError` when there is nothing to undo."""
        if self._at == 0:
            raise OpenError("nothing to undo")
        self._at -= 1
        return {"summary": diff(self._history[self._at + 1].m, self.map).summary()}

    def redo(self) -> dict[str, Any]:
        """Step forward again. Raises :class:`OpenError` when there is nothing to redo."""
        if self._at + 1 >= len(self._history):
            raise OpenError("nothing to redo")
        self._at += 1
        return {"summary": diff(self._history[self._at - 1].m, self.map).summary()}

    # -- saving --------------------------------------------------------------------------------

    def changed_on_disk(self) -> bool:
        """Whether the file (or its keepout mask) changed since it was opened or last saved."""
        return _digest(self._watched()) != self._disk

    def save(self, *, backup: bool = False) -> dict[str, Any]:
        """Write the map atomically, as `mapkit edit` does (nothing when nothing changed).

        Raises:
            ConflictError: The file changed on disk since it was opened or last saved.
        """
        if self.changed_on_disk():
            raise ConflictError(
                f"{self.path} changed on disk since it was opened; reload it "
                "(your edits are lost) or save elsewhere with the CLI"
            )
        if not self.dirty:
            return {"written": [], "message": f"nothing changed; {self.path} left as it was"}
        if self.kind == "ros":
            written = self._save_keepout(backup)
            md5 = None
        else:
            md5 = save(self.map, self.path, backup=backup)
            written = [str(self.path)]
        self._saved_at = self._at
        self._disk = _digest(self._watched())
        return {
            "written": written,
            "md5": md5,
            "backup": backup,
            "message": f"wrote {', '.join(written)}",
        }

    def _save_keepout(self, backup: bool) -> list[str]:
        from mapkit._atomic import atomic_write
        from mapkit.raster.masks import filter_params_text, keepout_mask
        from mapkit.raster.ros import write_ros_map

        assert self.keepout is not None
        params = Path(f"{self.path.with_suffix('')}_filters.yaml")
        image = None
        if self.keepout.exists():
            from mapkit.raster.ros import read_ros_yaml

            image = read_ros_yaml(self.keepout).image_path
            if Path(image).resolve().parent != self.keepout.parent:
                raise OpenError(
                    f"{self.keepout}: its image {image} is not beside it; "
                    "the editor writes only the map's own files"
                )
        targets = [self.keepout, Path(image) if image else self.keepout.with_suffix(".pgm"), params]
        if backup:
            for t in targets:
                if t.exists():
                    atomic_write(f"{t}.bak", t.read_bytes())
        default = Path(f"{self.path.with_suffix('')}_keepout.yaml")
        if self.keepout == default and targets[1] == default.with_suffix(".pgm"):
            from mapkit.raster.masks import write_filters

            f = write_filters(self.map, self.grid, self.path)  # what `rasterize --keepout` writes
            return [str(f.keepout_yaml), str(f.keepout_image), str(f.params)]
        files = write_ros_map(keepout_mask(self.map, self.grid), self.keepout, image_path=image)
        atomic_write(params, filter_params_text(files.yaml, source=self.path.name).encode("utf-8"))
        return [str(files.yaml), str(files.image), str(params)]

    def reload(self) -> dict[str, Any]:
        """Read the file again from disk, dropping every edit (and the undo history)."""
        fresh = MapSession.open(self.path, keepout=self.keepout if self.kind == "ros" else None)
        self.__dict__.update(fresh.__dict__)
        return {"summary": [f"reloaded {self.path}"]}

    # -- what the page shows -------------------------------------------------------------------

    def bounds(self) -> list[list[float]]:
        """``[[xmin, ymin], [xmax, ymax]]`` of points, lines and objects (mm)."""
        m = self.map
        xs: list[np.ndarray[Any, Any]] = [m.points[:, 0], m.lines[:, 0], m.lines[:, 2]]
        ys: list[np.ndarray[Any, Any]] = [m.points[:, 1], m.lines[:, 1], m.lines[:, 3]]
        for o in m.objects:
            xs.append(np.array([o.x]))
            ys.append(np.array([o.y]))
            if o.from_to is not None:
                c = np.array(o.corners(), dtype=np.float64).reshape(-1, 2)
                xs.append(c[:, 0])
                ys.append(c[:, 1])
        x = np.concatenate([a.astype(np.float64) for a in xs])
        y = np.concatenate([a.astype(np.float64) for a in ys])
        if not x.size:
            return [[-5000.0, -5000.0], [5000.0, 5000.0]]
        return [[float(x.min()), float(y.min())], [float(x.max()), float(y.max())]]

    def types(self) -> list[dict[str, Any]]:
        """The map's declared types: name, class, shape and parameters (for the add menu)."""
        out = []
        for name, cls in self.map.declared_types().items():
            args = [
                {"name": a.name, "kind": a.kind, "default": a.default, "min": a.min, "max": a.max}
                for a in type_args(self.map, name)
            ]
            out.append({"name": name, "class": cls, "shape": shape_of_class(cls), "params": args})
        return out

    def describe(self) -> dict[str, Any]:
        """What ``GET /api/map`` answers."""
        m = self.map
        return {
            "file": str(self.path),
            "kind": self.kind,
            "category": m.category,
            "counts": {"points": len(m.points), "lines": len(m.lines), "objects": len(m.objects)},
            "bounds": self.bounds(),
            "resolution": int(m.scan.resolution),
            "objects": list_objects(m),
            "types": self.types() if self.kind == "aria" else [],
            "operations": list(ROS_OPERATIONS) if self.kind == "ros" else None,
            "data_version": self.data_version,
            "dirty": self.dirty,
            "can_undo": self._at > 0,
            "can_redo": self._at + 1 < len(self._history),
            "edits": self.edits,
        }

    def findings(self, *, robot_radius: float | None = None) -> list[dict[str, Any]]:
        """``mapkit validate`` on the map as it would be saved, each finding with a place (or
        ``xy: null`` for map-wide ones)."""
        from mapkit.validate import DEFAULT_ROBOT_RADIUS, validate

        m = self.map
        report = validate(
            m,
            robot_radius=DEFAULT_ROBOT_RADIUS if robot_radius is None else robot_radius,
            source=self.path.name,
        )
        centres = {r["name"]: r["centre"] for r in list_objects(m) if r["name"]}
        out = []
        for issue in report.issues:
            d = issue.to_dict()
            loc = issue.location
            xy = list(loc.xy) if loc.xy is not None else centres.get(loc.object or "")
            d["xy"] = xy
            out.append(d)
        return out
