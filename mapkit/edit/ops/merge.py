"""Merging one map into another, with a policy for clashing object names."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from mapkit._text import plural
from mapkit.edit.checks import (
    check_data_range,
    check_span,
)
from mapkit.edit.declared import (
    unquote,
    with_params,
)
from mapkit.edit.ops.common import _check_object_range
from mapkit.edit.ops.data import _update_scan, rows_not_in
from mapkit.edit.ops.objects import _drop_orphan_params
from mapkit.edit.selection import Region, clip_lines, cut_lines, points_inside
from mapkit.errors import EditError
from mapkit.model import MapData, MapObject, Scan

__all__ = ["CLASH_POLICIES", "merge", "merge_clashes"]


#: What :func:`merge` does with an object of OTHER whose name a different BASE object has.
CLASH_POLICIES = ("keep", "rename", "base", "other", "error")


# -- merge -------------------------------------------------------------------------------------


def merge_clashes(base: MapData, other: MapData) -> list[tuple[MapObject, MapObject]]:
    """Pairs ``(base object, other object)`` with the same name (case-insensitive) that differ."""
    by_name: dict[str, list[MapObject]] = {}
    for o in base.objects:
        if o.name:
            by_name.setdefault(o.name.lower(), []).append(o)
    out = []
    for o in other.objects:
        for b in by_name.get(o.name.lower(), []) if o.name else []:
            if b != o:
                out.append((b, o))
    return out


def _free_name(name: str, taken: set[str]) -> str:
    k = 2
    while f"{name} {k}".lower() in taken:
        k += 1
    return f"{name} {k}"


def _merge_mapinfo(base: MapData, other: MapData) -> tuple[tuple[str, ...], ...]:
    """Base's MapInfo lines plus other's type declarations (with their ArgDesc lines) base lacks."""
    have = set(base.declared_types())
    lines = list(base.info.get("MapInfo", ()))
    adding = False
    for line in other.info.get("MapInfo", ()):
        if line and line[0].endswith("Type"):
            name = next((unquote(t)[5:] for t in line[1:] if unquote(t).startswith("Name=")), None)
            adding = name is not None and name not in have
        elif not (line and line[0] == "ArgDesc"):
            adding = False
        if adding:
            lines.append(line)
    return tuple(lines)


def merge(
    base: MapData, other: MapData, *, region: Region | None = None, on_clash: str = "keep"
) -> MapData:
    """Mapper3's Insert Map: data from OTHER goes into BASE; objects of both are kept.

    With a ``region``, the data inside it comes from OTHER (BASE's points and line parts there are
    removed) and the rest from BASE; without one, OTHER's points and lines are added (rows BASE
    already has are not repeated). Scans are matched by source name (primary with primary).

    OTHER's objects are appended; an object equal to one BASE has is not repeated. Name clashes
    (same name, different object, see :func:`merge_clashes`) follow ``on_clash``: ``keep`` both,
    ``rename`` OTHER's (``"Name 2"``), keep ``base``'s only, keep ``other``'s only, or ``error``.
    Type declarations and ``CairnInfo: Params`` lines that OTHER's objects need are added; every
    other info section is BASE's.

    Raises:
        EditError: A bad policy, a clash with ``error``, data out of range, or an OTHER source
            BASE cannot take.
    """
    if on_clash not in CLASH_POLICIES:
        raise EditError(f"on_clash must be one of {', '.join(CLASH_POLICIES)}, got {on_clash!r}")
    if region is not None and not isinstance(region, Region):
        raise EditError(f"merge needs a Region, got {region!r}")
    # Data.
    scans = list(base.scans)
    for j, os_ in enumerate(other.scans):
        if j == 0:
            i: int | None = 0
        else:
            i = next((k for k, s in enumerate(scans) if s.name.lower() == os_.name.lower()), None)
        if i is None:
            if any(s.name == "" for s in scans):
                raise EditError(
                    f"OTHER has a scan source {os_.name!r} that BASE lacks, and BASE's "
                    "sources have no names to put it beside"
                )
            scans.append(Scan(name=os_.name, display=os_.display, resolution=os_.resolution))
            i = len(scans) - 1
        bs = scans[i]
        if region is not None:
            keep_base = ~points_inside(bs.points, region)
            take = points_inside(os_.points, region)
            pts = np.concatenate([bs.points[keep_base], os_.points[take]])
            lns = np.concatenate([cut_lines(bs.lines, region), clip_lines(os_.lines, region)])
        else:
            add_p = os_.points[rows_not_in(os_.points, bs.points)]
            add_l = os_.lines[rows_not_in(os_.lines, bs.lines)]
            check_data_range(add_p, "OTHER's points")
            check_data_range(add_l, "OTHER's lines")
            pts = np.concatenate([bs.points, add_p])
            lns = np.concatenate([bs.lines, add_l])
        same_p = len(pts) == len(bs.points) and np.array_equal(pts, bs.points)
        same_l = len(lns) == len(bs.lines) and np.array_equal(lns, bs.lines)
        if not (same_p and same_l):
            scans[i] = _update_scan(
                bs, points=None if same_p else pts, lines=None if same_l else lns
            )
    # Objects.
    clashes = merge_clashes(base, other)
    if clashes and on_clash == "error":
        listed = ", ".join(repr(o.name) for _, o in clashes[:10])
        clash_words = plural(len(clashes), "name clash", "name clashes")
        raise EditError(f"{clash_words} between the maps: {listed}")
    clash_names = {o.name.lower() for _, o in clashes}
    objects = list(base.objects)
    if on_clash == "other":
        objects = [o for o in objects if o.name.lower() not in clash_names or not o.name]
    taken = {o.name.lower() for o in objects if o.name}
    renamed: dict[str, str] = {}
    added: list[MapObject] = []
    for o in other.objects:
        if o in base.objects:
            continue
        if o.name and o.name.lower() in clash_names:
            if on_clash == "base":
                continue
            if on_clash == "rename":
                new_name = _free_name(o.name, taken | {a.name.lower() for a in added})
                renamed[o.name.lower()] = new_name
                o = replace(o, name=new_name)
        added.append(o)
        if o.name:
            taken.add(o.name.lower())
    objects.extend(added)
    inactive = list(base.inactive_objects) + [
        o for o in other.inactive_objects if o not in base.inactive_objects
    ]
    children = list(base.child_objects) + [
        o for o in other.child_objects if o not in base.child_objects
    ]
    out = base.replace(
        scans=tuple(scans),
        objects=tuple(objects),
        inactive_objects=tuple(inactive),
        child_objects=tuple(children),
    )
    # Declarations and parameters the added objects need.
    mapinfo = _merge_mapinfo(base, other)
    if mapinfo != base.info.get("MapInfo", ()):
        info = dict(out.info)
        info["MapInfo"] = mapinfo
        out = out.replace(info=info)
    if on_clash == "other":
        out = _drop_orphan_params(out, [b.name for b, _ in clashes])
    base_params = {
        unquote(ln[1]).lower()
        for ln in out.info.get("CairnInfo", ())
        if len(ln) > 1 and ln[0] == "Params"
    }
    added_names = {o.name.lower() for o in added if o.name}
    for line in other.info.get("CairnInfo", ()):
        if len(line) < 2 or line[0] != "Params":
            continue
        n = unquote(line[1]).lower()
        target = renamed.get(n, unquote(line[1]))
        if target.lower() in added_names and (
            target.lower() not in base_params or on_clash == "other"
        ):
            out = with_params(out, ("Params", f'"{target}"', *line[2:]))
    for line in other.info.get("CairnInfo", ()):
        if line and line[0] == "GroupMember" and line not in out.info.get("CairnInfo", ()):
            info = dict(out.info)
            info["CairnInfo"] = (*out.info.get("CairnInfo", ()), line)
            out = out.replace(info=info)
    for o in added:
        _check_object_range(o, out.object_shape(o))
    check_span(base, out)
    return out
