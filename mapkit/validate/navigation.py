"""5xx: can a robot of the given radius reach every goal and dock?

The map is rasterised with :mod:`mapkit.raster` (walls of every scan, forbidden areas and
forbidden lines burnt in as walls). One Euclidean distance transform gives each cell's
*clearance* (distance from its centre to the nearest wall cell's centre); the robot's centre may
be in a cell whose clearance exceeds the robot radius, exactly the cells
:func:`mapkit.raster.inflate` leaves free. Connected regions (4-connected, so the robot cannot
slip between two diagonal wall cells) decide reachability from the first ``RobotHome`` (or,
without one, between the goals).

For a goal that is not reachable, the same regions at smaller clearances say whether a narrower
robot would get there and where the widest gap on the way is; for a reachable goal, regions at
clearances a little above the radius find the goals reached only through a tight passage, and a
breadth-first path at that clearance locates the passage.
"""

from __future__ import annotations

import itertools
import math
from collections import defaultdict
from typing import Any

import numpy as np
from numpy.typing import NDArray

from mapkit.diagnostics import IssueCode as C
from mapkit.model import MapObject
from mapkit.raster import grid_for_bounds, wall_mask
from mapkit.raster.grid import OccupancyGrid
from mapkit.validate._context import Context, rule

__all__ = ["NAV_MAX_CELLS", "TIGHT_MARGIN_MM", "Clearance", "clearance_grid"]

#: The largest grid the reachability check makes (cells); larger maps get coarser cells.
NAV_MAX_CELLS = 3_000_000
#: A passage is tight when its clearance is less than the robot radius plus this (mm on each side).
TIGHT_MARGIN_MM = 100.0
#: Cells per robot radius wanted (cell size = radius / this, at least the map's resolution).
CELLS_PER_RADIUS = 4.0
#: The check is skipped when the cells would have to be coarser than radius / this.
MIN_CELLS_PER_RADIUS = 2.0


