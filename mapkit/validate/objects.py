"""4xx: map objects (goals, docks, homes, forbidden lines and areas, custom types)."""

from __future__ import annotations

import math
from collections import defaultdict
from typing import Any

import numpy as np

from mapkit.diagnostics import IssueCode as C
from mapkit.formats.map import tokenize
from mapkit.model import BUILTIN_LINE_TYPES, MapObject
from mapkit.validate._context import BUILTIN_TYPES, Context, lines_list, rule
from mapkit.validate._spatial import nearest_points, nearest_segments, point_segment_distance

__all__ = ["in_rectangle"]

_POINT_CLASSES = {"GoalType", "DockType", "LocationType"}

#: How far (mm) outside the data's box an object may lie before it is reported.
OUTSIDE_MARGIN = 1000.0


def in_rectangle(obj: MapObject, x: float, y: float) -> bool:
    """True when (x, y) lies in a rectangle object (ARIA's rule: corners rotated about the origin).

    Examples:
        >>> a = MapObject("ForbiddenArea", 0, 0, 180, from_to=(-21124, 1564, 6001, 7648))
        >>> in_rectangle(a, 0, -5000), in_rectangle(a, 0, 5000)
        (True, False)
    """
    assert obj.from_to is not None
    fx, fy, tx, ty = obj.from_to
    if not obj.is_finite:
        return False  # an object at infinity (ARIA reads `inf`) is nowhere
    c, s = math.cos(math.radians(obj.theta)), math.sin(math.radians(obj.theta))
    u, v = c * x + s * y, -s * x + c * y  # rotate back by -theta
    return min(fx, tx) <= u <= max(fx, tx) and min(fy, ty) <= v <= max(fy, ty)


def _edges(obj: MapObject) -> np.ndarray[Any, Any]:
    """The outline of a rectangle or a line object as segments (x1 y1 x2 y2)."""
    c = obj.corners()
    if len(c) == 2 or (obj.from_to is not None and obj.type in BUILTIN_LINE_TYPES):
        fx, fy, tx, ty = obj.from_to  # type: ignore[misc]
        return np.array([[fx, fy, tx, ty]], dtype=np.float64)
    return np.array([[*c[i], *c[(i + 1) % 4]] for i in range(4)], dtype=np.float64)


@rule(C.NON_FINITE_OBJECT, C.INFINITE_OBJECT, C.UNWRITABLE_TEXT)
def writable(ctx: Context) -> None:
    """Everything in the model can be written and read back as it is."""
    for i, o in enumerate(ctx.map.objects):
        vals = (o.x, o.y, o.theta, *(o.from_to or ()))
        if any(math.isnan(v) for v in vals):
            ctx.add(
                C.NON_FINITE_OBJECT,
                f"{ctx.kind(o)} has a NaN coordinate or heading: ARIA crashes on it",
                line=ctx.object_line(i),
                object=o.name,
            )
        elif not all(math.isfinite(v) for v in vals):
            ctx.add(
                C.INFINITE_OBJECT,
                f"{ctx.kind(o)} has an infinite coordinate or heading: ARIA reads and writes it "
                "as inf, but no robot can go there; it is left out of drawings and checks",
                line=ctx.object_line(i),
                object=o.name,
            )
    if ctx.file_view:
        return  # read from a file: the reader already reported what it could not keep
    for label, objs in (
        ("Cairn:", ctx.map.objects),
        ("_Cairn:", ctx.map.inactive_objects),
        ("ChildCairn:", ctx.map.child_objects),
    ):
        for o in objs:
            problems = []
            if not o.type or tokenize(o.type) != [o.type] or o.type.startswith('"'):
                problems.append(f"type {o.type!r} is not one token")
            for what, text in (("name", o.name), ("description", o.description)):
                if tokenize(f'"{text}"') != [f'"{text}"'] or "\n" in text or "\r" in text:
                    problems.append(f"{what} {text!r} cannot be quoted without loss")
            if not o.icon or tokenize(o.icon) != [o.icon]:
                problems.append(f"icon {o.icon!r} is not one token")
            if problems:
                ctx.add(
                    C.UNWRITABLE_TEXT,
                    f"{label} {ctx.kind(o)}: " + "; ".join(problems),
                    object=o.name,
                )
    for section in (ctx.map.info, ctx.map.inactive_info):
        for key, lines in section.items():
            for n, line in enumerate(lines):
                joined = " ".join(line)
                if "\n" in joined or "\r" in joined or tokenize(joined) != list(line):
                    ctx.add(
                        C.UNWRITABLE_TEXT,
                        f"{key}: line {n + 1} ({joined[:50]!r}) reads back as other tokens",
                    )
    for text in ctx.map.remainder:
        if "\n" in text or "\r" in text:
            ctx.add(C.UNWRITABLE_TEXT, f"unknown line {text[:50]!r} contains a line break")
    for s in ctx.map.scans:
        if s.name and (tokenize(s.name) != [s.name] or s.name.startswith('"')):
            ctx.add(C.UNWRITABLE_TEXT, f"scan source name {s.name!r} is not one token")


