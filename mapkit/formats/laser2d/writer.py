"""The ``.2d`` writer: :class:`LogWriter` writes a log record by record in the chosen logger
version; :func:`dumps_log` and :func:`write_log`."""

from __future__ import annotations

import io
import math
from collections.abc import Iterable
from typing import IO, Any

import numpy as np

from mapkit._atomic import atomic_open
from mapkit._typing import PathLike
from mapkit.formats.laser2d.common import _CREATED, _END_MARK, VERSIONS
from mapkit.model.scan import (
    LaserConfig,
    LaserLog,
    LaserScan,
    LogEvent,
    LogHeader,
    LogRecord,
    Pose2D,
)

__all__ = ["LogWriter", "dumps_log", "write_log"]


# -- writer -------------------------------------------------------------------------------------


def _f0(v: float) -> str:
    return f"{v:.0f}"


def _f2(v: float) -> str:
    return f"{v:.2f}"


_INT64_SAFE = 2.0**62  # |values| below this convert to int64 exactly


def _rounded(a: np.ndarray[Any, Any]) -> list[Any]:
    """Values rounded half to even (as ``%.0f``), as ints; as ``%.0f`` text beyond 64 bits."""
    flat = np.asarray(a, dtype=np.float64).reshape(-1)
    if len(flat) and not np.abs(flat).max() < _INT64_SAFE:  # huge (a 50-digit number reads 1e50)
        return [f"{v:.0f}" for v in flat.tolist()]
    out: list[Any] = np.rint(flat).astype(np.int64).tolist()
    return out


def _ints(a: np.ndarray[Any, Any]) -> str:
    """Integers (rounded half to even, as ``%.0f``) joined by single spaces."""
    return " ".join(map(str, _rounded(a)))


_PAIR_FORMATS: dict[int, str] = {}


def _pairs(xy: np.ndarray[Any, Any]) -> str:
    """``scanK:`` pairs as ARIA writes them: `` x y `` for each pair (two spaces between)."""
    n = len(xy)
    fmt = _PAIR_FORMATS.get(n)
    if fmt is None:
        fmt = _PAIR_FORMATS[n] = " %s %s " * n
    return fmt % tuple(_rounded(xy))


def _time_text(t: float, version: int) -> str:
    if abs(t) < 1e15:
        total = round(float(t) * 1000)
        sec, ms = divmod(abs(total), 1000)
        sign = "-" if total < 0 else ""
    else:  # t * 1000 could overflow to inf; a double this large has no milliseconds to speak of
        whole, frac = divmod(abs(t), 1.0)
        sec, ms = int(whole) + (frac >= 0.9995), round(frac * 1000) % 1000
        sign = "-" if t < 0 else ""
    return f"{sign}{sec}.{ms:03d}" if version >= 4 else f"{sign}{sec}.{ms}"


def _pose_text(p: Pose2D) -> str:
    return f"{_f0(p.x)} {_f0(p.y)} {_f2(p.th)}"


