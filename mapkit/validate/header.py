"""2xx: the header against the data, the intro against the content, keywords that look misspelt."""

from __future__ import annotations

import difflib
from typing import Any

import numpy as np

from mapkit._text import plural
from mapkit.diagnostics import IssueCode as C
from mapkit.model import CATEGORIES, INFO_KEYWORDS
from mapkit.validate._context import Context, HeaderView, rule, unquote

__all__ = ["is_sorted"]

_PLAUSIBLE_RESOLUTION = (1, 1000)


def is_sorted(arr: np.ndarray[Any, Any]) -> bool:
    """True when rows are in ARIA's sorted order (lexicographic by column), in O(n).

    Examples:
        >>> is_sorted(np.array([[0, 5], [0, 7], [1, -3]])), is_sorted(np.array([[1, 0], [0, 9]]))
        (True, False)
    """
    if len(arr) < 2:
        return True
    a, b = arr[:-1], arr[1:]
    # Row i <= row i+1 lexicographically: decided by the first column where they differ.
    diff = a != b
    first = np.argmax(diff, axis=1)
    rows = np.arange(len(a))
    any_diff = diff[rows, first]
    ok = ~any_diff | (a[rows, first] < b[rows, first])
    return bool(ok.all())


def _box_of(xy: np.ndarray[Any, Any]) -> tuple[tuple[int, int], tuple[int, int]] | None:
    if len(xy) == 0:
        return None
    lo, hi = xy.min(axis=0), xy.max(axis=0)
    return (int(lo[0]), int(lo[1])), (int(hi[0]), int(hi[1]))


@rule(C.NUM_POINTS_MISMATCH, C.NUM_LINES_MISMATCH, C.COUNT_NOT_POSITIVE)
def counts(ctx: Context) -> None:
    """NumPoints:/NumLines: against the rows ARIA keeps (file view only)."""
    if not ctx.file_view:
        return
    for h in ctx.headers():
        for key, claimed, actual, what, code in (
            ("NumPoints:", h.num_points, h.scan.num_points, "DATA", C.NUM_POINTS_MISMATCH),
            ("NumLines:", h.num_lines, h.scan.num_lines, "LINES", C.NUM_LINES_MISMATCH),
        ):
            if claimed is None:
                continue
            kw = h.prefix + key
            if claimed <= 0:
                ctx.add(
                    C.COUNT_NOT_POSITIVE,
                    f"{kw} {claimed}: AriaCoda refuses the file (ARIA 2.9.4 and older accept it)"
                    + (f"; the file has {plural(actual, what + ' row')}" if actual else ""),
                    line=h.line(key),
                )
            elif claimed != actual:
                ctx.add(
                    code,
                    f"{kw} {claimed} but the file has {plural(actual, what + ' row')} ARIA keeps: "
                    "ARIA's "
                    f"ArMap uses {actual}, code that loads with ArMapSimple (e.g. the map "
                    f"server) trusts {claimed}",
                    line=h.line(key),
                )


