"""Formats by file suffix: the one place a reader or writer is registered.

``mapkit convert IN OUT`` reads IN with the reader for its suffix and writes OUT with the writer
for its suffix. Layer-3 packages (raster, mesh, ...) add writers with :func:`register_writer` at
import time; :data:`LAZY_WRITERS` names the module that registers a suffix so it is only
imported when needed.
"""

from __future__ import annotations

import importlib
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

from mapkit._typing import PathLike
from mapkit.errors import UnsupportedFormatError
from mapkit.formats import map as mapfmt
from mapkit.model import MapData

__all__ = ["LAZY_WRITERS", "convert_file", "read_any", "register_reader", "register_writer"]

Reader = Callable[[PathLike], MapData]
#: A writer takes the map and the output path and returns a one-line summary of what it wrote.
Writer = Callable[[MapData, PathLike], str]

_READERS: dict[str, Reader] = {".map": mapfmt.load}


def _write_map(m: MapData, path: PathLike) -> str:
    md5 = mapfmt.save(m, path)
    return f"wrote {os.fspath(path)} (MD5 {md5})"


_WRITERS: dict[str, Writer] = {".map": _write_map}

#: suffix -> module that registers its writer (imported on first use).
LAZY_WRITERS: dict[str, str] = {
    ".png": "mapkit.render",  # the picture; ROS map images are written by mapkit rasterize
    ".svg": "mapkit.render",
    ".pdf": "mapkit.render",
    ".stl": "mapkit.mesh",
    ".obj": "mapkit.mesh",
    ".glb": "mapkit.mesh",
    ".dae": "mapkit.mesh",
}
#: suffix -> module that registers its reader (imported on first use).
LAZY_READERS: dict[str, str] = {".2d": "mapkit.build"}


def register_reader(suffix: str, reader: Reader) -> None:
    """Register a reader for a suffix (``".yaml"``)."""
    _READERS[suffix.lower()] = reader


def register_writer(suffix: str, writer: Writer) -> None:
    """Register a writer for a suffix (``".pgm"``)."""
    _WRITERS[suffix.lower()] = writer


def _lookup(table: dict[str, Any], lazy: dict[str, str], path: PathLike, what: str) -> Any:
    suffix = Path(os.fspath(path)).suffix.lower()
    if suffix not in table and suffix in lazy:
        importlib.import_module(lazy[suffix])
    if suffix not in table:
        known = ", ".join(sorted(set(table) | set(lazy)))
        raise UnsupportedFormatError(
            f"cannot {what} {os.fspath(path)!r}: no format for suffix "
            f"{suffix or '(none)'!r} (known: {known})"
        )
    return table[suffix]


def read_any(path: PathLike) -> MapData:
    """Read a map from any registered format, chosen by suffix.

    Raises:
        UnsupportedFormatError: When no reader handles the suffix.
    """
    reader: Reader = _lookup(_READERS, LAZY_READERS, path, "read")
    return reader(path)


def convert_file(src: PathLike, dst: PathLike) -> str:
    """Read ``src`` and write ``dst``, each in the format of its suffix.

    Returns:
        A one-line summary of what was written.

    Raises:
        UnsupportedFormatError: When a suffix has no reader/writer.
        MapFormatError: When ``src`` cannot be parsed.
    """
    writer: Writer = _lookup(_WRITERS, LAZY_WRITERS, dst, "write")
    return writer(read_any(src), dst)


# raster: ROS map_server maps (NAME.yaml + NAME.pgm) both ways.
LAZY_WRITERS.update(
    {
        ".yaml": "mapkit.raster.export",
        ".yml": "mapkit.raster.export",
        ".pgm": "mapkit.raster.export",
    }
)
LAZY_READERS.update({".yaml": "mapkit.raster.export", ".yml": "mapkit.raster.export"})
