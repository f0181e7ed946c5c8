"""A simulated log and its truth: the true pose of every scan, written beside the log and read
back."""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from mapkit._atomic import atomic_write
from mapkit._text import plural
from mapkit._typing import PathLike
from mapkit.errors import MapkitError
from mapkit.model.scan import (
    LaserLog,
)
from mapkit.simulate.rays import FloatArray

__all__ = ["SimulatedLog", "read_truth", "truth_path_for"]


# -- the simulation ------------------------------------------------------------------------------


@dataclass(frozen=True)
class SimulatedLog:
    """A simulated log and what really happened.

    Attributes:
        log: The log (records in file order; header version as asked).
        truth: ``(N, 3)`` true robot pose of each scan (mm, mm, degrees), in scan order.
        truth_ids: ``(N,)`` the scans' ``scanId``.
        truth_times: ``(N,)`` the scans' times (s).
        distance: Distance driven (mm).
        odometry_error: Final odometry position error (mm) and heading error (degrees).
        skipped: Goals or waypoints the planner found no path to (left out of the route).
    """

    log: LaserLog
    truth: FloatArray
    truth_ids: np.ndarray[Any, Any]
    truth_times: FloatArray
    distance: float = 0.0
    odometry_error: tuple[float, float] = (0.0, 0.0)
    skipped: tuple[str, ...] = ()
    params: dict[str, Any] = field(default_factory=dict)

    def truth_text(self, log_name: str = "the log") -> str:
        """The truth sidecar's text: a comment, then ``scanId time x y th`` per scan."""
        lines = [
            f"# true robot poses of {log_name} (mapkit simulate): scanId time x y th (mm, degrees)"
        ]
        lines += [
            f"{int(i)} {t:.3f} {p[0]:.1f} {p[1]:.1f} {p[2]:.3f}"
            for i, t, p in zip(self.truth_ids, self.truth_times, self.truth, strict=True)
        ]
        return "\n".join(lines) + "\n"

    def save(
        self, path: PathLike, *, version: int | None = None, truth: bool | PathLike = True
    ) -> str:
        """Write the log (atomically) and, unless ``truth`` is false, the truth sidecar.

        Args:
            path: The ``.2d`` file.
            version: Logger version (default: the log's header version).
            truth: ``True`` for ``NAME.truth.tsv`` beside the log, a path, or ``False``.

        Returns:
            A one-line summary.

        Raises:
            OSError: When a file cannot be written.
        """
        from mapkit.formats.laser2d import write_log

        write_log(self.log, path, version=version)
        msg = (
            f"wrote {os.fspath(path)}: {plural(len(self.truth), 'scan')}, "
            f"{plural(len(self.log.events), 'event')}, "
            f"{self.distance / 1000:.1f} m driven, odometry off by {self.odometry_error[0]:.0f} mm "
            f"/ {self.odometry_error[1]:.1f} deg at the end"
        )
        if truth:
            tpath = truth_path_for(path) if truth is True else truth
            atomic_write(tpath, self.truth_text(os.path.basename(os.fspath(path))).encode())
            msg += f"; true poses in {os.fspath(tpath)}"
        return msg


def truth_path_for(log_path: PathLike) -> str:
    """The truth sidecar of a log: ``office.2d`` → ``office.truth.tsv``."""
    p = os.fspath(log_path)
    base = p[:-3] if p.lower().endswith(".2d") else p
    return base + ".truth.tsv"


def read_truth(path: PathLike) -> tuple[np.ndarray[Any, Any], FloatArray]:
    """Read a truth sidecar: ``(scan ids, (N, 3) poses)``.

    Raises:
        MapkitError: When a line is not ``id time x y th``.
        OSError: When the file cannot be read.
    """
    ids, poses = [], []
    with open(path, encoding="utf-8") as fh:
        for lineno, line in enumerate(fh, 1):
            if not line.strip() or line.startswith("#"):
                continue
            parts = line.split()
            try:
                if len(parts) != 5:
                    raise ValueError
                ids.append(int(parts[0]))
                poses.append([float(v) for v in parts[2:5]])
            except ValueError:
                raise MapkitError(
                    f"{os.fspath(path)}:{lineno}: expected 'scanId time x y th'"
                ) from None
    return np.array(ids, dtype=np.int64), np.array(poses, dtype=np.float64).reshape(-1, 3)