class Clearance:
    """A map's clearance grid: distance (in cells) from each cell to the nearest wall cell.

    Attributes:
        grid: The grid's geometry (values unused).
        cell: Cell size in mm.
        dist: ``(height, width)`` float array of clearances in cells.
    """

    def __init__(self, grid: OccupancyGrid, walls: NDArray[np.bool_]) -> None:
        from scipy import ndimage

        self.grid = grid
        self.cell = grid.resolution_mm
        self.dist = np.asarray(ndimage.distance_transform_edt(~walls), dtype=np.float32)
        self._labels: dict[float, NDArray[np.int32]] = {}
        self._near: dict[tuple[float, float, float, float], dict[int, tuple[int, int]]] = {}

    def free(self, clearance_mm: float) -> NDArray[np.bool_]:
        """Cells where the robot's centre may be: clearance greater than ``clearance_mm``.

        Equal to ``~inflate(walls, clearance_mm, resolution)`` (:func:`mapkit.raster.inflate`).
        """
        return np.asarray(self.dist > clearance_mm / self.cell + 1e-9)

    def labels(self, clearance_mm: float) -> NDArray[np.int32]:
        """4-connected regions of :meth:`free` (0 = not free), cached per clearance."""
        key = round(clearance_mm, 6)
        if key not in self._labels:
            from scipy import ndimage

            lab, _ = ndimage.label(self.free(clearance_mm))
            self._labels[key] = np.asarray(lab, dtype=np.int32)
        return self._labels[key]

    def cell_of(self, x: float, y: float) -> tuple[int, int]:
        """``(row, col)`` of a world point in mm."""
        rc = self.grid.world_to_cell([x, y])
        return int(rc[0]), int(rc[1])

    def near_cells(
        self, x: float, y: float, clearance_mm: float, reach_mm: float
    ) -> dict[int, tuple[int, int]]:
        """Free cells (at ``clearance_mm``) within ``reach_mm`` of (x, y): the nearest one of each
        region, by region label, nearest region first."""
        key = (float(x), float(y), round(clearance_mm, 6), round(reach_mm, 6))
        if key not in self._near:
            self._near[key] = self._near_cells(x, y, clearance_mm, reach_mm)
        return self._near[key]

    def _near_cells(
        self, x: float, y: float, clearance_mm: float, reach_mm: float
    ) -> dict[int, tuple[int, int]]:
        labels = self.labels(clearance_mm)
        r0, c0 = self.cell_of(x, y)
        k = math.ceil(reach_mm / self.cell) + 1
        h, w = labels.shape
        rows = np.arange(max(r0 - k, 0), min(r0 + k + 1, h))
        cols = np.arange(max(c0 - k, 0), min(c0 + k + 1, w))
        if not len(rows) or not len(cols):
            return {}
        win = labels[np.ix_(rows, cols)]
        rr, cc = np.nonzero(win > 0)
        if not len(rr):
            return {}
        centres = self.grid.cell_to_world(np.stack([rows[rr], cols[cc]], axis=1))
        d = np.hypot(centres[:, 0] - x, centres[:, 1] - y)
        ok = d <= reach_mm + self.cell / 2
        out: dict[int, tuple[int, int]] = {}
        for j in np.flatnonzero(ok)[np.argsort(d[ok], kind="stable")]:
            lab = int(win[rr[j], cc[j]])
            if lab not in out:
                out[lab] = (int(rows[rr[j]]), int(cols[cc[j]]))
        return out

    def connected(
        self, a: tuple[float, float], b: tuple[float, float], clearance_mm: float, reach_mm: float
    ) -> tuple[tuple[int, int], tuple[int, int]] | None:
        """Free cells near world points ``a`` and ``b`` in one region at ``clearance_mm``."""
        na = self.near_cells(a[0], a[1], clearance_mm, reach_mm)
        nb = self.near_cells(b[0], b[1], clearance_mm, reach_mm)
        for lab, ca in na.items():
            if lab in nb:
                return ca, nb[lab]
        return None

    def passages(
        self, start: tuple[int, int], goals: list[tuple[int, int]], clearance_mm: float
    ) -> list[tuple[float, tuple[float, float]] | None]:
        """The narrowest passage on the way from ``start`` to each goal, at ``clearance_mm``.

        A breadth-first path through the cells free at ``clearance_mm`` is split into stretches
        inside and outside the regions free at one cell more. Stretches outside that join two
        different regions are passages (a stretch that leaves a region and comes back into it is
        the path cutting a corner); the passage with the least clearance is the answer, as
        ``(clearance in mm, (x, y) in mm)``. ``None`` where there is no path.
        """
        from scipy.sparse import coo_matrix
        from scipy.sparse.csgraph import breadth_first_order

        labels = self.labels(clearance_mm)
        upper = self.labels(clearance_mm + self.cell)
        lab = labels[start]
        if lab == 0:
            return [None] * len(goals)
        region = labels == lab
        index = np.full(region.shape, -1, dtype=np.int64)
        cells = np.flatnonzero(region.ravel())
        index.ravel()[cells] = np.arange(len(cells))
        pairs = []
        for a, b in ((index[:, :-1], index[:, 1:]), (index[:-1, :], index[1:, :])):
            both = (a >= 0) & (b >= 0)
            pairs.append((a[both], b[both]))
        i = np.concatenate([p[0] for p in pairs])
        j = np.concatenate([p[1] for p in pairs])
        n = len(cells)
        graph = coo_matrix((np.ones(len(i), dtype=np.int8), (i, j)), shape=(n, n)).tocsr()
        root = int(index[start])
        _, pred = breadth_first_order(graph, root, directed=False, return_predecessors=True)
        flat_dist = self.dist.ravel()
        flat_upper = upper.ravel()
        out: list[tuple[float, tuple[float, float]] | None] = []
        for g in goals:
            node = int(index[g]) if region[g] else -1
            if node < 0 or (node != root and pred[node] < 0):
                out.append(None)
                continue
            path = [node]
            while path[-1] != root:
                path.append(int(pred[path[-1]]))
            flat = cells[np.array(path[::-1])]
            up = flat_upper[flat]
            best = _narrowest_crossing(up, flat_dist[flat])
            k = int(flat[best])
            rc = np.unravel_index(k, self.dist.shape)
            xy = self.grid.cell_to_world([int(rc[0]), int(rc[1])])
            out.append((float(flat_dist[k]) * self.cell, (float(xy[0]), float(xy[1]))))
        return out


