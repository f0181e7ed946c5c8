"""The map model: one immutable value per map (:class:`MapData`), one :class:`Scan` per source."""

from __future__ import annotations

import types
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from mapkit._typing import LineArray, PointArray
from mapkit.model.objects import BUILTIN_LINE_TYPES, MapObject

__all__ = [
    "CATEGORIES",
    "INFO_KEYWORDS",
    "InfoLine",
    "MapData",
    "Provenance",
    "Scan",
    "ScanHeader",
    "missing_rows",
]

#: Map categories (intro lines), oldest first.
CATEGORIES = ("2D-Map", "2D-Map-Ex", "2D-Map-Ex2", "2D-Map-Ex3", "2D-Map-Ex4")

#: The nine info sections, in the order ARIA writes them (case-insensitive alphabetical).
INFO_KEYWORDS = (
    "CairnInfo",
    "CustomInfo",
    "MacroInfo",
    "MapInfo",
    "MetaInfo",
    "RouteInfo",
    "SchedInfo",
    "SchedTaskInfo",
    "TaskInfo",
)

#: One info line: its argument tokens as ARIA splits them (quoted tokens keep their quotes).
InfoLine = tuple[str, ...]

_EMPTY_POINTS = np.zeros((0, 2), dtype=np.int64)
_EMPTY_LINES = np.zeros((0, 4), dtype=np.int64)
_EMPTY_POINTS.flags.writeable = False
_EMPTY_LINES.flags.writeable = False


def _frozen_array(a: Any, cols: int) -> np.ndarray[Any, np.dtype[np.int64]]:
    arr = np.asarray(a)
    if arr.size == 0:
        arr = np.zeros((0, cols), dtype=np.int64)
    if arr.ndim != 2 or arr.shape[1] != cols:
        raise ValueError(f"expected an array of shape (N, {cols}), got {arr.shape}")
    if arr.dtype != np.int64:
        if arr.dtype.kind == "f":
            if not np.all(np.isfinite(arr)):
                raise ValueError("coordinates must be finite")
            arr = np.rint(arr)
        arr = arr.astype(np.int64)
    elif arr.flags.writeable:
        arr = arr.copy() if arr.base is not None or not arr.flags.c_contiguous else arr
    arr = np.ascontiguousarray(arr)
    arr.flags.writeable = False
    return arr


def _box(arr: np.ndarray[Any, Any], pairs: int) -> tuple[tuple[int, int], tuple[int, int]] | None:
    if len(arr) == 0:
        return None
    xy = arr.reshape(-1, 2) if pairs == 2 else arr
    lo = xy.min(axis=0)
    hi = xy.max(axis=0)
    return (int(lo[0]), int(lo[1])), (int(hi[0]), int(hi[1]))


@dataclass(frozen=True, slots=True)
class ScanHeader:
    """A scan's header keywords exactly as the file gave them (``None`` = absent).

    Kept for validation and provenance; the writer does not use it (it writes what ARIA writes,
    from :class:`Scan`'s fields).
    """

    min_pos: tuple[int, int] | None = None
    max_pos: tuple[int, int] | None = None
    num_points: int | None = None
    points_sorted: bool | None = None
    resolution: int | None = None
    line_min_pos: tuple[int, int] | None = None
    line_max_pos: tuple[int, int] | None = None
    num_lines: int | None = None
    lines_sorted: bool | None = None
    display: str | None = None


