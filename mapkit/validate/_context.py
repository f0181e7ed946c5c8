"""What every rule sees: the map as read or as it will be written, line numbers, the findings."""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from mapkit.diagnostics import CODE_SUMMARY, Issue, IssueCode, Location, Severity
from mapkit.formats.map import written_category
from mapkit.model import (
    BUILTIN_LINE_TYPES,
    BUILTIN_POINT_TYPES,
    BUILTIN_RECT_TYPES,
    MapData,
    MapObject,
    Scan,
)

__all__ = ["RULES", "Context", "HeaderView", "rule"]

#: Built-in goal and dock base types (``GoalWithHeading`` has base type ``Goal``).
BUILTIN_GOALS = frozenset({"Goal"})
BUILTIN_DOCKS = frozenset({"Dock"})
BUILTIN_TYPES = BUILTIN_POINT_TYPES | BUILTIN_LINE_TYPES | BUILTIN_RECT_TYPES


def unquote(tok: str) -> str:
    """A token without its surrounding quotes (ARIA's rule: both ends must be quotes)."""
    if len(tok) >= 2 and tok[0] == '"' and tok[-1] == '"':
        return tok[1:-1]
    return tok


def key_values(tokens: Sequence[str]) -> dict[str, str]:
    """``Key=Value`` tokens (quotes removed) as a dict; the first occurrence of a key wins."""
    out: dict[str, str] = {}
    for tok in tokens:
        t = unquote(tok)
        k, sep, v = t.partition("=")
        if sep and k and k not in out:
            out[k] = v
    return out


def _as_written(o: MapObject) -> MapObject:
    """The object as ARIA's writer prints it and reads it back (``%.0f`` and ``%f``)."""

    def f0(v: float) -> float:
        return float(format(v, ".0f")) if np.isfinite(v) else v

    ft = None if o.from_to is None else tuple(f0(v) for v in o.from_to)
    th = float(format(o.theta, "f")) if np.isfinite(o.theta) else o.theta
    return replace(o, x=f0(o.x), y=f0(o.y), theta=th, from_to=ft)  # type: ignore[arg-type]


@dataclass(frozen=True)
class HeaderView:
    """One scan's header as the file has it (file view) or as mapkit would write it (model view).

    ``None`` means the keyword is absent. ``lines`` maps canonical keywords (``NumPoints:``) to
    line numbers.
    """

    scan: Scan
    prefix: str
    num_points: int | None
    num_lines: int | None
    min_pos: tuple[int, int] | None
    max_pos: tuple[int, int] | None
    line_min_pos: tuple[int, int] | None
    line_max_pos: tuple[int, int] | None
    resolution: int | None
    points_sorted: bool | None
    lines_sorted: bool | None
    lines: dict[str, int] = field(default_factory=dict)

    def line(self, keyword: str) -> int | None:
        """Line number of ``prefix + keyword`` in the file, if known."""
        return self.lines.get(self.prefix + keyword)