def _narrowest_crossing(up: NDArray[Any], clear: NDArray[Any]) -> int:
    """Index of the least-clear cell in the stretches of a path that join different regions.

    ``up`` holds each path cell's region label at the higher clearance (0 outside every region).
    The path's ends count as regions of their own when they lie outside one.

    Examples:
        >>> _narrowest_crossing(np.array([1, 0, 1, 1, 0, 0, 2]), np.array([9, 2, 9, 9, 4, 3, 9]))
        5
    """
    lab = up.astype(np.int64).copy()
    if lab[0] == 0:
        lab[0] = -1
    if lab[-1] == 0:
        lab[-1] = -2
    inside = np.flatnonzero(lab != 0)
    best, best_c = -1, np.inf
    for a, b in itertools.pairwise(inside):
        if b - a > 1 and lab[a] != lab[b]:
            k = a + 1 + int(np.argmin(clear[a + 1 : b]))
            if clear[k] < best_c:
                best, best_c = int(k), clear[k]
    if best < 0:  # no crossing found (snapping at the ends): the least-clear cell of the path
        best = int(np.argmin(clear))
    return best


def reach_mm(radius: float, cell: float) -> float:
    """How far (mm) from a goal a free cell may be for the goal to count as reached."""
    return radius + 2 * cell


def nav_cell_mm(ctx: Context, span_mm: float) -> float | None:
    """The cell size (mm) for the reachability grid, or ``None`` when the map is too large."""
    r = ctx.robot_radius
    cell = max(float(ctx.resolution), r / CELLS_PER_RADIUS if r > 0 else 0.0)
    cells = (span_mm / cell) ** 2
    if cells > NAV_MAX_CELLS:
        cell = math.ceil(span_mm / math.sqrt(NAV_MAX_CELLS))
    if r > 0 and cell > r / MIN_CELLS_PER_RADIUS:
        return None
    return float(math.ceil(cell))


def clearance_grid(
    ctx: Context, bounds: tuple[tuple[float, float], tuple[float, float]], cell_mm: float
) -> Clearance:
    """Rasterise the map's walls, forbidden areas and forbidden lines and measure clearances."""
    grid = grid_for_bounds(bounds, cell_mm / 1000.0, margin_m=0.0)
    # Objects with NaN or infinite numbers (MK405) cannot be drawn: leave them out.
    objects = tuple(
        o
        for o in ctx.objects
        if all(math.isfinite(v) for v in (o.x, o.y, o.theta, *(o.from_to or ())))
    )
    m = ctx.map.replace(objects=objects)
    walls = wall_mask(m, grid, forbidden_as_walls=True)
    return Clearance(grid, walls)


def _name(o: MapObject) -> str:
    return f'{o.type} "{o.name}"' if o.name else f"the unnamed {o.type}"