@rule(C.DUPLICATE_NAME, C.EMPTY_NAME)
def names(ctx: Context) -> None:
    """Goal and dock names: present and unique (case-insensitively, as ARIA looks them up)."""
    seen: dict[str, list[tuple[int, MapObject]]] = defaultdict(list)
    required = {
        name for name, params in ctx.type_params().items() if params.get("NameRequired") == "1"
    }
    for i, o in enumerate(ctx.objects):
        dest = ctx.is_goal(o) or ctx.is_dock(o)
        if not o.name:
            if dest or o.type in required or o.base_type in required:
                why = (
                    "it is a goal or dock: nothing can send the robot there"
                    if dest
                    else "its type declares NameRequired=1"
                )
                ctx.add(
                    C.EMPTY_NAME,
                    f"{o.type} at ({o.x:.0f}, {o.y:.0f}) has no name but {why}",
                    line=ctx.object_line(i),
                    xy=(o.x, o.y),
                )
            continue
        if dest:
            seen[o.name.lower()].append((i, o))
    for group in seen.values():
        if len(group) < 2:
            continue
        i1, second = group[1]
        others = lines_list([ctx.object_line(i) for i, _ in group])
        ctx.add(
            C.DUPLICATE_NAME,
            f"{len(group)} goals/docks are named {second.name!r}"
            + (f" (lines {others})" if others else "")
            + ": ARIA compares names case-insensitively and always picks the first",
            line=ctx.object_line(i1),
            object=second.name,
            xy=(second.x, second.y),
        )


