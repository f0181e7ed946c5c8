"""Reading maps: :func:`load`, :func:`loads`, :func:`parse_map` and the tolerant :func:`recover`."""

from __future__ import annotations

import os

from mapkit._typing import PathLike
from mapkit.diagnostics import Issue
from mapkit.formats.map.parser import _Parser
from mapkit.formats.map.tokens import _encode
from mapkit.model import (
    MapData,
)

__all__ = ["load", "loads", "parse_map", "recover"]


# -- public reading API ----------------------------------------------------------------------


def _as_bytes(data: str | bytes) -> bytes:
    return _encode(data) if isinstance(data, str) else bytes(data)


def parse_map(data: str | bytes, *, source: str = "<string>") -> MapData:
    """Parse map text strictly: the first structural error raises.

    Args:
        data: The file's bytes (or text).
        source: File name for error messages.

    Returns:
        The map.

    Raises:
        MapFormatError: Naming the source, the line and what was expected.
    """
    return _Parser(_as_bytes(data), source, strict=True).parse()


def loads(data: str | bytes, *, source: str = "<string>") -> MapData:
    """Parse a map from text or bytes (strict).

    Args:
        data: Map text or bytes.
        source: Name used in error messages.

    Returns:
        The map.

    Raises:
        MapFormatError: When the text is not a map ARIA would load.

    Examples:
        >>> m = loads("2D-Map\\nDATA\\n1 2\\n")
        >>> m.points.tolist(), m.md5
        ([[1, 2]], '688ea5a151f70b05bdfb3e892a0574ec')
    """
    return parse_map(data, source=source)


def load(path: PathLike) -> MapData:
    """Read a ``.map`` file (strict).

    Args:
        path: The file.

    Returns:
        The map, with its provenance (file name, MD5, line numbers).

    Raises:
        MapFormatError: When the file is not a map ARIA would load.
        OSError: When the file cannot be read.
    """
    with open(path, "rb") as fh:
        data = fh.read()
    return parse_map(data, source=os.fspath(path))


def recover(data: PathLike | bytes, *, source: str | None = None) -> tuple[MapData, list[Issue]]:
    """Read a map tolerantly: load what ARIA would load and list every problem met.

    Lines ARIA would reject are skipped and reported; data ARIA would lose is kept and reported.
    Only a file with no intro line at all (or an empty one) still raises.

    Args:
        data: A path, or the file's bytes.
        source: Name for the issues (defaults to the path).

    Returns:
        ``(map, issues)``.

    Raises:
        MapFormatError: When there is nothing to load.
        OSError: When the file cannot be read.

    Examples:
        >>> m, issues = recover(b"2D-Map\\nNumPoints: x\\nDATA\\n1 1\\n2 2")
        >>> m.points.tolist(), [int(i.code) for i in issues]
        ([[1, 1], [2, 2]], [110, 104])
    """
    if isinstance(data, (bytes, bytearray, memoryview)):
        raw, name = bytes(data), source or "<bytes>"
    else:
        with open(data, "rb") as fh:
            raw = fh.read()
        name = source or os.fspath(data)
    p = _Parser(raw, name, strict=False)
    m = p.parse()
    return m, p.issues
