"""What ``mapkit build`` did, for people: the trajectory file and the report picture.

* :func:`write_poses` / :func:`read_poses`: the trajectory as a TSV file, one scan per line
  (``scanId x y th odo_x odo_y odo_th``, mm and degrees), written atomically.
* :func:`report_figures`: the figures of a build (residuals, loop closures, how far scans moved
  from odometry); :func:`write_report`: the same as a PNG picture (matplotlib): the map with the
  built and odometry trajectories and the loops closed, the residual of each scan's match, and
  how far each scan moved from its odometry pose.
"""

from __future__ import annotations

import io
import os
from typing import TYPE_CHECKING, Any

import numpy as np

from mapkit._atomic import atomic_write
from mapkit._typing import PathLike
from mapkit.errors import MapkitError

if TYPE_CHECKING:
    from mapkit.build import BuildResult

__all__ = ["read_poses", "report_figures", "write_poses", "write_report"]

FloatArray = np.ndarray[Any, np.dtype[np.float64]]
_HEADER = "scanId\tx\ty\tth\todo_x\todo_y\todo_th"


def poses_text(result: BuildResult) -> str:
    """The trajectory TSV's text: a header line, then one scan per line."""
    rows = [_HEADER]
    for sid, p, o in zip(result.scan_ids, result.poses, result.odometry, strict=True):
        rows.append(
            f"{int(sid)}\t{p[0]:.1f}\t{p[1]:.1f}\t{p[2]:.3f}\t{o[0]:.1f}\t{o[1]:.1f}\t{o[2]:.3f}"
        )
    return "\n".join(rows) + "\n"


def write_poses(result: BuildResult, path: PathLike) -> None:
    """Write the trajectory of a build to ``path`` (TSV, atomically).

    Raises:
        OSError: When the file cannot be written.
    """
    atomic_write(path, poses_text(result).encode("utf-8"))


def read_poses(path: PathLike) -> tuple[np.ndarray[Any, Any], FloatArray, FloatArray]:
    """Read a trajectory TSV: ``(scan ids, (N, 3) poses, (N, 3) odometry)``.

    Raises:
        MapkitError: When a line is not ``scanId x y th odo_x odo_y odo_th``, naming the line.
        OSError: When the file cannot be read.
    """
    ids, poses, odo = [], [], []
    with open(path, encoding="utf-8") as fh:
        for lineno, line in enumerate(fh, 1):
            if not line.strip() or line.startswith(("#", "scanId")):
                continue
            parts = line.split()
            try:
                if len(parts) != 7:
                    raise ValueError
                ids.append(int(parts[0]))
                vals = [float(v) for v in parts[1:]]
            except ValueError:
                raise MapkitError(
                    f"{os.fspath(path)}:{lineno}: expected 'scanId x y th odo_x odo_y odo_th'"
                ) from None
            poses.append(vals[:3])
            odo.append(vals[3:])
    return (
        np.array(ids, dtype=np.int64),
        np.array(poses, dtype=np.float64).reshape(-1, 3),
        np.array(odo, dtype=np.float64).reshape(-1, 3),
    )


def report_figures(result: BuildResult) -> dict[str, Any]:
    """Figures of a build: residuals per scan, loop closures, how far scans moved from odometry."""
    res = result.residuals
    good = res[np.isfinite(res)] if len(res) else res
    moved = result.moved

    def pct(a: FloatArray, q: float) -> float | None:
        return round(float(np.percentile(a, q)), 1) if len(a) else None

    return {
        "scans": len(result.poses),
        "matched": len(good),
        "residual_mm": {"median": pct(good, 50), "p90": pct(good, 90), "max": pct(good, 100)},
        "worst_scans": [
            int(result.scan_ids[k])
            for k in np.argsort(-np.nan_to_num(res, nan=-1))[:5]
            if np.isfinite(res[k])
        ]
        if len(res)
        else [],
        "loops_closed": len(result.closures),
        "moved_from_odometry_mm": {
            "median": pct(moved, 50),
            "p90": pct(moved, 90),
            "max": pct(moved, 100),
        },
    }


def render_report(result: BuildResult) -> bytes:
    """The report picture as PNG bytes (see the module's description)."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    from matplotlib.figure import Figure

    fig = Figure(figsize=(12, 8), dpi=100)
    grid = fig.add_gridspec(2, 2, width_ratios=(3, 2))
    ax = fig.add_subplot(grid[:, 0])
    pts = result.map.points
    if len(pts):
        ax.scatter(pts[:, 0] / 1000, pts[:, 1] / 1000, s=0.3, c="0.3", linewidths=0)
    ax.plot(
        result.odometry[:, 0] / 1000,
        result.odometry[:, 1] / 1000,
        color="tab:red",
        lw=0.8,
        alpha=0.7,
        label="odometry",
    )
    ax.plot(
        result.poses[:, 0] / 1000,
        result.poses[:, 1] / 1000,
        color="tab:blue",
        lw=0.9,
        label="built",
    )
    for n, (a, b) in enumerate(result.closures):
        pa, pb = result.poses[a], result.poses[b]
        ax.plot(
            [pa[0] / 1000, pb[0] / 1000],
            [pa[1] / 1000, pb[1] / 1000],
            color="tab:green",
            lw=1.2,
            label="loop closed" if n == 0 else None,
        )
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title(f"map, trajectory and {len(result.closures)} loop closures")
    ax.legend(loc="best", fontsize=8)
    idx = np.arange(len(result.poses))
    ax1 = fig.add_subplot(grid[0, 1])
    if len(result.residuals):
        ax1.plot(idx, result.residuals, ".", ms=2, color="tab:blue")
    for _a, b in result.closures:
        ax1.axvline(b, color="tab:green", lw=0.5, alpha=0.6)
    ax1.set_ylabel("match residual (mm)")
    ax1.set_title("residual of each scan's match (green: loop closed)")
    ax2 = fig.add_subplot(grid[1, 1], sharex=ax1)
    ax2.plot(idx, result.moved, color="tab:orange", lw=0.8)
    ax2.set_xlabel("scan")
    ax2.set_ylabel("moved from odometry (mm)")
    ax2.set_title("how far each scan moved from its odometry pose")
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    return buf.getvalue()


def write_report(result: BuildResult, path: PathLike) -> dict[str, Any]:
    """Write the report picture (PNG, atomically); returns :func:`report_figures`.

    Raises:
        OSError: When the file cannot be written.
    """
    atomic_write(path, render_report(result))
    return report_figures(result)