@rule(C.UNDECLARED_TYPE, C.TYPE_NOT_LISTED, C.WRONG_SHAPE_FOR_TYPE)
def types(ctx: Context) -> None:
    """Object types: built in or declared, listed when the map lists its types, right shape."""
    declared = ctx.declared()
    undeclared: dict[str, list[int | None]] = defaultdict(list)
    shapes: dict[tuple[str, str], list[int | None]] = defaultdict(list)
    objs = [(o, ctx.object_line(i)) for i, o in enumerate(ctx.objects)]
    objs += [(o, ctx.child_line(i)) for i, o in enumerate(ctx.map.child_objects)]
    for o, line in objs:
        cls = declared.get(o.type) or (declared.get(o.base_type) if o.is_point else None)
        if cls is None and o.type not in BUILTIN_TYPES and o.base_type not in BUILTIN_TYPES:
            undeclared[o.type].append(line)
            continue
        form = (
            "point"
            if o.is_point
            else "line"
            if (o.type in BUILTIN_LINE_TYPES or cls == "BoundaryType")
            else "rectangle"
        )
        want = None
        if cls in _POINT_CLASSES or (cls is None and o.base_type in {"Goal", "Dock"}):
            want = "point"
        elif cls == "BoundaryType" or (cls is None and o.type in BUILTIN_LINE_TYPES):
            want = "line"
        elif cls == "SectorType" or (cls is None and o.type == "ForbiddenArea"):
            want = "rectangle"
        if want is not None and form != want and not (want == "line" and form == "rectangle"):
            shapes[
                (
                    o.type,
                    f"is a {want} type but the object has "
                    f"{'no corners' if o.is_point else 'corners'}",
                )
            ].append(line)
        elif want == "line" and o.is_point:
            shapes[(o.type, "is a line type but the object has no end points")].append(line)
    for t, lines in undeclared.items():
        where = lines_list(lines)
        ctx.add(
            C.UNDECLARED_TYPE,
            f"{len(lines)} object{'s' if len(lines) > 1 else ''} of type {t!r}"
            + (f" (line{'s' if len(lines) > 1 else ''} {where})" if where else "")
            + ": the type is neither built in nor declared in MapInfo:, so ARIA's tools show "
            "it as a plain object and the robot ignores it",
            line=lines[0],
            object=t,
        )
    for (t, what), lines in shapes.items():
        where = lines_list(lines)
        ctx.add(
            C.WRONG_SHAPE_FOR_TYPE,
            f"{len(lines)} {t} object{'s' if len(lines) > 1 else ''}: {t} {what}"
            + (f" (line{'s' if len(lines) > 1 else ''} {where})" if where else ""),
            line=lines[0],
            object=t,
        )
    # A map that declares goal (dock) types must list every goal (dock) type it uses.
    for builtin, cls in (("Goal", "GoalType"), ("Dock", "DockType")):
        listed = [n for n, c in declared.items() if c == cls]
        if not listed or builtin in declared:
            continue
        used = [
            (i, o)
            for i, o in enumerate(ctx.objects)
            if o.is_point and o.base_type == builtin and o.type not in declared
        ]
        if used:
            i, o = used[0]
            ctx.add(
                C.TYPE_NOT_LISTED,
                f"{len(used)} {builtin} object{'s' if len(used) > 1 else ''} but MapInfo: "
                f"lists {cls}s ({', '.join(listed[:5])}) without Name={builtin}: a map that "
                f"declares {cls}s must list every one it uses, so ARIA's {builtin.lower()} "
                f"lists leave these out; add 'MapInfo: {cls} Name={builtin}'",
                line=ctx.object_line(i),
                object=o.name,
            )


@rule(C.HEADING_NOT_NORMALISED)
def headings(ctx: Context) -> None:
    """Headings written outside (-180, 180] (seen in the file's text; ARIA normalises them)."""
    if ctx.raw_lines is None or ctx.map.provenance is None:
        return
    prov = ctx.map.provenance
    found: list[tuple[int, str, float]] = []
    for lineno in (*prov.object_lines, *prov.inactive_object_lines, *prov.child_object_lines):
        if not 0 < lineno <= len(ctx.raw_lines):
            continue
        toks = tokenize(ctx.raw_lines[lineno - 1].decode("utf-8", "surrogateescape"))
        try:
            th = float(toks[4])
        except (IndexError, ValueError):
            continue
        if math.isfinite(th) and not -180.0 < th <= 180.0:
            found.append((lineno, toks[7] if len(toks) > 7 else "", th))
    if found:
        lineno, name, th = found[0]
        more = (
            f" and {len(found) - 1} more (lines {lines_list([f[0] for f in found[1:]])})"
            if len(found) > 1
            else ""
        )
        ctx.add(
            C.HEADING_NOT_NORMALISED,
            f"heading {th:g} of {name or 'an object'}{more} is outside (-180, 180]: ARIA "
            "normalises it on load and writes it back changed",
            line=lineno,
        )


