"""What differs between two maps: objects, info lines, header values, points and lines.

Objects are paired in passes: identical objects first (as many as both maps hold), then by type
and name, then by name alone (a ``Goal`` that gained a heading and became ``GoalWithHeading`` is
*changed*, not removed and added), then by type and place (a renamed object); unnamed objects
left over are paired by type in file order when both maps have the same number of them. A pair
that differs only in position, heading or corners is *moved*; one that differs in anything else
is *changed*.

Points and lines are compared as sets of integer rows (vectorised): how many rows each side has
that the other lacks, and the box they cover. Info lines are compared per section as multisets.

Examples:
    >>> from mapkit.formats.map import loads
    >>> a = loads("2D-Map\\nCairn: Goal 0 0 0 \\"\\" ICON \\"A\\"\\nDATA\\n1 1\\n2 2\\n")
    >>> b = loads("2D-Map\\nCairn: Goal 500 0 0 \\"\\" ICON \\"A\\"\\nDATA\\n1 1\\n3 3\\n")
    >>> d = diff(a, b)
    >>> d.equal, [c.kind for c in d.objects], [(c.added, c.removed) for c in d.data]
    (False, ['moved'], [(1, 1)])
    >>> print("\\n".join(d.summary()))
    moved Goal 'A': (0, 0) -> (500, 0)
    points: 1 added in (3, 3)-(3, 3), 1 removed in (2, 2)-(2, 2) (2 -> 2)
    >>> diff(a, a).equal
    True
"""

from __future__ import annotations

import math
from collections import Counter, defaultdict
from collections.abc import Sequence
from dataclasses import dataclass, fields
from typing import Any

import numpy as np

from mapkit.edit.rows import isin_rows
from mapkit.model import INFO_KEYWORDS, MapData, MapObject, Scan

__all__ = [
    "DataChange",
    "InfoChange",
    "MapDiff",
    "ObjectChange",
    "ValueChange",
    "diff",
    "object_json",
]

_GEOMETRY = ("x", "y", "theta", "from_to")
_Box = tuple[tuple[int, int], tuple[int, int]]


def object_json(o: MapObject) -> dict[str, Any]:
    """An object as JSON-ready data."""
    return {
        "type": o.type,
        "name": o.name,
        "x": o.x,
        "y": o.y,
        "theta": o.theta,
        "description": o.description,
        "icon": o.icon,
        "from_to": list(o.from_to) if o.from_to is not None else None,
    }


def _fmt(v: float) -> str:
    if not math.isfinite(v):
        return f"{v:.0f}"  # "inf" / "nan", as ARIA writes them
    return f"{v:.0f}" if abs(v - round(v)) < 0.05 else f"{v:.1f}"


def _where(o: MapObject) -> str:
    if o.from_to is None:
        return f"({_fmt(o.x)}, {_fmt(o.y)})" + (f" heading {o.theta:g}" if o.theta else "")
    if o.theta:  # a turned rectangle: its corners in the world, not ARIA's stored frame
        corners = " ".join(f"({x:.0f}, {y:.0f})" for x, y in o.corners())  # as `objects`
        return f"corners {corners}, turned {o.theta:g}"
    fx, fy, tx, ty = o.from_to
    return f"({_fmt(fx)}, {_fmt(fy)}) - ({_fmt(tx)}, {_fmt(ty)})"


def _label(o: MapObject) -> str:
    return f"{o.type} {o.name!r}" if o.name else f"unnamed {o.type}"


@dataclass(frozen=True)
class ObjectChange:
    """One object added, removed, moved or changed.

    Attributes:
        kind: ``added``, ``removed``, ``moved`` or ``changed``.
        where: ``objects``, ``inactive_objects`` or ``child_objects``.
        before: The object in A (``None`` when added).
        after: The object in B (``None`` when removed).
        fields: The fields that differ (moved/changed).
    """

    kind: str
    where: str
    before: MapObject | None
    after: MapObject | None
    fields: tuple[str, ...] = ()

    def describe(self) -> str:
        """One line of text."""
        prefix = {"objects": "", "inactive_objects": "inactive ", "child_objects": "child "}[
            self.where
        ]
        if self.kind == "added":
            assert self.after is not None
            return f"added {prefix}{_label(self.after)} at {_where(self.after)}"
        if self.kind == "removed":
            assert self.before is not None
            return f"removed {prefix}{_label(self.before)} at {_where(self.before)}"
        assert self.before is not None and self.after is not None
        if self.kind == "moved":
            return (
                f"moved {prefix}{_label(self.after)}: {_where(self.before)} -> {_where(self.after)}"
            )
        parts = []
        for f in self.fields:
            if f in _GEOMETRY:
                continue
            parts.append(f"{f} {getattr(self.before, f)!r} -> {getattr(self.after, f)!r}")
        if any(f in _GEOMETRY for f in self.fields):
            parts.append(f"{_where(self.before)} -> {_where(self.after)}")
        return f"changed {prefix}{_label(self.before)}: " + "; ".join(parts)

    def to_json(self) -> dict[str, Any]:
        """JSON-ready data."""
        return {
            "kind": self.kind,
            "where": self.where,
            "before": object_json(self.before) if self.before else None,
            "after": object_json(self.after) if self.after else None,
            "fields": list(self.fields),
        }