class LogWriter:
    """Writes a ``.2d`` log record by record in one logger version.

    Args:
        fh: A binary file (text is encoded as UTF-8 with ``surrogateescape``).
        header: The header to write (its version is ignored; ``version`` decides).
        version: Logger version 1 to 4 (default: the header's).

    Raises:
        ValueError: For an unknown version.

    Examples:
        >>> buf = io.BytesIO()
        >>> w = LogWriter(buf, LogHeader(lasers=(LaserConfig(count=2),)), version=3)
        >>> w.write(LaserScan(scan_id=1, robot=Pose2D(0, 0, 0), time=5.007, xy=[[10, 0], [0, 0]]))
        >>> w.close()
        >>> print(buf.getvalue().decode())  # doctest: +NORMALIZE_WHITESPACE
        LaserOdometryLog
        #Created by ARIA's ArLaserLogger
        version: 3
        sick1pose: 0 0 0.00
        sick1conf: -90 90 2
        locationTypes: robot robotGlobal
        scan1Id: 1
        time: 5.7
        robot: 0 0 0.00
        robotGlobal: 0 0 0.00
        scan1: 10 0  0 0
        # End of log
    """

    def __init__(self, fh: IO[bytes], header: LogHeader, *, version: int | None = None) -> None:
        v = header.version if version is None else version
        if v not in VERSIONS:
            raise ValueError(f"unknown .2d version {v}; mapkit writes versions 1 to 4")
        self.version = v
        self.header = header
        self._fh = fh
        self._lasers = {las.number: las for las in header.lasers}
        self._loc = tuple(header.location_types) or ("robot", "robotGlobal")
        if "robot" not in self._loc:
            self._loc = ("robot", *self._loc)
        self._last_time: tuple[Any, Any] | None = None
        self._count = 0
        self._put_lines(self._header_lines())

    def _put_lines(self, lines: Iterable[str]) -> None:
        self._fh.write("".join(s + "\n" for s in lines).encode("utf-8", "surrogateescape"))

    def _header_lines(self) -> list[str]:
        v = self.version
        out = ["LaserOdometryLog"]
        created = _CREATED[v]
        if created:
            out.append(created)
        for c in self.header.comments:
            if "#" + c != created:
                out.append("#" + c)
        out.append(f"version: {v}")
        if self.header.use_encoder_pose is not None:
            out.append(f"useEncoderPose: {int(self.header.use_encoder_pose)}")
        for las in self.header.lasers:
            k = las.number
            lx, ly, lth = las.pose
            if v == 4:
                conf = f"{_f2(las.start)} {_f2(las.end)} {las.count}"
                out.append(f"sick{k}pose: {_pose_text(las.pose)}")
                out.append(f"sick{k}conf: {conf}")
                out.append(f"sick{k}name: {las.name}")
                out.append(f"scan{k}pose: {_f0(lx)} {_f0(ly)} {_f0(las.z or 0.0)} {_f2(lth)}")
                out.append(f"scan{k}conf: {conf}")
                out.append(f"scan{k}name: {las.name}")
            elif v == 3:
                a, b = las.start + lth, las.end + lth
                out.append(f"sick{k}pose: {_pose_text(las.pose)}")
                out.append(f"sick{k}conf: {_f0(min(a, b))} {_f0(max(a, b))} {las.count}")
            elif v == 2:
                out.append(f"sick{k}pose: {_f0(lx)} {_f0(ly)} {_f2(lth)}")
                out.append(f"sick{k}conf: {_f0(las.start)} {_f0(las.end)} {las.count}")
            else:
                out.append(f"sick{k}pose: {_f0(lx)} {_f0(ly)} {_f2(lth)}")
                out.append(f"sick{k}conf: {_f0(las.start)} {_f0(las.end)} {las.count}")
        if v >= 3:
            out.append("locationTypes: " + " ".join(self._loc))
        out.extend(self.header.extra)
        return out

    def _pose_lines(self, rec: LaserScan | LogEvent, *, with_vel: bool = False) -> list[str]:
        robot = rec.robot or Pose2D(0.0, 0.0, 0.0)
        v = self.version
        if v == 1:
            return [f"robot: {robot.x:.3f} {robot.y:.3f} {robot.th:.4f}", "robot_id: 0"]
        if v == 2:
            out = []
            if rec.robot_raw is not None:
                out.append(f"#rawRobot: {_pose_text(rec.robot_raw)}")
            if with_vel and isinstance(rec, LaserScan) and rec.velocities is not None:
                vel = rec.velocities
                out.append(f"robot: {_pose_text(robot)} {_f0(vel[0])} {_f0(vel[1])}")
            else:
                out.append(f"robot: {_pose_text(robot)}")
            return out
        others = dict(rec.other_poses)
        out = []
        for name in self._loc:
            if name == "robot":
                out.append(f"robot: {_pose_text(robot)}")
            elif name == "robotGlobal":
                out.append(f"robotGlobal: {_pose_text(rec.robot_global or robot)}")
            elif name == "robotRaw":
                if rec.robot_raw is not None:
                    out.append(f"robotRaw: {_pose_text(rec.robot_raw)}")
            elif name in others:
                p = others[name]
                out.append(f"{name}: {_pose_text(p)}" if p is not None else f"{name}: ")
        return out

    def write(self, rec: LogRecord) -> None:
        """Write one scan or event.

        Raises:
            ValueError: When a value cannot be written (NaN, a scan with neither points nor
                ranges, an event that version 1 cannot hold).
        """
        self._put_lines(self._record_lines(rec))

    def write_many(self, records: Iterable[LogRecord]) -> None:
        """Write records in order."""
        chunk: list[str] = []
        for rec in records:
            chunk.extend(self._record_lines(rec))
            if len(chunk) > 2000:
                self._put_lines(chunk)
                chunk = []
        self._put_lines(chunk)

    def _record_lines(self, rec: LogRecord) -> list[str]:
        v = self.version
        if isinstance(rec, LogEvent):
            self._last_time = None
            if rec.kind == "info":
                return [rec.text]
            out = []
            if rec.time is not None and v >= 2:
                out.append(f"time: {_time_text(rec.time, v)}")
            if rec.robot is not None:
                out.extend(s for s in self._pose_lines(rec) if not s.startswith("robot_id"))
            out.append(rec.text)
            return out
        for val in (*rec.robot, *(rec.robot_global or ()), *(rec.velocities or ())[:2]):
            if not math.isfinite(val):
                raise ValueError(f"scan {rec.scan_id}: NaN or infinite pose or velocity")
        k = rec.laser
        las = self._lasers.get(k) or LaserConfig(number=k)
        out = []
        if v == 4:
            key = (rec.time, rec.velocities)
            if rec.time is not None and key != self._last_time:
                out.append(f"logTime: {_time_text(rec.time, 4)}")
                if rec.velocities is not None:
                    out.append(
                        "velocities: "
                        + " ".join(_f2(x if math.isfinite(x) else 0.0) for x in rec.velocities)
                    )
                self._last_time = key
            out.append(f"scanId: {rec.scan_id}")
        elif v in (2, 3):
            out.append(f"scan1Id: {rec.scan_id}")
            if rec.time is not None:
                out.append(f"time: {_time_text(rec.time, v)}")
            if v == 3 and rec.velocities is not None:
                out.append(
                    "velocities: "
                    + " ".join(_f2(x if math.isfinite(x) else 0.0) for x in rec.velocities)
                )
        else:
            out.append(f"#scan{rec.scan_id}")
        out.extend(self._pose_lines(rec, with_vel=True))
        out.extend(rec.extra)
        if rec.reflectors is not None and v >= 2:
            out.append(f"reflector{k}: " + _ints(rec.reflectors))
        ranges = rec.ranges
        if v == 1 and ranges is None and rec.xy is not None:
            ranges = np.hypot(rec.xy[:, 0], rec.xy[:, 1])
        if ranges is not None:
            if not np.all(np.isfinite(ranges)):
                raise ValueError(f"scan {rec.scan_id}: NaN or infinite range")
            r = ranges
            if v == 3 and las.start < las.end:
                r = r[::-1]
            out.append(f"sick{k}: " + _ints(r))
        if v >= 2:
            xy = rec.xy
            if xy is None:
                if rec.ranges is None:
                    raise ValueError(f"scan {rec.scan_id}: neither hit points nor ranges")
                xy = _xy_from_ranges(rec.ranges, las)
            if not np.all(np.isfinite(xy)):
                raise ValueError(f"scan {rec.scan_id}: NaN or infinite hit point")
            if v in (2, 3) and las.pose.th != 0.0:
                t = math.radians(las.pose.th)
                c, s = math.cos(t), math.sin(t)
                rot = np.stack([c * xy[:, 0] - s * xy[:, 1], s * xy[:, 0] + c * xy[:, 1]], axis=1)
                xy = np.where(np.any(xy != 0, axis=1)[:, None], rot, 0.0)
            out.append(f"scan{k}:" + _pairs(xy))
        elif ranges is None:
            raise ValueError(f"scan {rec.scan_id}: version 1 needs ranges or hit points")
        self._count += 1
        return out

    def close(self, *, end_mark: bool = True) -> None:
        """Finish the log (``# End of log`` unless ``end_mark`` is false); the file stays open."""
        if end_mark:
            self._put_lines([_END_MARK])