@rule(C.DEGENERATE_FORBIDDEN)
def degenerate(ctx: Context) -> None:
    """Forbidden areas with no area and forbidden lines with no length stop nothing."""
    for i, o in enumerate(ctx.objects):
        if o.from_to is None or o.type not in ("ForbiddenArea", "ForbiddenLine"):
            continue
        fx, fy, tx, ty = o.from_to
        if o.type == "ForbiddenLine" and (fx, fy) == (tx, ty):
            ctx.add(
                C.DEGENERATE_FORBIDDEN,
                f"{ctx.kind(o)} at ({fx:.0f}, {fy:.0f}) has no length: it forbids nothing",
                line=ctx.object_line(i),
                object=o.name or None,
                xy=(fx, fy),
            )
        elif o.type == "ForbiddenArea" and (fx == tx or fy == ty):
            cx, cy = np.mean(o.corners(), axis=0)
            ctx.add(
                C.DEGENERATE_FORBIDDEN,
                f"{ctx.kind(o)} is {abs(tx - fx):.0f} x {abs(ty - fy):.0f} mm: an area without "
                "area forbids nothing (draw a ForbiddenLine for a barrier)",
                line=ctx.object_line(i),
                object=o.name or None,
                xy=(cx, cy),
            )


@rule(C.OBJECT_OUTSIDE_MAP)
def outside(ctx: Context) -> None:
    """Objects (entirely) outside the box of the map's data."""
    box = ctx.data_box()
    if box is None:
        return
    (x0, y0), (x1, y1) = box
    # Forbidden lines drawn along the outside of a building are normal: allow a margin.
    margin = max(OUTSIDE_MARGIN, 2 * ctx.robot_radius)
    for i, o in enumerate(ctx.objects):
        if o.from_to is not None and o.type not in ("ForbiddenArea", "ForbiddenLine"):
            fx, fy, tx, ty = o.from_to
            if fx == tx and fy == ty:
                continue  # zero-size anchors (Omron FeedbackHandler ...) sit wherever
        pts = np.array(o.corners(), dtype=np.float64)
        if not np.all(np.isfinite(pts)):
            continue
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        if hi[0] < x0 - margin or lo[0] > x1 + margin or hi[1] < y0 - margin or lo[1] > y1 + margin:
            cx, cy = (lo + hi) / 2
            what = "" if o.is_point else "entirely "
            ctx.add(
                C.OBJECT_OUTSIDE_MAP,
                f"{ctx.kind(o)} at ({cx:.0f}, {cy:.0f}) is {what}outside the map's data "
                f"({x0}, {y0}) .. ({x1}, {y1}) by more than {margin:.0f} mm",
                line=ctx.object_line(i),
                object=o.name or None,
                xy=(cx, cy),
            )