@dataclass(frozen=True)
class DataChange:
    """Points or lines of one scan source that one map has and the other lacks.

    Attributes:
        source: Scan source name (``""`` for the default).
        kind: ``points`` or ``lines``.
        added: Rows B has that A lacks.
        removed: Rows A has that B lacks.
        added_box: Box of the added rows (``((xmin, ymin), (xmax, ymax))``), or ``None``.
        removed_box: Box of the removed rows.
        count_before: Rows in A.
        count_after: Rows in B.
    """

    source: str
    kind: str
    added: int
    removed: int
    added_box: _Box | None
    removed_box: _Box | None
    count_before: int
    count_after: int

    def describe(self) -> str:
        """One line of text."""
        src = f" of source {self.source!r}" if self.source else ""
        parts = []
        for n, box, verb in (
            (self.added, self.added_box, "added"),
            (self.removed, self.removed_box, "removed"),
        ):
            if n:
                assert box is not None
                parts.append(f"{n} {verb} in ({box[0][0]}, {box[0][1]})-({box[1][0]}, {box[1][1]})")
        if not parts:
            parts.append("same rows, other order or repeats")
        return (
            f"{self.kind}{src}: "
            + ", ".join(parts)
            + f" ({self.count_before} -> {self.count_after})"
        )

    def to_json(self) -> dict[str, Any]:
        """JSON-ready data."""

        def box(b: _Box | None) -> list[list[int]] | None:
            return [list(b[0]), list(b[1])] if b else None

        return {
            "source": self.source,
            "kind": self.kind,
            "added": self.added,
            "removed": self.removed,
            "added_box": box(self.added_box),
            "removed_box": box(self.removed_box),
            "count_before": self.count_before,
            "count_after": self.count_after,
        }


@dataclass(frozen=True)
class InfoChange:
    """Lines of one info section that one map has and the other lacks.

    Attributes:
        section: ``MapInfo`` ... (``_MapInfo`` for the inactive sections).
        added: Lines in B only, each a tuple of tokens.
        removed: Lines in A only.
    """

    section: str
    added: tuple[tuple[str, ...], ...]
    removed: tuple[tuple[str, ...], ...]

    def describe(self) -> list[str]:
        """One line of text per line added or removed."""
        return [f"+ {self.section}: {' '.join(x)}" for x in self.added] + [
            f"- {self.section}: {' '.join(x)}" for x in self.removed
        ]

    def to_json(self) -> dict[str, Any]:
        """JSON-ready data."""
        return {
            "section": self.section,
            "added": [" ".join(x) for x in self.added],
            "removed": [" ".join(x) for x in self.removed],
        }


@dataclass(frozen=True)
class ValueChange:
    """A header value that differs (category, origin, a scan's resolution or flags, ...)."""

    what: str
    before: Any
    after: Any

    def describe(self) -> str:
        """One line of text."""
        return f"{self.what}: {self.before!r} -> {self.after!r}"

    def to_json(self) -> dict[str, Any]:
        """JSON-ready data."""
        return {"what": self.what, "before": self.before, "after": self.after}


