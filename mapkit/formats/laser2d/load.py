"""Reading whole logs and summaries: :func:`iter_log`, :func:`read_log`, :func:`recover_log`,
:func:`log_summary`, :func:`loads_log`."""

from __future__ import annotations

import io
import math
import os
from typing import IO, Any

import numpy as np

from mapkit._typing import PathLike
from mapkit.diagnostics import Issue
from mapkit.formats.laser2d.reader import LogReader
from mapkit.model.scan import (
    LaserLog,
    LaserScan,
    Pose2D,
)

__all__ = ["iter_log", "loads_log", "log_summary", "read_log", "recover_log"]


def iter_log(
    source: PathLike | IO[bytes] | bytes, *, strict: bool = True, name: str | None = None
) -> LogReader:
    """Open a ``.2d`` log for streaming: the header is read now, records as you iterate.

    Args:
        source: A path, an open binary file, or the log's bytes.
        strict: Raise :class:`~mapkit.errors.LogFormatError` on the first bad record; with
            ``False`` bad records are skipped and listed in ``reader.issues``.
        name: File name for messages (defaults to the path).

    Returns:
        A :class:`LogReader`: ``reader.header``, then ``for record in reader``.

    Raises:
        LogFormatError: When the file is not a ``.2d`` log (both modes), or (strict) a header
            line cannot be read.
        OSError: When the file cannot be opened.

    Examples:
        >>> r = iter_log(b"LaserOdometryLog\\nversion: 4\\nsick1conf: -90 90 2\\n"
        ...              b"scanId: 0\\nrobot: 0 0 0\\nscan1: 1000 0  0 1000 \\n")
        >>> r.header.version, [s.xy.tolist() for s in r]
        (4, [[[1000.0, 0.0], [0.0, 1000.0]]])
    """
    if isinstance(source, (bytes, bytearray, memoryview)):
        data = bytes(source)
        return LogReader(
            io.BytesIO(data), source=name or "<bytes>", strict=strict, size=len(data), close=True
        )
    if hasattr(source, "readline"):
        return LogReader(
            source,  # type: ignore[arg-type]
            source=name or getattr(source, "name", "<stream>"),  # type: ignore[arg-type]
            strict=strict,
        )
    path = os.fspath(source)
    fh = open(path, "rb", buffering=1 << 20)  # noqa: SIM115 (the reader owns and closes it)
    try:
        size = os.fstat(fh.fileno()).st_size
    except OSError:
        size = None
    return LogReader(fh, source=name or path, strict=strict, size=size, close=True)


def _collect(reader: LogReader) -> LaserLog:
    with reader:
        records = list(reader)
    return LaserLog(
        header=reader.header, records=tuple(records), complete=reader.complete, source=reader.source
    )


def read_log(source: PathLike | IO[bytes] | bytes, *, name: str | None = None) -> LaserLog:
    """Read a whole ``.2d`` log strictly into memory.

    Args:
        source: A path, an open binary file, or the log's bytes.
        name: File name for messages.

    Returns:
        The log.

    Raises:
        LogFormatError: At the first line that is not valid (the message names file and line).
        OSError: When the file cannot be read.
    """
    return _collect(iter_log(source, strict=True, name=name))


def recover_log(
    source: PathLike | IO[bytes] | bytes, *, name: str | None = None
) -> tuple[LaserLog, list[Issue]]:
    """Read a ``.2d`` log tolerantly: bad records are skipped and reported.

    Args:
        source: A path, an open binary file, or the log's bytes.
        name: File name for the issues.

    Returns:
        ``(log, issues)``; the issues have 7xx codes (:class:`~mapkit.diagnostics.IssueCode`).

    Raises:
        LogFormatError: Only when the file is not a ``.2d`` log at all.
        OSError: When the file cannot be read.

    Examples:
        >>> log, issues = recover_log(b"LaserOdometryLog\\nversion: 4\\nsick1conf: -90 90 2\\n"
        ...     b"scanId: 0\\nrobot: 0 0 0\\nscan1: 1 2  3 nan \\n"
        ...     b"scanId: 1\\nrobot: 0 0 0\\nscan1: 1 2  3 4 \\n# End of log\\n")
        >>> [s.scan_id for s in log.scans], [str(i) for i in issues]
        ([1], ['<bytes>:6: error MK703: scan1: NaN or infinite value'])
    """
    reader = iter_log(source, strict=False, name=name)
    log = _collect(reader)
    return log, reader.issues


