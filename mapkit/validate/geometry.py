"""3xx: the sensed data itself (points and line segments)."""

from __future__ import annotations

from typing import Any

import numpy as np

from mapkit.diagnostics import IssueCode as C
from mapkit.model import Scan
from mapkit.validate._context import Context, rule

_INT32 = 2**31 - 1


def _rows(
    ctx: Context,
    code: C,
    scan: Scan,
    rows: np.ndarray[Any, Any],
    bad: np.ndarray[Any, Any],
    what: str,
    why: str,
    *,
    at_first: bool = True,
) -> None:
    """One finding for the rows of a scan selected by the mask ``bad`` (none when it is empty)."""
    n = int(np.count_nonzero(bad))
    if not n:
        return
    label = f"source {scan.name!r}: " if scan.name else ""
    first = rows[int(np.argmax(bad))]
    where = f" (first at ({first[0]}, {first[1]}))" if at_first else ""
    ctx.add(
        code,
        f"{label}{n} of {len(rows)} {what}{where}: {why}",
        xy=(first[0], first[1]) if at_first else None,
    )


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
                bad = np.any((arr > _INT32) | (arr < -_INT32 - 1), axis=1)
                _rows(
                    ctx,
                    C.COORDINATE_OVERFLOW,
                    s,
                    arr,
                    bad,
                    f"{kind} rows have coordinates beyond +-2147483647 mm",
                    "ARIA reads rows with 32-bit atoi and gets other numbers",
                    at_first=False,
                )


@rule(C.ZERO_LENGTH_LINES)
def zero_length_lines(ctx: Context) -> None:
    """LINES rows whose ends coincide (one finding per source)."""
    for s in ctx.map.scans:
        ln = s.lines
        if len(ln):
            zero = (ln[:, 0] == ln[:, 2]) & (ln[:, 1] == ln[:, 3])
            _rows(
                ctx,
                C.ZERO_LENGTH_LINES,
                s,
                ln,
                zero,
                "line segments have no length",
                "they draw nothing and can be removed",
            )


@rule(C.POINTS_OFF_GRID)
def points_on_grid(ctx: Context) -> None:
    """Points of a scan with a Resolution: should share one lattice (the most common offset)."""
    for s in ctx.map.scans:
        r = s.resolution
        p = s.points
        if not 1 < r <= 1000 or len(p) < 2:  # an implausible Resolution: is MK207
            continue
        key = (p[:, 0] % r) * r + (p[:, 1] % r)
        off = key != np.argmax(np.bincount(key, minlength=r * r))
        _rows(
            ctx,
            C.POINTS_OFF_GRID,
            s,
            p,
            off,
            f"points are off the {r} mm lattice of the others",
            "the data was edited or merged at another resolution",
        )