@dataclass
class Context:
    """Everything a rule needs, and where findings go.

    Attributes:
        map: The map (objects rounded as the writer writes them in model view).
        file_view: True when checking a file as read (header values as given); False when
            checking a map as mapkit would write it.
        source: File name for locations, if any.
        raw_lines: The file's lines (bytes, without LF) in file view.
        robot_radius: Robot radius in mm.
        navigation: Run the reachability checks.
        issues: Findings so far.
        stats: Facts for the report (what was checked).
        cache: Values computed once and shared by rules.
    """

    map: MapData
    file_view: bool
    source: str | None = None
    raw_lines: list[bytes] | None = None
    robot_radius: float = 250.0
    navigation: bool = True
    issues: list[Issue] = field(default_factory=list)
    stats: dict[str, Any] = field(default_factory=dict)
    cache: dict[str, Any] = field(default_factory=dict)
    _objects: tuple[MapObject, ...] | None = None

    # -- findings ------------------------------------------------------------------------------

    def add(
        self,
        code: IssueCode,
        message: str,
        *,
        line: int | None = None,
        object: str | None = None,
        xy: tuple[float, float] | None = None,
        severity: Severity | None = None,
    ) -> None:
        """Record a finding with the code's default severity (unless given)."""
        sev = severity or CODE_SUMMARY[code][0]
        if xy is not None:
            xy = (float(xy[0]), float(xy[1]))
        self.issues.append(Issue(code, sev, message, Location(self.source, line, object, xy)))

    # -- the map as checked --------------------------------------------------------------------

    @property
    def category(self) -> str:
        """The intro as read (file view) or as the writer will write it (model view)."""
        return self.map.category if self.file_view else written_category(self.map)

    @property
    def objects(self) -> tuple[MapObject, ...]:
        """Active objects; in model view rounded as the writer writes them."""
        if self._objects is None:
            objs = self.map.objects
            self._objects = objs if self.file_view else tuple(_as_written(o) for o in objs)
        return self._objects

    def object_line(self, index: int) -> int | None:
        """Line number of active object ``index`` when the provenance matches the objects."""
        prov = self.map.provenance
        if prov is None or len(prov.object_lines) != len(self.map.objects):
            return None
        return prov.object_lines[index]

    def child_line(self, index: int) -> int | None:
        """Line number of child object ``index``."""
        prov = self.map.provenance
        if prov is None or len(prov.child_object_lines) != len(self.map.child_objects):
            return None
        return prov.child_object_lines[index]

    def info_line(self, key: str, index: int) -> int | None:
        """Line number of line ``index`` of info section ``key`` (``"MapInfo"``)."""
        prov = self.map.provenance
        if prov is None:
            return None
        lines = prov.info_lines.get(key, ())
        if len(lines) != len(self.map.info.get(key, ())):
            return None
        return lines[index]

    def headers(self) -> Iterator[HeaderView]:
        """One header view per scan."""
        prov = self.map.provenance
        lines = dict(prov.header_lines) if (prov is not None and self.file_view) else {}
        for s in self.map.scans:
            prefix = "" if s.is_default else s.name
            if self.file_view:
                h = s.header
                yield HeaderView(
                    s,
                    prefix,
                    h.num_points,
                    h.num_lines,
                    h.min_pos,
                    h.max_pos,
                    h.line_min_pos,
                    h.line_max_pos,
                    h.resolution,
                    h.points_sorted,
                    h.lines_sorted,
                    lines,
                )
            else:
                has_p, has_l = s.num_points > 0, s.num_lines > 0
                yield HeaderView(
                    s,
                    prefix,
                    s.num_points if has_p else None,
                    s.num_lines if has_l else None,
                    s.min_pos if has_p else None,
                    s.max_pos if has_p else None,
                    s.line_min_pos if has_l else None,
                    s.line_max_pos if has_l else None,
                    None if s.resolution == -1 else s.resolution,
                    s.points_sorted if has_p else None,
                    s.lines_sorted if has_l else None,
                )

    # -- types ---------------------------------------------------------------------------------

    def declared(self) -> dict[str, str]:
        """Declared types, name → class (``GoalType`` ...), from ``MapInfo:``."""
        if "declared" not in self.cache:
            self.cache["declared"] = self.map.declared_types()
        return dict(self.cache["declared"])

    def type_params(self) -> dict[str, dict[str, str]]:
        """Parameters of each declared type (first declaration): ``Name`` → ``{key: value}``."""
        if "type_params" not in self.cache:
            out: dict[str, dict[str, str]] = {}
            for line in self.map.info.get("MapInfo", ()):
                if line and line[0].endswith("Type") and line[0] != "FeedbackType":
                    kv = key_values(line[1:])
                    if "Name" in kv:
                        out.setdefault(kv["Name"], kv)
            self.cache["type_params"] = out
        params: dict[str, dict[str, str]] = self.cache["type_params"]
        return params

    def type_class(self, obj: MapObject) -> str | None:
        """The declaring class of an object's type (base type for ``...WithHeading``)."""
        d = self.declared()
        return d.get(obj.type) or d.get(obj.base_type)

    def is_goal(self, obj: MapObject) -> bool:
        """A point goal: built-in ``Goal``/``GoalWithHeading`` or a declared ``GoalType``."""
        return obj.is_point and (
            obj.base_type in BUILTIN_GOALS or self.type_class(obj) == "GoalType"
        )

    def is_dock(self, obj: MapObject) -> bool:
        """A point dock: built-in ``Dock`` or a declared ``DockType``."""
        return obj.is_point and (
            obj.base_type in BUILTIN_DOCKS or self.type_class(obj) == "DockType"
        )

    def is_home(self, obj: MapObject) -> bool:
        """A ``RobotHome`` in point form."""
        return obj.is_point and obj.type == "RobotHome"

    def destinations(self) -> list[tuple[int, MapObject]]:
        """Goals and docks with their index among the active objects."""
        return [(i, o) for i, o in enumerate(self.objects) if self.is_goal(o) or self.is_dock(o)]

    def homes(self) -> list[tuple[int, MapObject]]:
        """Point ``RobotHome`` objects with their index."""
        return [(i, o) for i, o in enumerate(self.objects) if self.is_home(o)]

    @staticmethod
    def kind(obj: MapObject) -> str:
        """A word for messages: the object's type and name."""
        return f'{obj.type} "{obj.name}"' if obj.name else f"unnamed {obj.type}"

    # -- data ----------------------------------------------------------------------------------

    def all_points(self) -> np.ndarray[Any, np.dtype[np.int64]]:
        """Points of every scan."""
        arrs = [s.points for s in self.map.scans if len(s.points)]
        if len(arrs) == 1:
            return arrs[0]
        return np.concatenate(arrs) if arrs else np.zeros((0, 2), np.int64)

    def all_lines(self) -> np.ndarray[Any, np.dtype[np.int64]]:
        """Line segments of every scan."""
        arrs = [s.lines for s in self.map.scans if len(s.lines)]
        if len(arrs) == 1:
            return arrs[0]
        return np.concatenate(arrs) if arrs else np.zeros((0, 4), np.int64)

    def data_box(self) -> tuple[tuple[int, int], tuple[int, int]] | None:
        """Extents of all data (points and line ends of every scan)."""
        if "data_box" not in self.cache:
            boxes = [b for b in (s.data_bounds() for s in self.map.scans) if b is not None]
            self.cache["data_box"] = (
                None
                if not boxes
                else (
                    (min(b[0][0] for b in boxes), min(b[0][1] for b in boxes)),
                    (max(b[1][0] for b in boxes), max(b[1][1] for b in boxes)),
                )
            )
        box: tuple[tuple[int, int], tuple[int, int]] | None = self.cache["data_box"]
        return box

    @property
    def resolution(self) -> int:
        """The primary scan's grid size in mm (20 when unknown or implausible)."""
        r = self.map.scan.resolution
        return r if 1 <= r <= 1000 else 20


Rule = Callable[[Context], None]

#: Every rule, in the order they run, with the codes it may report.
RULES: list[tuple[Rule, tuple[IssueCode, ...]]] = []


def rule(*codes: IssueCode) -> Callable[[Rule], Rule]:
    """Register a rule and the codes it reports."""

    def deco(fn: Rule) -> Rule:
        RULES.append((fn, codes))
        return fn

    return deco


def lines_list(lines: Sequence[int | None], limit: int = 8) -> str:
    """``"12, 13, 20"`` (or ``"12, 13, ... (40 in all)"``) for messages."""
    known = [str(n) for n in lines if n is not None]
    if not known:
        return ""
    if len(known) <= limit:
        return ", ".join(known)
    return ", ".join(known[:limit]) + f", ... ({len(known)} in all)"