@dataclass(frozen=True, slots=True, eq=False)
class Scan:
    """The sensed data of one scan source: points and line segments in integer millimetres.

    ``min_pos``/``max_pos`` and ``line_min_pos``/``line_max_pos`` are the boxes the writer emits.
    The reader sets them by ARIA's rule (union of the header box, or the origin when the header has
    none, with the data); :meth:`with_data` and :meth:`from_arrays` set them to the data's extents,
    as ARIA does when a map is edited through its API.

    Attributes:
        name: Source name (``""`` for the default source; ``SickLaser`` is also the default).
        display: Label shown by ARIA's tools (defaults to the source name).
        points: ``(N, 2)`` int64 array, read-only.
        lines: ``(M, 4)`` int64 array of ``x1 y1 x2 y2``, read-only.
        resolution: Grid size in mm the points were quantised to (0 when the file has none, as
            ARIA writes it); -1 means unknown and is not written.
        points_sorted: The ``PointsAreSorted:`` flag (ARIA copies it, never checks it).
        lines_sorted: The ``LinesAreSorted:`` flag.
        min_pos: Lower-left corner of the points box, or ``None`` when there are no points.
        max_pos: Upper-right corner of the points box.
        line_min_pos: Lower-left corner of the lines box.
        line_max_pos: Upper-right corner of the lines box.
        header: The header values as read from the file.

    Examples:
        >>> s = Scan.from_arrays(points=[[0, 0], [100, 40]], lines=[[0, 0, 100, 0]], resolution=20)
        >>> s.num_points, s.num_lines, s.max_pos
        (2, 1, (100, 40))
    """

    name: str = ""
    display: str = ""
    points: PointArray = field(default_factory=lambda: _EMPTY_POINTS)
    lines: LineArray = field(default_factory=lambda: _EMPTY_LINES)
    resolution: int = 0
    points_sorted: bool = False
    lines_sorted: bool = False
    min_pos: tuple[int, int] | None = None
    max_pos: tuple[int, int] | None = None
    line_min_pos: tuple[int, int] | None = None
    line_max_pos: tuple[int, int] | None = None
    header: ScanHeader = field(default_factory=ScanHeader)

    def __post_init__(self) -> None:
        object.__setattr__(self, "points", _frozen_array(self.points, 2))
        object.__setattr__(self, "lines", _frozen_array(self.lines, 4))

    @classmethod
    def from_arrays(
        cls,
        points: Any = None,
        lines: Any = None,
        *,
        name: str = "",
        display: str | None = None,
        resolution: int = 20,
        sort: bool = False,
    ) -> Scan:
        """A scan from point and line arrays, with boxes set to the data's extents.

        Args:
            points: ``(N, 2)`` array-like of millimetres (floats are rounded).
            lines: ``(M, 4)`` array-like of millimetres.
            name: Source name.
            display: Label; defaults to the name.
            resolution: Grid size in mm (-1 for unknown).
            sort: Sort points and lines (x, then y) and set the sorted flags.

        Returns:
            The new scan.
        """
        base = cls(
            name=name,
            display=name if display is None else display,
            points=_EMPTY_POINTS if points is None else points,
            lines=_EMPTY_LINES if lines is None else lines,
            resolution=resolution,
        )
        return base.with_data(sort=sort)

    def with_data(self, points: Any = None, lines: Any = None, *, sort: bool | None = None) -> Scan:
        """A copy with new points and/or lines and boxes recomputed from the data.

        Args:
            points: New points (``None`` keeps the current ones).
            lines: New lines (``None`` keeps the current ones).
            sort: ``True`` sorts both arrays and sets the flags; ``False`` clears the flags;
                ``None`` keeps a flag only where its array did not change.

        Returns:
            The new scan.
        """
        p = self.points if points is None else _frozen_array(points, 2)
        ln = self.lines if lines is None else _frozen_array(lines, 4)
        ps, ls = self.points_sorted, self.lines_sorted
        if sort:
            if len(p):
                p = _frozen_array(p[np.lexsort((p[:, 1], p[:, 0]))], 2)
            if len(ln):
                ln = _frozen_array(ln[np.lexsort((ln[:, 3], ln[:, 2], ln[:, 1], ln[:, 0]))], 4)
            ps = ls = True
        elif sort is False:
            ps = ls = False
        else:
            ps = ps and points is None
            ls = ls and lines is None
        pbox = _box(p, 1)
        lbox = _box(ln, 2)
        return replace(
            self,
            points=p,
            lines=ln,
            points_sorted=ps,
            lines_sorted=ls,
            min_pos=None if pbox is None else pbox[0],
            max_pos=None if pbox is None else pbox[1],
            line_min_pos=None if lbox is None else lbox[0],
            line_max_pos=None if lbox is None else lbox[1],
        )

    @property
    def num_points(self) -> int:
        """Number of points."""
        return len(self.points)

    @property
    def num_lines(self) -> int:
        """Number of line segments."""
        return len(self.lines)

    @property
    def is_default(self) -> bool:
        """True for the source that uses unprefixed keywords (``""`` or ``SickLaser``, any case)."""
        return self.name == "" or self.name.lower() == "sicklaser"

    def data_bounds(self) -> tuple[tuple[int, int], tuple[int, int]] | None:
        """Exact extents of points and line ends together, or ``None`` when there is no data."""
        boxes = [b for b in (_box(self.points, 1), _box(self.lines, 2)) if b is not None]
        if not boxes:
            return None
        return (
            (min(b[0][0] for b in boxes), min(b[0][1] for b in boxes)),
            (max(b[1][0] for b in boxes), max(b[1][1] for b in boxes)),
        )

    def equals(self, other: Scan) -> bool:
        """Value equality (arrays compared element by element)."""
        return (
            isinstance(other, Scan)
            and np.array_equal(self.points, other.points)
            and np.array_equal(self.lines, other.lines)
            and all(
                getattr(self, f) == getattr(other, f)
                for f in (
                    "name",
                    "display",
                    "resolution",
                    "points_sorted",
                    "lines_sorted",
                    "min_pos",
                    "max_pos",
                    "line_min_pos",
                    "line_max_pos",
                )
            )
        )

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Scan) and self.equals(other)

    __hash__ = None  # type: ignore[assignment]


