"""ARIA's canonical writer: the bytes ``ArMap::writeFile`` emits, in chunks, and the atomic
:func:`save`."""

from __future__ import annotations

import hashlib
import math
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor

from mapkit._atomic import atomic_open
from mapkit._typing import PathLike
from mapkit.formats._rows import (
    iter_format_rows,
    worker_pool,
)
from mapkit.formats.map.tokens import _decode, _encode, _unquote
from mapkit.model import (
    INFO_KEYWORDS,
    MapData,
    MapObject,
    Scan,
)

__all__ = ["dumpb", "dumps", "iter_header_lines", "iter_map_chunks", "save", "written_category"]

_PARALLEL_ROWS = 100_000  # rows from which worker threads format a map


# -- writer ----------------------------------------------------------------------------------


def written_category(m: MapData) -> str:
    """The intro line ARIA writes for this map (FORMATS.md A.2).

    Upgraded to ``2D-Map-Ex4`` when the map uses templates; ``2D-Map-Ex`` with only the default
    source is written as ``2D-Map``; never downgraded otherwise.
    """
    cat = m.category
    if _uses_templates(m):
        return "2D-Map-Ex4"
    if cat == "2D-Map-Ex" and len(m.scans) == 1 and m.scans[0].is_default:
        return "2D-Map"
    return cat


def _uses_templates(m: MapData) -> bool:
    if m.info.get("MacroInfo"):
        return True
    for line in m.info.get("MapInfo", ()):
        if line and line[0] == "CairnGroupType":
            return True
    for line in m.info.get("RouteInfo", ()):
        if line and line[0] == "MacroTemplate":
            return True
    for line in m.info.get("MetaInfo", ()):
        if line and line[0] == "Feature" and any(_unquote(t) == "Name=templates" for t in line[1:]):
            return True
    return False


def _printf(spec: str, v: float) -> str:
    """C's printf of one double: as Python's %, but a NaN with its sign bit set is ``-nan``."""
    text = spec % v
    return "-" + text if math.isnan(v) and math.copysign(1.0, v) < 0 else text


def _f0(v: float) -> str:
    return _printf("%.0f", v)


def _object_line(keyword: str, o: MapObject) -> str:
    th = _printf("%f", o.theta)
    s = f'{keyword} {o.type} {_f0(o.x)} {_f0(o.y)} {th} "{o.description}" {o.icon} "{o.name}"'
    if o.from_to is not None:
        s += " " + " ".join(_f0(v) for v in o.from_to)
    return s


def _pair(p: tuple[int, int] | None) -> str:
    p = p or (0, 0)
    return f"{p[0]} {p[1]}"


def _scan_prefix(scan: Scan) -> str:
    return "" if scan.is_default else scan.name


def iter_header_lines(m: MapData) -> Iterator[str]:
    """The header lines ARIA writes, in its order (without newlines)."""
    yield written_category(m)
    if m.scans[0].name:
        yield "Sources: " + " ".join(s.name for s in m.scans)
    for s in m.scans:
        p = _scan_prefix(s)
        if s.display:
            yield f'{p}Display: "{s.display}"'
        if s.num_points:
            yield f"{p}MinPos: {_pair(s.min_pos)}"
            yield f"{p}MaxPos: {_pair(s.max_pos)}"
            yield f"{p}NumPoints: {s.num_points}"
            yield f"{p}PointsAreSorted: {'true' if s.points_sorted else 'false'}"
        if s.resolution != -1:
            yield f"{p}Resolution: {s.resolution}"
        if s.num_lines:
            yield f"{p}LineMinPos: {_pair(s.line_min_pos)}"
            yield f"{p}LineMaxPos: {_pair(s.line_max_pos)}"
            yield f"{p}NumLines: {s.num_lines}"
            yield f"{p}LinesAreSorted: {'true' if s.lines_sorted else 'false'}"
    if m.origin_lla is not None:
        lat, lon, alt = m.origin_lla
        yield "OriginLatLongAlt: " + " ".join(_printf("%f", v) for v in (lat, lon, alt))
    for key in INFO_KEYWORDS:
        for line in m.info.get(key, ()):
            yield f"{key}: " + " ".join(line)
    for o in m.objects:
        yield _object_line("Cairn:", o)
    for key in INFO_KEYWORDS:
        for line in m.inactive_info.get(key, ()):
            yield f"_{key}: " + " ".join(line)
    for o in m.inactive_objects:
        yield _object_line("_Cairn:", o)
    for o in m.child_objects:
        yield _object_line("ChildCairn:", o)
    yield from m.remainder


def iter_map_chunks(m: MapData) -> Iterator[bytes]:
    """The canonical file as byte chunks (header, then each data section).

    For a big map, worker threads format the rows ahead of the consumer (numpy releases the GIL),
    so that writing and hashing the chunks overlap with formatting the next ones.
    """
    with worker_pool(sum(s.num_points + s.num_lines for s in m.scans) >= _PARALLEL_ROWS) as pool:
        yield from _map_chunks(m, pool)


def _map_chunks(m: MapData, pool: ThreadPoolExecutor | None) -> Iterator[bytes]:
    yield _encode("".join(line + "\n" for line in iter_header_lines(m)))
    for s in m.scans:
        if s.num_lines:
            yield _encode(_scan_prefix(s) + "_LINES\n" if _scan_prefix(s) else "LINES\n")
            yield from iter_format_rows(s.lines, pool)
    for s in m.scans:
        yield _encode(_scan_prefix(s) + "_DATA\n" if _scan_prefix(s) else "DATA\n")
        yield from iter_format_rows(s.points, pool)


def dumpb(m: MapData) -> bytes:
    """The map as ARIA's writer emits it, as bytes.

    Examples:
        >>> dumpb(MapData())
        b'2D-Map\\nResolution: 0\\nDATA\\n'
    """
    return b"".join(iter_map_chunks(m))


def dumps(m: MapData) -> str:
    """The map as ARIA's writer emits it, as text (undecodable bytes as surrogates)."""
    return _decode(dumpb(m))


def save(m: MapData, path: PathLike, *, backup: bool = False) -> str:
    """Write a map atomically (temp file beside it, fsync, rename) in ARIA's canonical form.

    Args:
        m: The map.
        path: Destination file.
        backup: Keep the previous file as ``path.bak``.

    Returns:
        The MD5 (hex) of the bytes written: ARIA's checksum of the new file.

    Raises:
        OSError: When the file cannot be written; any previous file is then unchanged.
    """
    md5 = hashlib.md5()
    with atomic_open(path, backup=backup) as fh:
        for chunk in iter_map_chunks(m):
            md5.update(chunk)
            fh.write(chunk)
    return md5.hexdigest()