@rule(C.UNREACHABLE, C.NARROW_PASSAGE, C.NAVIGATION_SKIPPED)
def reachability(ctx: Context) -> None:
    """Every goal and dock reachable from RobotHome (or from each other); how tight the way is."""
    if not ctx.navigation:
        return
    # Goals inside a forbidden area are reported as such (MK411), not again as unreachable.
    forbidden = ctx.cache.get("forbidden_targets", set())
    finite = [(i, o) for i, o in ctx.destinations() if math.isfinite(o.x) and math.isfinite(o.y)]
    targets = [(i, o) for i, o in finite if i not in forbidden]
    box = ctx.data_box()
    r = ctx.robot_radius
    stats: dict[str, Any] = {
        "targets": len(finite),
        "robot_radius": r,
        "in_forbidden_areas": len(finite) - len(targets),
    }
    ctx.stats["navigation"] = stats
    if not targets or box is None:
        return
    homes = [o for _, o in ctx.homes() if math.isfinite(o.x) and math.isfinite(o.y)]
    margin = max(r + 1000.0, 2 * r)  # as far out as MK408 lets objects be, and room to pass
    (x0, y0), (x1, y1) = box
    inside = [
        (i, o)
        for i, o in targets
        if x0 - margin <= o.x <= x1 + margin and y0 - margin <= o.y <= y1 + margin
    ]
    homes = [
        h for h in homes if x0 - margin <= h.x <= x1 + margin and y0 - margin <= h.y <= y1 + margin
    ]
    bounds = ((x0 - margin, y0 - margin), (x1 + margin, y1 + margin))
    span = max(x1 - x0, y1 - y0) + 2 * margin
    cell = nav_cell_mm(ctx, span)
    if cell is None:
        ctx.add(
            C.NAVIGATION_SKIPPED,
            f"reachability not checked: the map spans {span / 1000:.0f} m, too large for a grid "
            f"of at most {NAV_MAX_CELLS:,} cells fine enough for a {r:.0f} mm robot radius "
            f"(cells of at most {r / MIN_CELLS_PER_RADIUS:.0f} mm)",
        )
        stats["skipped"] = "too large"
        return
    cl = clearance_grid(ctx, bounds, cell)
    stats.update(cell_mm=cell, grid=[cl.grid.width, cl.grid.height])
    # How far from a goal its free cell may be: the radius and two cells of discretisation (a
    # goal near or on a wall still counts as reached from the free side).
    reach = reach_mm(r, cell)

    # The start: the first usable RobotHome, else the goals' biggest connected group.
    start_cell: tuple[int, int] | None = None
    start_name = ""
    for h in homes:
        near = cl.near_cells(h.x, h.y, r, reach)
        if near:
            start_cell, start_name = next(iter(near.values())), _name(h)
            stats["start"] = start_name
            break
    near_goal = {i: cl.near_cells(o.x, o.y, r, reach) for i, o in inside}
    if start_cell is None:
        groups: dict[int, list[int]] = defaultdict(list)
        for i, near in near_goal.items():
            for lab in near:
                groups[lab].append(i)
        if groups:
            best = max(groups, key=lambda k: (len(groups[k]), -min(groups[k])))
            first = min(groups[best])
            start_cell = near_goal[first][best]
            start_name = "the other goals"
            stats["start"] = f"{_name(dict(inside)[first])} (no usable RobotHome)"
        else:
            stats["start"] = None
    start_label = None if start_cell is None else int(cl.labels(r)[start_cell])
    reachable, unreachable = [], []
    free_cells: dict[int, tuple[int, int] | None] = {}
    for i, o in inside:
        near = near_goal[i]
        free_cells[i] = near.get(start_label) if start_label is not None else None
        if free_cells[i] is not None:
            reachable.append((i, o))
        else:
            unreachable.append((i, o))
            free_cells[i] = next(iter(near.values()), None)
    stats["reachable"] = len(reachable)
    stats["not_checked"] = len(targets) - len(inside)  # too far outside the map
    _report_unreachable(ctx, cl, start_cell, start_name, unreachable, free_cells)
    if start_cell is not None:
        _report_tight(ctx, cl, start_cell, stats["start"], reachable)


def _levels(low: float, high: float, step: float) -> list[float]:
    """Clearances from ``high`` down to ``low`` in steps, both ends included, descending.

    Examples:
        >>> _levels(250, 350, 63)
        [350, 287, 250]
    """
    out = []
    v = high
    while v > low + 1e-9:
        out.append(v)
        v -= step
    return [*out, low]


def _cell_xy(cl: Clearance, cell: tuple[int, int]) -> tuple[float, float]:
    xy = cl.grid.cell_to_world([cell[0], cell[1]])
    return float(xy[0]), float(xy[1])