@dataclass(frozen=True, slots=True)
class Provenance:
    """Where a map came from: file name, MD5 of its bytes and line numbers of its parts.

    Attributes:
        source: File name or ``"<string>"``.
        md5: ARIA's map checksum: MD5 (hex) of the bytes read.
        size: Number of bytes read.
        object_lines: Line number of each ``Cairn:`` object, in order.
        inactive_object_lines: Line numbers of ``_Cairn:`` objects.
        child_object_lines: Line numbers of ``ChildCairn:`` objects.
        info_lines: Per info keyword (``MapInfo`` or ``_MapInfo``), the line number of each line.
        remainder_lines: Line numbers of the unknown lines.
        header_lines: Per scan-header keyword as spelt canonically (``MinPos:``,
            ``SonarNumPoints:``), the line number of its last occurrence.
        intro_line: Line number of the intro line.
        first_data_line: Line number of the first data tag.
    """

    source: str = "<string>"
    md5: str = ""
    size: int = 0
    object_lines: tuple[int, ...] = ()
    inactive_object_lines: tuple[int, ...] = ()
    child_object_lines: tuple[int, ...] = ()
    info_lines: Mapping[str, tuple[int, ...]] = field(
        default_factory=lambda: types.MappingProxyType({})
    )
    remainder_lines: tuple[int, ...] = ()
    header_lines: Mapping[str, int] = field(default_factory=lambda: types.MappingProxyType({}))
    intro_line: int = 1
    first_data_line: int = 0


def _freeze_info(
    info: Mapping[str, Iterable[Iterable[str]]] | None,
) -> Mapping[str, tuple[InfoLine, ...]]:
    out: dict[str, tuple[InfoLine, ...]] = {}
    for key, lines in (info or {}).items():
        if key not in INFO_KEYWORDS:
            raise ValueError(
                f"unknown info section {key!r}; expected one of {', '.join(INFO_KEYWORDS)}"
            )
        frozen = tuple(tuple(line) for line in lines)
        if frozen:
            out[key] = frozen
    return types.MappingProxyType(
        dict(sorted(out.items(), key=lambda kv: INFO_KEYWORDS.index(kv[0])))
    )