def log_summary(
    source: PathLike | IO[bytes] | bytes, *, strict: bool = True, name: str | None = None
) -> dict[str, Any]:
    """What a log holds, read in one streaming pass (bounded memory, any length).

    Args:
        source: A path, an open binary file, or the log's bytes.
        strict: Raise at the first bad record; ``False`` counts and lists the problems.
        name: File name for messages.

    Returns:
        JSON-ready figures: version, lasers, scans, readings, valid fraction, events by kind,
        time span, odometry path length, whether the log ended cleanly, and issues.

    Raises:
        LogFormatError: When the log cannot be read (strict mode: any bad record).
        OSError: When the file cannot be read.

    Examples:
        >>> s = log_summary(b"LaserOdometryLog\\nversion: 4\\nsick1conf: -90 90 2\\n"
        ...                 b"scanId: 0\\nrobot: 0 0 0\\nscan1: 1000 0  0 0 \\n"
        ...                 b"scanId: 1\\nrobot: 300 0 0\\nscan1: 700 0  0 0 \\n# End of log\\n")
        >>> s["scans"], s["path_length_m"], s["valid_fraction"], s["complete"]
        (2, 0.3, 0.5, True)
    """
    reader = iter_log(source, strict=strict, name=name)
    scans = readings = valid = 0
    events: dict[str, int] = {}
    goals: list[str] = []
    t_first = t_last = None
    length = 0.0
    last: Pose2D | None = None
    per_laser: dict[int, int] = {}
    with reader:
        for rec in reader:
            t = rec.time
            if t is not None:
                t_first = t if t_first is None else t_first
                t_last = t
            if isinstance(rec, LaserScan):
                scans += 1
                per_laser[rec.laser] = per_laser.get(rec.laser, 0) + 1
                readings += rec.num_readings
                valid += int(np.count_nonzero(rec.valid))
                if last is not None and rec.laser == 1:
                    length += math.hypot(rec.robot.x - last.x, rec.robot.y - last.y)
                if rec.laser == 1:
                    last = rec.robot
            else:
                events[rec.kind] = events.get(rec.kind, 0) + 1
                if rec.kind == "goal":
                    goals.append(rec.name)
    h = reader.header
    return {
        "file": reader.source,
        "version": h.version,
        "lasers": [
            {
                "number": las.number,
                "name": las.name,
                "pose": list(las.pose),
                "first_angle": las.start,
                "last_angle": las.end,
                "readings": las.count,
            }
            for las in h.lasers
        ],
        "location_types": list(h.location_types),
        "scans": scans,
        "scans_per_laser": {str(k): v for k, v in sorted(per_laser.items())},
        "readings": readings,
        "valid_fraction": round(valid / readings, 4) if readings else 0.0,
        "events": events,
        "goals": goals,
        "time_span_s": round(t_last - t_first, 3)
        if t_first is not None and t_last is not None
        else None,
        "path_length_m": round(length / 1000.0, 3),
        "complete": reader.complete,
        "issues": [i.to_dict() for i in reader.issues],
    }


def loads_log(text: str | bytes, *, name: str = "<string>") -> LaserLog:
    """Read a ``.2d`` log from text (strict); see :func:`read_log`."""
    data = text.encode("utf-8", "surrogateescape") if isinstance(text, str) else bytes(text)
    return read_log(data, name=name)
