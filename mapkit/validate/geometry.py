"""3xx: the sensed data itself (points and line segments)."""

from __future__ import annotations

import numpy as np

from mapkit.diagnostics import IssueCode as C
from mapkit.validate._context import Context, rule

_INT32 = 2**31 - 1


@rule(C.EMPTY_MAP, C.COORDINATE_OVERFLOW)
def data_present(ctx: Context) -> None:
    """A map with no data at all; coordinates ARIA's 32-bit row reader cannot hold."""
    if all(s.num_points == 0 and s.num_lines == 0 for s in ctx.map.scans):
        ctx.add(
            C.EMPTY_MAP,
            "the map has no points and no lines: there is nothing to localise "
            "against or plan around",
        )
        return
    for s in ctx.map.scans:
        for kind, arr in (("points", s.points), ("lines", s.lines)):
            if len(arr) and (arr.max() > _INT32 or arr.min() < -_INT32 - 1):
                bad = int(np.count_nonzero(np.any((arr > _INT32) | (arr < -_INT32 - 1), axis=1)))
                label = f"source {s.name!r}: " if s.name else ""
                ctx.add(
                    C.COORDINATE_OVERFLOW,
                    f"{label}{bad} {kind} rows have coordinates beyond +-2147483647 mm: ARIA "
                    "reads rows with 32-bit atoi and gets other numbers",
                )


@rule(C.ZERO_LENGTH_LINES)
def zero_length_lines(ctx: Context) -> None:
    """LINES rows whose ends coincide (one finding per source)."""
    for s in ctx.map.scans:
        ln = s.lines
        if not len(ln):
            continue
        zero = (ln[:, 0] == ln[:, 2]) & (ln[:, 1] == ln[:, 3])
        n = int(np.count_nonzero(zero))
        if n:
            first = ln[int(np.argmax(zero))]
            label = f"source {s.name!r}: " if s.name else ""
            ctx.add(
                C.ZERO_LENGTH_LINES,
                f"{label}{n} of {len(ln)} line segments have no length (first at "
                f"({first[0]}, {first[1]})); they draw nothing and can be removed",
                xy=(first[0], first[1]),
            )


@rule(C.POINTS_OFF_GRID)
def points_on_grid(ctx: Context) -> None:
    """Points of a scan with a Resolution: should share that lattice."""
    for s in ctx.map.scans:
        r = s.resolution
        p = s.points
        if not 1 < r <= 1000 or len(p) < 2:  # an implausible Resolution: is MK207
            continue
        key = (p[:, 0] % r) * r + (p[:, 1] % r)
        off = key != np.argmax(np.bincount(key, minlength=r * r))
        n = int(np.count_nonzero(off))
        if n:
            first = p[int(np.argmax(off))]
            label = f"source {s.name!r}: " if s.name else ""
            ctx.add(
                C.POINTS_OFF_GRID,
                f"{label}{n} of {len(p)} points are off the {r} mm lattice of the others "
                f"(first at ({first[0]}, {first[1]})): the data was edited or merged at "
                "another resolution",
                xy=(first[0], first[1]),
            )