@rule(C.GOAL_IN_WALL, C.GOAL_NEAR_WALL, C.GOAL_IN_FORBIDDEN_AREA)
def clearance(ctx: Context) -> None:
    """Goals, docks and homes: not on a wall, not within the robot radius of one, not forbidden."""
    targets = [
        (i, o)
        for i, o in enumerate(ctx.objects)
        if (ctx.is_goal(o) or ctx.is_dock(o) or ctx.is_home(o)) and o.is_finite
    ]
    if not targets:
        return
    r = float(ctx.robot_radius)
    half = ctx.resolution / 2.0
    q = np.array([(o.x, o.y) for _, o in targets], dtype=np.float64)
    search = max(r, 2 * half)
    pts = ctx.all_points()
    dp, ip = nearest_points(pts, q, search)
    dl, il = nearest_segments(ctx.all_lines(), q, search)
    # Objects at infinity (MK416) are nowhere: they neither forbid nor block anything.
    areas = [
        o
        for o in ctx.objects
        if o.type == "ForbiddenArea" and o.from_to is not None and o.is_finite
    ]
    flines = [
        o
        for o in ctx.objects
        if o.type == "ForbiddenLine" and o.from_to is not None and o.is_finite
    ]
    fseg = np.array([o.from_to for o in flines], dtype=np.float64).reshape(-1, 4)
    # All forbidden-area edges in one array; area k owns rows 4k..4k+3.
    aseg = np.concatenate([_edges(a) for a in areas]) if areas else np.zeros((0, 4))
    for k, (i, o) in enumerate(targets):
        line, name, xy = ctx.object_line(i), o.name or None, (o.x, o.y)
        inside = [a for a in areas if in_rectangle(a, o.x, o.y)]
        if inside:
            ctx.cache.setdefault("forbidden_targets", set()).add(i)
            a = inside[0]
            label = f' "{a.name}"' if a.name else ""
            ctx.add(
                C.GOAL_IN_FORBIDDEN_AREA,
                f"{ctx.kind(o)} at ({o.x:.0f}, {o.y:.0f}) is inside ForbiddenArea{label}: the "
                "robot may not drive there",
                line=line,
                object=name,
                xy=xy,
            )
        # On a wall: inside an occupied cell (points) or on a line segment.
        hit = None
        if ip[k] >= 0:
            px, py = pts[ip[k]]
            if max(abs(px - o.x), abs(py - o.y)) <= half:
                hit = f"the occupied cell at ({px}, {py})"
        if hit is None and dl[k] <= half:
            hit = "a wall line"
        if hit is not None:
            ctx.add(
                C.GOAL_IN_WALL,
                f"{ctx.kind(o)} at ({o.x:.0f}, {o.y:.0f}) is on {hit}: the robot cannot stand "
                "there",
                line=line,
                object=name,
                xy=xy,
            )
            continue
        if r <= 0:
            continue
        near: list[tuple[float, str]] = []
        if ip[k] >= 0:
            near.append((max(0.0, dp[k] - half), "a wall (map points)"))
        if il[k] >= 0:
            near.append((dl[k], "a wall line"))
        if len(fseg):
            near.append((float(point_segment_distance(q[k], fseg).min()), "a ForbiddenLine"))
        if not inside and len(aseg):
            per_area = point_segment_distance(q[k], aseg).reshape(len(areas), 4).min(axis=1)
            j = int(np.argmin(per_area))
            a = areas[j]
            near.append(
                (float(per_area[j]), f'ForbiddenArea "{a.name}"' if a.name else "a ForbiddenArea")
            )
        if near:
            dist, what = min(near)
            if dist < r:
                ctx.add(
                    C.GOAL_NEAR_WALL,
                    f"{ctx.kind(o)} at ({o.x:.0f}, {o.y:.0f}) is {dist:.0f} mm from {what}, "
                    f"closer than the robot radius ({r:.0f} mm): the robot cannot reach the "
                    "exact pose",
                    line=line,
                    object=name,
                    xy=xy,
                )


@rule(C.NO_ROBOT_HOME, C.SEVERAL_ROBOT_HOMES)
def homes(ctx: Context) -> None:
    """RobotHome: MobileSim and ARNL start from it."""
    homes = [(i, o) for i, o in enumerate(ctx.objects) if o.type == "RobotHome"]
    if not homes:
        docks = [o for o in ctx.objects if ctx.is_dock(o)]
        start = f"the first dock ({docks[0].name or 'unnamed'})" if docks else "(0, 0)"
        ctx.add(
            C.NO_ROBOT_HOME,
            f"no RobotHome: MobileSim starts the robot at {start} and ARNL's start-up "
            "localisation has no home pose to try; reachability is checked between the goals "
            "instead",
        )
    elif len(homes) > 1:
        names = ", ".join(
            repr(h.name) if h.name else f"({h.x:.0f}, {h.y:.0f})" for _, h in homes[:6]
        )
        ctx.add(
            C.SEVERAL_ROBOT_HOMES,
            f"{len(homes)} RobotHome objects ({names}): ARNL tries each on start-up, MobileSim "
            "uses the first; reachability is checked from the first",
            line=ctx.object_line(homes[1][0]),
            object=homes[1][1].name or None,
        )