def _check_box(
    ctx: Context,
    h: HeaderView,
    kind: str,
    data: np.ndarray[Any, Any],
    lo: tuple[int, int] | None,
    hi: tuple[int, int] | None,
) -> None:
    kmin, kmax = ("MinPos:", "MaxPos:") if kind == "points" else ("LineMinPos:", "LineMaxPos:")
    box = _box_of(data)
    if box is None:
        return
    (dx0, dy0), (dx1, dy1) = box
    if lo is None or hi is None:
        if ctx.file_view:
            missing = " or ".join(h.prefix + k for k, v in ((kmin, lo), (kmax, hi)) if v is None)
            n = len(data) if kind == "points" else len(data) // 2
            ctx.add(
                C.BOX_MISSING,
                f"{n} {kind if n != 1 else kind[:-1]} but no {missing} line; ARIA then starts "
                f"the box at (0, 0), so it includes the origin; the {kind} span "
                f"({dx0}, {dy0}) .. ({dx1}, {dy1})",
                line=h.line(kmin if lo is None else kmax),
            )
        return
    (x0, y0), (x1, y1) = lo, hi
    if x0 > dx0 or y0 > dy0 or x1 < dx1 or y1 < dy1:
        ctx.add(
            C.BOX_EXCLUDES_DATA,
            f"{h.prefix}{kmin} {x0} {y0} / {h.prefix}{kmax} {x1} {y1} do not enclose the "
            f"{kind}, which span ({dx0}, {dy0}) .. ({dx1}, {dy1}); ARIA widens the box on load, "
            "code that trusts the header clips the map",
            line=h.line(kmin if (x0 > dx0 or y0 > dy0) else kmax),
        )
    elif (x0, y0, x1, y1) != (dx0, dy0, dx1, dy1):
        ctx.add(
            C.BOX_LARGER_THAN_DATA,
            f"{h.prefix}{kmin} {x0} {y0} / {h.prefix}{kmax} {x1} {y1} are wider than the "
            f"{kind} ({dx0}, {dy0}) .. ({dx1}, {dy1}); ARIA keeps the wider box (grids and "
            "exports made from it get empty margins)",
            line=h.line(kmin if (x0, y0) != (dx0, dy0) else kmax),
        )


@rule(C.BOX_EXCLUDES_DATA, C.BOX_LARGER_THAN_DATA, C.BOX_MISSING)
def boxes(ctx: Context) -> None:
    """MinPos/MaxPos and LineMinPos/LineMaxPos against the data's real extents."""
    for h in ctx.headers():
        _check_box(ctx, h, "points", h.scan.points, h.min_pos, h.max_pos)
        _check_box(ctx, h, "lines", h.scan.lines.reshape(-1, 2), h.line_min_pos, h.line_max_pos)


def lattice_step(points: np.ndarray[Any, Any]) -> int:
    """The grid step the points lie on (gcd of their offsets from the first point), 0 if none.

    Examples:
        >>> lattice_step(np.array([[0, 0], [40, 20], [100, -60]]))
        20
    """
    if len(points) < 2:
        return 0
    off = np.abs(points - points[0]).ravel()
    return int(np.gcd.reduce(off))


@rule(C.RESOLUTION_MISSING, C.RESOLUTION_IMPLAUSIBLE)
def resolution(ctx: Context) -> None:
    """Resolution: present (when there are points) and plausible."""
    for h in ctx.headers():
        n = h.scan.num_points
        if n == 0:
            continue
        kw = h.prefix + "Resolution:"
        step = lattice_step(h.scan.points)
        hint = f" (the points lie on a {step} mm lattice)" if 1 < step <= 1000 else ""
        if h.resolution is None:
            ctx.add(
                C.RESOLUTION_MISSING,
                f"{plural(n, 'point')} but no {kw} line; ARIA assumes 0 and writes "
                "'Resolution: 0'; "
                f"localisation grids and ROS exports need the grid size{hint}",
                line=None,
            )
        elif not (_PLAUSIBLE_RESOLUTION[0] <= h.resolution <= _PLAUSIBLE_RESOLUTION[1]):
            ctx.add(
                C.RESOLUTION_IMPLAUSIBLE,
                f"{kw} {h.resolution} is not a plausible grid size for {plural(n, 'point')} "
                f"(expected {_PLAUSIBLE_RESOLUTION[0]} to {_PLAUSIBLE_RESOLUTION[1]} mm, "
                f"usually 20){hint}",
                line=h.line("Resolution:"),
            )