@dataclass(frozen=True)
class MapDiff:
    """Everything that differs between map A and map B (empty when they are equal)."""

    objects: tuple[ObjectChange, ...] = ()
    info: tuple[InfoChange, ...] = ()
    data: tuple[DataChange, ...] = ()
    values: tuple[ValueChange, ...] = ()

    @property
    def equal(self) -> bool:
        """True when nothing differs."""
        return not (self.objects or self.info or self.data or self.values)

    def counts(self) -> dict[str, int]:
        """Number of object changes of each kind."""
        c = Counter(x.kind for x in self.objects)
        return {k: c.get(k, 0) for k in ("added", "removed", "moved", "changed")}

    def summary(self) -> list[str]:
        """Lines of text, objects first, then info, values and data."""
        out = [c.describe() for c in self.objects]
        for ic in self.info:
            out.extend(ic.describe())
        out.extend(v.describe() for v in self.values)
        out.extend(d.describe() for d in self.data)
        return out

    def to_json(self) -> dict[str, Any]:
        """JSON-ready data: ``equal``, counts, and each list."""
        return {
            "equal": self.equal,
            "counts": self.counts(),
            "objects": [c.to_json() for c in self.objects],
            "info": [c.to_json() for c in self.info],
            "values": [c.to_json() for c in self.values],
            "data": [c.to_json() for c in self.data],
        }


# -- objects -----------------------------------------------------------------------------------


def _differing(a: MapObject, b: MapObject) -> tuple[str, ...]:
    return tuple(f.name for f in fields(MapObject) if getattr(a, f.name) != getattr(b, f.name))


def _pair_by(
    key: Any, a: Sequence[MapObject], b: Sequence[MapObject], rest_a: list[int], rest_b: list[int]
) -> tuple[list[tuple[int, int]], list[int], list[int]]:
    """Pair the left-over objects whose keys agree, in order (a ``None`` key never pairs)."""
    by_key: dict[Any, list[int]] = defaultdict(list)
    for j in rest_b:
        k = key(b[j])
        if k is not None:
            by_key[k].append(j)
    pairs, still_a = [], []
    for i in rest_a:
        k = key(a[i])
        js = by_key.get(k) if k is not None else None
        if js:
            pairs.append((i, js.pop(0)))
        else:
            still_a.append(i)
    taken = {j for _, j in pairs}
    return pairs, still_a, [j for j in rest_b if j not in taken]


_PASSES = (
    lambda o: o,  # identical: not a change
    lambda o: (o.type.lower(), o.name.lower()) if o.name else None,
    lambda o: o.name.lower() if o.name else None,  # a retyped object (Goal -> GoalWithHeading)
    lambda o: (o.type.lower(), o.x, o.y, o.theta, o.from_to),  # renamed or re-described in place
)


def _pair_objects(a: Sequence[MapObject], b: Sequence[MapObject], where: str) -> list[ObjectChange]:
    rest_a, rest_b = list(range(len(a))), list(range(len(b)))
    pairs: list[tuple[int, int]] = []
    for n, key in enumerate(_PASSES):
        found, rest_a, rest_b = _pair_by(key, a, b, rest_a, rest_b)
        if n:
            pairs.extend(found)
    # Unnamed leftovers: pair by type in file order when the counts agree.
    by_type_a: dict[str, list[int]] = defaultdict(list)
    by_type_b: dict[str, list[int]] = defaultdict(list)
    for i in rest_a:
        if not a[i].name:
            by_type_a[a[i].type].append(i)
    for j in rest_b:
        if not b[j].name:
            by_type_b[b[j].type].append(j)
    for t, ia in by_type_a.items():
        jb = by_type_b.get(t, [])
        if len(ia) == len(jb):
            pairs.extend(zip(ia, jb, strict=True))
            rest_a = [i for i in rest_a if i not in ia]
            rest_b = [j for j in rest_b if j not in jb]
    out = []
    for i, j in sorted(pairs):
        changed = _differing(a[i], b[j])
        kind = "moved" if all(f in _GEOMETRY for f in changed) else "changed"
        out.append(ObjectChange(kind, where, a[i], b[j], changed))
    out.extend(ObjectChange("removed", where, a[i], None) for i in rest_a)
    out.extend(ObjectChange("added", where, None, b[j]) for j in rest_b)
    return out


# -- data --------------------------------------------------------------------------------------


def _box(rows: np.ndarray[Any, Any]) -> _Box | None:
    if len(rows) == 0:
        return None
    xy = rows.reshape(-1, 2)
    lo, hi = xy.min(axis=0), xy.max(axis=0)
    return (int(lo[0]), int(lo[1])), (int(hi[0]), int(hi[1]))


def _data_change(
    source: str, kind: str, a: np.ndarray[Any, Any], b: np.ndarray[Any, Any]
) -> DataChange | None:
    if a is b or (a.shape == b.shape and np.array_equal(a, b)):
        return None
    if len(a) and len(b):
        only_a = a[~isin_rows(a, b)]
        only_b = b[~isin_rows(b, a)]
    else:
        only_a, only_b = a, b
    return DataChange(
        source, kind, len(only_b), len(only_a), _box(only_b), _box(only_a), len(a), len(b)
    )