def _report_unreachable(
    ctx: Context,
    cl: Clearance,
    start: tuple[int, int] | None,
    start_name: str,
    unreachable: list[tuple[int, MapObject]],
    free_cells: dict[int, tuple[int, int] | None],
) -> None:
    r = ctx.robot_radius
    reach = reach_mm(r, cl.cell)
    # For a narrower robot: the largest clearance below r at which the goal joins the start.
    levels = [v for v in _levels(0.0, r, cl.cell) if v < r]
    frm = (
        f"from {start_name}"
        if start_name != "the other goals"
        else "from the other goals (they share one connected area; this one is cut off)"
    )
    for i, o in unreachable:
        who = f"{_name(o)} at ({o.x:.0f}, {o.y:.0f})"
        if start is None:
            why = f": no goal, dock or home has room for a robot of radius {r:.0f} mm"
        elif free_cells.get(i) is None:
            why = (
                f" cannot be reached {frm}: there is no room for a robot of radius {r:.0f} mm "
                f"anywhere within {r:.0f} mm of it"
            )
        else:
            start_xy = _cell_xy(cl, start)
            gap = None
            # Connected at all (at the smallest clearance)? Only then look for the widest way.
            if levels and cl.connected(start_xy, (o.x, o.y), levels[-1], reach) is not None:
                for level in levels:
                    pair = cl.connected(start_xy, (o.x, o.y), level, reach)
                    if pair is not None:
                        gap = cl.passages(pair[0], [pair[1]], level)[0]
                        break
            if gap is None:
                why = (
                    f" cannot be reached {frm}: walls, forbidden areas or forbidden lines close "
                    "it off completely"
                )
            else:
                c_mm, (gx, gy) = gap
                why = (
                    f" cannot be reached {frm} by a robot of radius {r:.0f} mm: the widest way "
                    f"passes a gap about {_width(c_mm)} mm wide at ({gx:.0f}, {gy:.0f})"
                )
        ctx.add(
            C.UNREACHABLE, who + why, line=ctx.object_line(i), object=o.name or None, xy=(o.x, o.y)
        )


def _report_tight(
    ctx: Context,
    cl: Clearance,
    start: tuple[int, int],
    start_name: str,
    reachable: list[tuple[int, MapObject]],
) -> None:
    r = ctx.robot_radius
    start_xy = _cell_xy(cl, start)
    levels = _levels(r, r + TIGHT_MARGIN_MM, cl.cell)  # descending, the last one is r
    # Each tight goal with its free cells (start side, goal side) at the largest clearance at
    # which it is still connected. At each clearance a goal may sit as far from its free cell as
    # that clearance (plus discretisation): a goal close to a wall is MK410's business.
    by_level: dict[float, list[tuple[int, MapObject, tuple[int, int], tuple[int, int]]]]
    by_level = defaultdict(list)
    for i, o in reachable:
        for level in levels:
            pair = cl.connected(start_xy, (o.x, o.y), level, reach_mm(level, cl.cell))
            if pair is not None:
                if level < levels[0]:
                    by_level[level].append((i, o, pair[0], pair[1]))
                break
    passages: dict[tuple[int, int], list[tuple[int, MapObject, float, tuple[float, float]]]]
    passages = defaultdict(list)
    for level, goals in by_level.items():
        found = cl.passages(goals[0][2], [g[3] for g in goals], level)
        for (i, o, _, _), f in zip(goals, found, strict=True):
            if f is not None:
                c_mm, (x, y) = f
                passages[(round(x / cl.cell), round(y / cl.cell))].append((i, o, c_mm, (x, y)))
    for group in passages.values():
        i, o, c_mm, (x, y) = group[0]
        names = ", ".join(_name(g[1]) for g in group[:5]) + (
            f" and {len(group) - 5} more" if len(group) > 5 else ""
        )
        ctx.add(
            C.NARROW_PASSAGE,
            f"the way from {start_name} to {names} passes a gap about {_width(c_mm)} mm wide "
            f"at ({x:.0f}, {y:.0f}) (measured on a {cl.cell:.0f} mm grid): the robot is "
            f"{2 * r:.0f} mm wide and needs about {2 * (r + TIGHT_MARGIN_MM):.0f} mm to pass "
            "with ease",
            line=ctx.object_line(i),
            object=o.name or None,
            xy=(x, y),
        )


def _width(clearance_mm: float) -> int:
    """A passage's width from its clearance, rounded to 10 mm (the grid is not finer than that)."""
    return round(2 * clearance_mm / 10.0) * 10