@rule(C.NOT_MARKED_SORTED, C.SORTED_FLAG_WRONG)
def sorted_flags(ctx: Context) -> None:
    """PointsAreSorted:/LinesAreSorted: false (or absent with points), or true but wrong.

    Unmarked points and lines of one scan make one finding.
    """
    for h in ctx.headers():
        unmarked: list[tuple[str, str, int | None]] = []  # (state, what, line)
        for kind, arr, flag, key in (
            ("points", h.scan.points, h.points_sorted, "PointsAreSorted:"),
            ("lines", h.scan.lines, h.lines_sorted, "LinesAreSorted:"),
        ):
            if len(arr) < 2:
                continue
            kw = h.prefix + key
            if flag:
                if not is_sorted(arr):
                    ctx.add(
                        C.SORTED_FLAG_WRONG,
                        f"{kw} true but the {len(arr)} {kind} are not in sorted order (x, then "
                        "y); ARIA copies the flag without checking, code that trusts it "
                        "(binary searches, map-change diffs) goes wrong",
                        line=h.line(key),
                    )
                continue
            # Hand-drawn maps (lines only) are never sorted and ARIA writes them with
            # "LinesAreSorted: false": normal. Lines count only in scanned maps (with points).
            if kind == "lines" and (flag is None or h.scan.num_points == 0):
                continue
            state = f"{kw} false" if flag is False else f"no {kw} line"
            order = "in fact sorted" if is_sorted(arr) else "in file order"
            unmarked.append((state, f"the {len(arr)} {kind} are {order}", h.line(key)))
        if unmarked:
            ordered = all("in file order" in u[1] for u in unmarked)
            advice = (
                "ARIA keeps that order and never sorts on load (mapkit can sort them)"
                if ordered
                else "setting the flag is free"
                if all("in fact sorted" in u[1] for u in unmarked)
                else "ARIA never sorts on load (mapkit can sort them)"
            )
            ctx.add(
                C.NOT_MARKED_SORTED,
                f"{', '.join(u[0] for u in unmarked)}: {' and '.join(u[1] for u in unmarked)}; "
                + advice,
                line=next((u[2] for u in unmarked if u[2] is not None), None),
            )


# -- the intro line against the content ----------------------------------------------------------


def _features(ctx: Context) -> dict[str, list[str]]:
    """What the map uses, by the category that introduced it."""
    m = ctx.map
    out: dict[str, list[str]] = {
        "2D-Map-Ex": [],
        "2D-Map-Ex2": [],
        "2D-Map-Ex3": [],
        "2D-Map-Ex4": [],
    }
    if len(m.scans) > 1 or not m.scans[0].is_default:
        out["2D-Map-Ex"].append(f"scan sources ({', '.join(s.name for s in m.scans)})")
    if m.info.get("CairnInfo"):
        out["2D-Map-Ex2"].append("CairnInfo:")
    if m.info.get("CustomInfo"):
        out["2D-Map-Ex2"].append("CustomInfo:")
    mapinfo = m.info.get("MapInfo", ())
    if any(line and line[0] == "ArgDesc" for line in mapinfo):
        out["2D-Map-Ex2"].append("MapInfo: ArgDesc")
    if any(line and line[0] == "GroupType" for line in mapinfo):
        out["2D-Map-Ex3"].append("MapInfo: GroupType")
    if any(line and line[0] == "CairnGroupType" for line in mapinfo):
        out["2D-Map-Ex4"].append("MapInfo: CairnGroupType")
    if m.info.get("MacroInfo"):
        out["2D-Map-Ex4"].append("MacroInfo:")
    if any(line and line[0] == "MacroTemplate" for line in m.info.get("RouteInfo", ())):
        out["2D-Map-Ex4"].append("RouteInfo: MacroTemplate")
    if any(
        line and line[0] == "Feature" and any(unquote(t) == "Name=templates" for t in line[1:])
        for line in m.info.get("MetaInfo", ())
    ):
        out["2D-Map-Ex4"].append("MetaInfo: Feature Name=templates")
    if m.child_objects:
        out["2D-Map-Ex4"].append("ChildCairn:")
    return out