def _xy_from_ranges(ranges: np.ndarray[Any, Any], las: LaserConfig) -> np.ndarray[Any, Any]:
    a = np.radians(las.angles(len(ranges)))
    xy = np.stack([ranges * np.cos(a), ranges * np.sin(a)], axis=1)
    xy[ranges <= 0] = 0.0
    return xy


def dumps_log(log: LaserLog, *, version: int | None = None) -> str:
    """The log as ``.2d`` text in one logger version (default: the log's own).

    Args:
        log: The log.
        version: 1 to 4.

    Returns:
        The text.

    Raises:
        ValueError: For an unknown version or a value that cannot be written (NaN).
    """
    buf = io.BytesIO()
    w = LogWriter(buf, log.header, version=version)
    w.write_many(log.records)
    w.close(end_mark=log.complete)
    return buf.getvalue().decode("utf-8", "surrogateescape")


def write_log(
    log: LaserLog | tuple[LogHeader, Iterable[LogRecord]],
    path: PathLike,
    *,
    version: int | None = None,
    backup: bool = False,
) -> int:
    """Write a ``.2d`` log atomically; records may come from an iterator (streamed).

    Args:
        log: A :class:`~mapkit.model.LaserLog`, or ``(header, records)`` with any iterable of
            records (e.g. a :class:`LogReader`, to convert a huge log between versions).
        path: The output file.
        version: Logger version 1 to 4 (default: the header's).
        backup: Keep the previous file as ``path + ".bak"``.

    Returns:
        The number of scans written.

    Raises:
        ValueError: For an unknown version or a value that cannot be written (NaN).
        OSError: When the file cannot be written (the old file is then unchanged).
    """
    records: Iterable[LogRecord]
    if isinstance(log, LaserLog):
        header, records, end = log.header, log.records, log.complete
    else:
        header, records = log
        end = True
    with atomic_open(path, backup=backup) as fh:
        w = LogWriter(fh, header, version=version)
        w.write_many(records)
        w.close(end_mark=end)
    return w._count