@dataclass(frozen=True, slots=True, eq=False)
class MapData:
    """An ARIA map as one immutable value.

    Edits return new values (:func:`dataclasses.replace` or the functions in :mod:`mapkit.edit`).

    Attributes:
        category: The intro line as read (``2D-Map`` ... ``2D-Map-Ex4``).
        scans: One :class:`Scan` per source; the first is the primary one. A map without a
            ``Sources:`` line has one scan named ``""``.
        objects: ``Cairn:`` objects in file order.
        inactive_objects: ``_Cairn:`` objects.
        child_objects: ``ChildCairn:`` objects (template children, ``2D-Map-Ex4``).
        info: Info sections by keyword without the colon (``"MapInfo"``), each a tuple of lines,
            each line a tuple of tokens.
        inactive_info: The ``_MapInfo:`` ... sections, keyed the same way (without ``_``).
        origin_lla: ``OriginLatLongAlt:`` as (lat, lon, alt), or ``None``.
        remainder: Unknown header lines as ARIA writes them back (normalised), in file order.
        provenance: Where the map was read from (ignored by equality).

    Examples:
        >>> m = MapData(objects=(MapObject("Goal", 1000, 0, name="A"),))
        >>> m.category, len(m.objects), m.scan.num_points
        ('2D-Map', 1, 0)
    """

    category: str = "2D-Map"
    scans: tuple[Scan, ...] = (Scan(),)
    objects: tuple[MapObject, ...] = ()
    inactive_objects: tuple[MapObject, ...] = ()
    child_objects: tuple[MapObject, ...] = ()
    info: Mapping[str, tuple[InfoLine, ...]] = field(
        default_factory=lambda: types.MappingProxyType({})
    )
    inactive_info: Mapping[str, tuple[InfoLine, ...]] = field(
        default_factory=lambda: types.MappingProxyType({})
    )
    origin_lla: tuple[float, float, float] | None = None
    remainder: tuple[str, ...] = ()
    provenance: Provenance | None = None

    def __post_init__(self) -> None:
        if self.category not in CATEGORIES:
            raise ValueError(
                f"unknown map category {self.category!r}; expected one of {CATEGORIES}"
            )
        scans = tuple(self.scans)
        if not scans:
            raise ValueError("a map has at least one scan source")
        names = [s.name.lower() for s in scans]
        if len(set(names)) != len(names):
            raise ValueError(f"duplicate scan source names: {[s.name for s in scans]}")
        if len(scans) > 1 and any(s.name == "" for s in scans):
            raise ValueError("with several sources, every source needs a name")
        object.__setattr__(self, "scans", scans)
        object.__setattr__(self, "objects", tuple(self.objects))
        object.__setattr__(self, "inactive_objects", tuple(self.inactive_objects))
        object.__setattr__(self, "child_objects", tuple(self.child_objects))
        object.__setattr__(self, "info", _freeze_info(self.info))
        object.__setattr__(self, "inactive_info", _freeze_info(self.inactive_info))
        object.__setattr__(self, "remainder", tuple(self.remainder))

    # -- convenient views -------------------------------------------------------------------

    @property
    def scan(self) -> Scan:
        """The primary scan source."""
        return self.scans[0]

    @property
    def points(self) -> PointArray:
        """The primary scan's points, ``(N, 2)`` int64 millimetres."""
        return self.scans[0].points

    @property
    def lines(self) -> LineArray:
        """The primary scan's line segments, ``(M, 4)`` int64 millimetres."""
        return self.scans[0].lines

    @property
    def md5(self) -> str | None:
        """MD5 of the bytes the map was read from (ARIA's map checksum), if it was read."""
        return self.provenance.md5 if self.provenance else None

    def declared_types(self, kind: str | None = None) -> dict[str, str]:
        """Types declared in ``MapInfo:``, name → class (``GoalType``, ``SectorType``, ...).

        Args:
            kind: Only this class (e.g. ``"SectorType"``).

        Returns:
            A dict in declaration order.
        """
        out: dict[str, str] = {}
        for line in self.info.get("MapInfo", ()):
            if not line or not line[0].endswith("Type"):
                continue
            if kind is not None and line[0] != kind:
                continue
            for tok in line[1:]:
                t = tok[1:-1] if len(tok) >= 2 and tok[0] == tok[-1] == '"' else tok
                if t.startswith("Name="):
                    out.setdefault(t[5:], line[0])
                    break
        return out

    def object_shape(self, obj: MapObject) -> str:
        """``"point"``, ``"line"`` or ``"rect"``: how ARIA's tools draw this object.

        Objects with from/to corners are lines when their type is ``ForbiddenLine`` or a declared
        ``BoundaryType``, and rectangles otherwise.
        """
        if obj.from_to is None:
            return "point"
        if obj.type in BUILTIN_LINE_TYPES or self.declared_types().get(obj.type) == "BoundaryType":
            return "line"
        return "rect"

    def find(self, name: str, type: str | None = None) -> list[MapObject]:
        """Active objects with this name (and type), compared case-insensitively as ARIA does."""
        n = name.lower()
        return [
            o
            for o in self.objects
            if o.name.lower() == n and (type is None or o.type.lower() == type.lower())
        ]

    def with_scan(self, scan: Scan, index: int = 0) -> MapData:
        """A copy with one scan replaced."""
        scans = list(self.scans)
        scans[index] = scan
        return replace(self, scans=tuple(scans))

    def replace(self, **changes: Any) -> MapData:
        """A copy with fields replaced (the provenance is kept: it says where the original came
        from)."""
        return replace(self, **changes)

    def equals(self, other: MapData) -> bool:
        """Value equality of everything but the provenance."""
        return (
            isinstance(other, MapData)
            and self.category == other.category
            and len(self.scans) == len(other.scans)
            and all(a.equals(b) for a, b in zip(self.scans, other.scans, strict=True))
            and self.objects == other.objects
            and self.inactive_objects == other.inactive_objects
            and self.child_objects == other.child_objects
            and dict(self.info) == dict(other.info)
            and dict(self.inactive_info) == dict(other.inactive_info)
            and self.origin_lla == other.origin_lla
            and self.remainder == other.remainder
        )

    def __eq__(self, other: object) -> bool:
        return isinstance(other, MapData) and self.equals(other)

    __hash__ = None  # type: ignore[assignment]