@rule(C.CATEGORY_OLDER_THAN_CONTENT, C.TEMPLATES_NEED_EX4, C.CATEGORY_NEWER_THAN_ARIA_291)
def category(ctx: Context) -> None:
    """The intro line: too old for the content, or too new for ARIA 2.9.1."""
    cat = ctx.category
    level = CATEGORIES.index(cat)
    line = ctx.map.provenance.intro_line if (ctx.file_view and ctx.map.provenance) else None
    feats = _features(ctx)
    if feats["2D-Map-Ex4"] and level < CATEGORIES.index("2D-Map-Ex4"):
        ctx.add(
            C.TEMPLATES_NEED_EX4,
            f"{cat} uses template content ({', '.join(feats['2D-Map-Ex4'])}), a 2D-Map-Ex4 "
            "feature: ARIA 2.9.4 upgrades the intro on load, ARIA 2.9.1 and older load the map "
            "without understanding the templates",
            line=line,
        )
    older = [
        (c, f)
        for c in ("2D-Map-Ex", "2D-Map-Ex2", "2D-Map-Ex3")
        for f in feats[c]
        if CATEGORIES.index(c) > level
    ]
    if older:
        need = max((c for c, _ in older), key=CATEGORIES.index)
        ctx.add(
            C.CATEGORY_OLDER_THAN_CONTENT,
            f"{cat} uses {', '.join(f for _, f in older)} ({need} content): every ARIA reads "
            f"it, but ARIA 2.9.1 rewrites the intro as {need} when it saves the map "
            "(ARIA 2.9.4 keeps it)",
            line=line,
        )
    if level >= CATEGORIES.index("2D-Map-Ex4"):
        ctx.add(
            C.CATEGORY_NEWER_THAN_ARIA_291,
            f"{cat}: ARIA 2.9.1 and older refuse the file ('supports up to 2D-Map-Ex3'); "
            "robots with ARIA 2.9.4 or later, and Omron ARAM, read it",
            line=line,
        )


# -- unknown keywords that look like known ones -------------------------------------------------

_SCAN_KEYWORDS = (
    "MinPos:",
    "MaxPos:",
    "NumPoints:",
    "PointsAreSorted:",
    "Resolution:",
    "LineMinPos:",
    "LineMaxPos:",
    "NumLines:",
    "LinesAreSorted:",
    "Display:",
)
_OTHER_KEYWORDS = (
    "Sources:",
    "OriginLatLongAlt:",
    "Cairn:",
    "_Cairn:",
    "ChildCairn:",
    "DATA",
    "LINES",
)


def known_keywords(ctx: Context) -> list[str]:
    """Every header keyword this map's reader knows."""
    out = list(_OTHER_KEYWORDS)
    for k in INFO_KEYWORDS:
        out += [k + ":", "_" + k + ":"]
    for s in ctx.map.scans:
        prefix = "" if s.is_default else s.name
        out += [prefix + k for k in _SCAN_KEYWORDS]
        if prefix:
            out += [prefix + "_DATA", prefix + "_LINES"]
    return out


@rule(C.MISSPELT_KEYWORD)
def misspelt(ctx: Context) -> None:
    """Unknown header lines whose keyword is a near miss of a real one (``OriginLatLonAlt:``)."""
    if not ctx.map.remainder:
        return
    known = known_keywords(ctx)
    lower = {k.lower(): k for k in known}
    prov = ctx.map.provenance
    rem_lines = prov.remainder_lines if prov is not None else ()
    for i, text in enumerate(ctx.map.remainder):
        kw = text.split(" ", 1)[0]
        if not kw or kw.lower() in lower:
            continue
        close = difflib.get_close_matches(kw.lower(), list(lower), n=1, cutoff=0.85)
        if not close:
            continue
        right = lower[close[0]]
        line = rem_lines[i] if i < len(rem_lines) else None
        ctx.add(
            C.MISSPELT_KEYWORD,
            f"{kw} is not an ARIA keyword (did you mean {right}?): ARIA keeps the line as "
            "unknown text and ignores its value",
            line=line,
        )
        ctx.cache.setdefault("misspelt_lines", set()).add(line)