def _scan_values(sa: Scan, sb: Scan, label: str) -> list[ValueChange]:
    out = []
    for f in ("display", "resolution", "points_sorted", "lines_sorted"):
        if getattr(sa, f) != getattr(sb, f):
            out.append(ValueChange(f"{label}{f}", getattr(sa, f), getattr(sb, f)))
    # Boxes are written only for non-empty data; on their own they differ only for equal data.
    if sa.num_points and np.array_equal(sa.points, sb.points):
        for f in ("min_pos", "max_pos"):
            if getattr(sa, f) != getattr(sb, f):
                out.append(ValueChange(f"{label}{f}", getattr(sa, f), getattr(sb, f)))
    if sa.num_lines and np.array_equal(sa.lines, sb.lines):
        for f in ("line_min_pos", "line_max_pos"):
            if getattr(sa, f) != getattr(sb, f):
                out.append(ValueChange(f"{label}{f}", getattr(sa, f), getattr(sb, f)))
    return out


# -- info --------------------------------------------------------------------------------------


def _multiset_diff(a: Sequence[Any], b: Sequence[Any]) -> tuple[tuple[Any, ...], tuple[Any, ...]]:
    cb = Counter(b)
    ca = Counter(a)
    removed = []
    for x in a:
        if cb[x] > 0:
            cb[x] -= 1
        else:
            removed.append(x)
    added = []
    for x in b:
        if ca[x] > 0:
            ca[x] -= 1
        else:
            added.append(x)
    return tuple(added), tuple(removed)


def diff(a: MapData, b: MapData) -> MapDiff:
    """What changed from map ``a`` to map ``b``.

    Args:
        a: The first map ("before").
        b: The second map ("after").

    Returns:
        A :class:`MapDiff`; ``diff(a, a).equal`` is always true.
    """
    objects: list[ObjectChange] = []
    for where in ("objects", "inactive_objects", "child_objects"):
        objects.extend(_pair_objects(getattr(a, where), getattr(b, where), where))
    info: list[InfoChange] = []
    for prefix, fa, fb in (("", a.info, b.info), ("_", a.inactive_info, b.inactive_info)):
        for key in INFO_KEYWORDS:
            la, lb = fa.get(key, ()), fb.get(key, ())
            if la == lb:
                continue
            added, removed = _multiset_diff(la, lb)
            if added or removed:
                info.append(InfoChange(prefix + key, added, removed))
    values: list[ValueChange] = []
    if a.category != b.category:
        values.append(ValueChange("category", a.category, b.category))
    if a.origin_lla != b.origin_lla:
        values.append(ValueChange("origin_lla", a.origin_lla, b.origin_lla))
    added, removed = _multiset_diff(a.remainder, b.remainder)
    values.extend(ValueChange("unknown line", x, None) for x in removed)
    values.extend(ValueChange("unknown line", None, x) for x in added)
    data: list[DataChange] = []
    names_b = {s.name.lower(): s for s in b.scans}
    names_a = {s.name.lower() for s in a.scans}
    for i, sa in enumerate(a.scans):
        sb = names_b.get(sa.name.lower())
        if sb is None and i == 0 and b.scans[0].is_default and sa.is_default:
            sb = b.scans[0]
        label = f"source {sa.name!r} " if sa.name else ""
        if sb is None:
            values.append(ValueChange("source", sa.name, None))
            sb = Scan(name=sa.name)
        else:
            values.extend(_scan_values(sa, sb, label))
        for kind in ("points", "lines"):
            ch = _data_change(sa.name, kind, getattr(sa, kind), getattr(sb, kind))
            if ch is not None:
                data.append(ch)
    for j, sb in enumerate(b.scans):
        if sb.name.lower() in names_a or (j == 0 and sb.is_default and a.scans[0].is_default):
            continue
        values.append(ValueChange("source", None, sb.name))
        for kind in ("points", "lines"):
            ch = _data_change(
                sb.name,
                kind,
                np.zeros((0, 2 if kind == "points" else 4), np.int64),
                getattr(sb, kind),
            )
            if ch is not None:
                data.append(ch)
    return MapDiff(tuple(objects), tuple(info), tuple(data), tuple(values))