def missing_rows(m: MapData) -> list[str]:
    """What a truncated file lost: one line per scan whose header promises more rows than it has.

    A file cut short (a copy that stopped, a full disk) still reads: ARIA and mapkit keep the rows
    that are there. Writing it back would set ``NumPoints:``/``NumLines:`` to what is left and
    lock the loss in, so edits refuse such a map unless told to go on, and ``mapkit info`` warns.

    Examples:
        >>> from mapkit import loads
        >>> missing_rows(loads(b"2D-Map\\nNumPoints: 3\\nDATA\\n0 0\\n"))
        ['NumPoints: 3 but the file has 1 DATA row: 2 missing (the file looks cut short)']
        >>> missing_rows(loads(b"2D-Map\\nNumPoints: 1\\nDATA\\n0 0\\n"))
        []
    """
    out = []
    for s in m.scans:
        prefix = "" if s.is_default else s.name
        for key, claimed, actual, what in (
            ("NumPoints:", s.header.num_points, s.num_points, "DATA"),
            ("NumLines:", s.header.num_lines, s.num_lines, "LINES"),
        ):
            if claimed is not None and claimed > actual:
                rows = "row" if actual == 1 else "rows"
                out.append(
                    f"{prefix}{key} {claimed} but the file has {actual} {what} {rows}: "
                    f"{claimed - actual} missing (the file looks cut short)"
                )
    return out
