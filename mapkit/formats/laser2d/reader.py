"""The streaming ``.2d`` reader: :class:`LogReader` reads the header at once, then one record at a
time, strictly or tolerantly."""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import IO, Any

import numpy as np

from mapkit.diagnostics import Issue, IssueCode
from mapkit.formats.laser2d.common import (
    _decode,
    _finite,
    _int,
    _numbers,
    _small,
    _time,
)
from mapkit.formats.laser2d.events import goal_fields
from mapkit.formats.laser2d.header import _HeaderReader, _is_laser_no
from mapkit.model.scan import (
    LaserConfig,
    LaserScan,
    LogEvent,
    LogRecord,
    Pose2D,
)

__all__ = ["LogReader"]


# -- reader -------------------------------------------------------------------------------------


@dataclass
class _Pending:
    """A record being read: everything since its first line."""

    start_line: int = 0
    scan_id: int | None = None
    poses: dict[str, Pose2D | None] = field(default_factory=dict)
    pose_order: list[str] = field(default_factory=list)
    ranges: dict[int, np.ndarray[Any, Any]] = field(default_factory=dict)
    reflectors: dict[int, np.ndarray[Any, Any]] = field(default_factory=dict)
    extra: list[str] = field(default_factory=list)
    bad: bool = False
    has_time: bool = False
    v2_velocities: tuple[float, float, float] | None = None

    def empty(self) -> bool:
        return self.scan_id is None and not self.poses and not self.ranges and not self.reflectors


class LogReader(_HeaderReader):
    """Streams a ``.2d`` log: ``header`` at once, then records one at a time.

    Use :func:`iter_log` to make one. Iterating yields :class:`~mapkit.model.LaserScan` and
    :class:`~mapkit.model.LogEvent` values in file order.

    Attributes:
        header: The log's header.
        source: File name used in messages.
        strict: Raise on the first bad record (else skip it and add an issue).
        issues: Problems met so far (tolerant mode; unknown tags are noted in both modes).
        complete: ``True`` once ``# End of log`` was read.
        bytes_read: Bytes consumed so far (for progress bars).
        size: Total size in bytes when known, else ``None``.
    """

    def __init__(
        self,
        fh: IO[bytes],
        *,
        source: str = "<stream>",
        strict: bool = True,
        size: int | None = None,
        close: bool = False,
    ) -> None:
        self.source = source
        self.strict = strict
        self.issues: list[Issue] = []
        self.complete = False
        self.bytes_read = 0
        self.size = size
        self._fh = fh
        self._close = close
        self._lineno = 0
        self._has_nl = True
        self._pushback: tuple[int, bytes, bool] | None = None
        self._time: float | None = None
        self._velocities: tuple[float, float, float] | None = None
        self._pending = _Pending()
        self._v1_id: int | None = None
        self._done = False
        self._warned_lasers: set[int] = set()
        try:
            self.header = self._read_header()
        except BaseException:
            self.close()
            raise
        self._lasers = {las.number: las for las in self.header.lasers}
        self._gen = self._records()

    # -- plumbing --

    def close(self) -> None:
        """Close the file when the reader opened it."""
        if self._close:
            self._fh.close()
            self._close = False

    def __enter__(self) -> LogReader:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __iter__(self) -> Iterator[LogRecord]:
        return self

    def __next__(self) -> LogRecord:
        try:
            return next(self._gen)
        except StopIteration:
            self.close()
            raise
        except BaseException:
            self.close()
            raise

    # -- records --

    def _laser(self, k: int, lineno: int) -> LaserConfig:
        las = self._lasers.get(k)
        if las is None:
            if k not in self._warned_lasers:
                self._warned_lasers.add(k)
                self._note(
                    IssueCode.LOG_UNKNOWN_LASER,
                    f"scan{k}: but the header describes no laser {k}",
                    lineno,
                )
            las = LaserConfig(number=k)
        return las

    def _reset(self, lineno: int) -> None:
        self._pending = _Pending(start_line=lineno)

    def _drop_incomplete(self, lineno: int, why: str) -> None:
        p = self._pending
        if not p.empty() and not p.bad:
            self._fail(
                IssueCode.LOG_INCOMPLETE_RECORD,
                f"the record started on line {p.start_line} has no scanK: line ({why})",
                p.start_line,
            )
        self._reset(lineno)

    def _records(self) -> Iterator[LogRecord]:
        version = self._version
        for item, s in self._content_lines():
            lineno, line, has_nl = item
            p = self._pending
            if s[:1] == b"#":
                if s == b"# End of log":
                    self.complete = True
                elif s.startswith(b"#rawRobot:"):
                    self._pose_line("robotRaw", s.split(None, 1)[1:], lineno, line, has_nl)
                elif s.startswith(b"#scan") and s[5:].isdigit():
                    if not p.empty():
                        self._drop_incomplete(lineno, "a new #scan record starts")
                        p = self._pending
                    p.start_line = lineno
                    p.scan_id = _int(s[5:])
                continue
            parts = s.split(None, 1)
            tag = parts[0]
            rest = parts[1] if len(parts) > 1 else b""
            if tag[-1:] == b":" and tag.startswith(b"scan") and _is_laser_no(tag[4:-1]):
                rec = self._finish_scan(int(tag[4:-1]), rest, lineno, line, has_nl, pairs=True)
                if rec is not None:
                    yield rec
                continue
            if tag[-1:] == b":" and tag.startswith(b"sick") and _is_laser_no(tag[4:-1]):
                k = int(tag[4:-1])
                if version == 1:
                    rec = self._finish_scan(k, rest, lineno, line, has_nl, pairs=False)
                    if rec is not None:
                        yield rec
                else:
                    self._array_line(p.ranges, k, rest, lineno, line, has_nl, "sick")
                continue
            if tag == b"scanId:" or tag == b"scan1Id:":
                if not p.empty():
                    self._drop_incomplete(lineno, f"a new {_decode(tag)} line starts")
                    p = self._pending
                p.start_line = lineno
                try:
                    p.scan_id = _int(rest.split()[0])
                except (ValueError, IndexError):
                    self._fail(
                        IssueCode.LOG_BAD_VALUE,
                        f"{_decode(tag)} expects an integer",
                        lineno,
                        line,
                        has_nl,
                    )
                    p.bad = True
                    p.scan_id = -1
                continue
            if tag == b"logTime:" or tag == b"time:":
                if not p.empty() and (p.scan_id is None or p.poses):
                    self._drop_incomplete(lineno, f"a new {_decode(tag)} line starts")
                    p = self._pending
                if p.empty():
                    p.start_line = lineno
                p.has_time = True
                if tag == b"logTime:":
                    self._velocities = None  # a new cycle: its velocities: line follows
                try:
                    self._time = _time(rest.split()[0])
                except (ValueError, IndexError):
                    self._fail(
                        IssueCode.LOG_BAD_VALUE,
                        f"{_decode(tag)} expects seconds.milliseconds",
                        lineno,
                        line,
                        has_nl,
                    )
                    p.bad = True
                    continue
                if not math.isfinite(self._time):
                    self._fail(
                        IssueCode.LOG_NON_FINITE,
                        f"{_decode(tag)} NaN or infinite value",
                        lineno,
                        line,
                        has_nl,
                    )
                    p.bad = True
                continue
            if tag == b"velocities:":
                try:
                    v = _small(rest)
                    if len(v) not in (2, 3):
                        raise ValueError(f"expects 3 numbers (Vel RotVel LatVel), got {len(v)}")
                except ValueError as err:
                    msg = str(err) if "expects" in str(err) else "values that are not numbers"
                    self._fail(IssueCode.LOG_BAD_VALUE, f"velocities: {msg}", lineno, line, has_nl)
                    p.bad = True
                    continue
                if not all(map(math.isfinite, v)):
                    self._fail(
                        IssueCode.LOG_NON_FINITE,
                        "velocities: NaN or infinite value",
                        lineno,
                        line,
                        has_nl,
                    )
                    p.bad = True
                    continue
                self._velocities = (v[0], v[1], v[2] if len(v) == 3 else math.nan)
                continue
            if tag.startswith(b"reflector") and _is_laser_no(tag[9:-1]) and tag[-1:] == b":":
                self._array_line(
                    p.reflectors, int(tag[9:-1]), rest, lineno, line, has_nl, "reflector"
                )
                continue
            if tag == b"cairn:":
                yield from self._event("goal", s, lineno)
                continue
            if tag in (b"loop:", b"loop"):
                words = rest.split()
                if len(words) >= 1 and words[0] in (b"start", b"stop", b"end"):
                    yield from self._event(
                        "loop",
                        s,
                        lineno,
                        action=_decode(words[0]),
                        name=_decode(b" ".join(words[1:])),
                    )
                    continue
            if tag == b"robot_id:" and version == 1:
                continue
            if tag[-1:] == b":" and len(tag) > 1:
                name = _decode(tag[:-1])
                if (
                    name in ("robot", "robotGlobal", "robotRaw")
                    or name in self.header.location_types
                ):
                    self._pose_line(name, [rest], lineno, line, has_nl)
                    continue
                # Unknown tag: part of the scan record, a tagged string, or an info line.
                if p.scan_id is not None:
                    p.extra.append(_decode(s))
                    self._note(
                        IssueCode.LOG_UNKNOWN_TAG,
                        f"unknown tag {_decode(tag)!r} in a scan record kept",
                        lineno,
                    )
                elif p.poses:
                    yield from self._event("tag", s, lineno)
                else:
                    self._note(
                        IssueCode.LOG_UNKNOWN_TAG,
                        f"unknown tag {_decode(tag)!r} kept as an info line",
                        lineno,
                    )
                    yield LogEvent("info", _decode(s), time=None, line=lineno)
                continue
            if p.poses and p.scan_id is None and _printable(s):
                yield from self._event("tag", s, lineno)
                continue
            self._fail(
                IssueCode.LOG_GARBAGE_LINE,
                "expected a tag ('word:' then values), a comment ('#...') or a loop marker",
                lineno,
                line,
                has_nl,
            )
        if not self._pending.empty() and not self._pending.bad:
            self._fail(
                IssueCode.LOG_TRUNCATED,
                f"the log ends inside the record started on line {self._pending.start_line} "
                f"(no scanK: line follows; truncated?)",
                self._pending.start_line,
            )
        if not self.complete:
            self._note(
                IssueCode.LOG_NO_END_MARK,
                "no '# End of log' line: the logger did not "
                "shut down cleanly (or the file is truncated)",
                None,
            )
        self._done = True

    def _event(
        self, kind: str, s: bytes, lineno: int, *, action: str = "", name: str = ""
    ) -> Iterator[LogEvent]:
        p = self._pending
        if p.bad:
            self._reset(lineno)
            return
        text = _decode(s)
        if kind == "goal":
            name = goal_fields(LogEvent("goal", text))[3]
        poses = p.poses
        ev = LogEvent(
            kind,
            text,
            time=self._time if p.has_time else None,
            robot=poses.get("robot"),
            robot_global=poses.get("robotGlobal"),
            robot_raw=poses.get("robotRaw"),
            other_poses=tuple(
                (k, poses[k]) for k in p.pose_order if k not in ("robot", "robotGlobal", "robotRaw")
            ),
            name=name,
            action=action,
            line=lineno,
        )
        self._reset(lineno)
        if self._version < 4:
            self._time = None
        yield ev

    def _pose_line(
        self, name: str, rest_parts: list[bytes], lineno: int, line: bytes, has_nl: bool
    ) -> None:
        p = self._pending
        if p.empty() and p.start_line == 0:
            p.start_line = lineno
        rest = rest_parts[0] if rest_parts else b""
        try:
            v = _small(rest)
        except ValueError:
            self._fail(
                IssueCode.LOG_BAD_VALUE,
                f"{name}: values that are not numbers",
                lineno,
                line,
                has_nl,
            )
            p.bad = True
            return
        if len(v) == 0 and name not in ("robot", "robotGlobal"):
            if name not in p.poses:
                p.pose_order.append(name)
            p.poses[name] = None
            return
        if len(v) not in (3, 5):
            self._fail(
                IssueCode.LOG_BAD_VALUE,
                f"{name}: expects 3 numbers (X Y Th), got {len(v)}",
                lineno,
                line,
                has_nl,
            )
            p.bad = True
            return
        if not all(map(math.isfinite, v)):
            self._fail(
                IssueCode.LOG_NON_FINITE, f"{name}: NaN or infinite value", lineno, line, has_nl
            )
            p.bad = True
            return
        if name not in p.poses:
            p.pose_order.append(name)
        p.poses[name] = Pose2D(float(v[0]), float(v[1]), float(v[2]))
        if len(v) == 5 and name == "robot":
            p.v2_velocities = (float(v[3]), float(v[4]), math.nan)

    def _array_line(
        self,
        store: dict[int, np.ndarray[Any, Any]],
        k: int,
        rest: bytes,
        lineno: int,
        line: bytes,
        has_nl: bool,
        what: str,
    ) -> None:
        p = self._pending
        if p.empty() and p.start_line == 0:
            p.start_line = lineno
        try:
            v = _numbers(rest)
        except ValueError:
            self._fail(
                IssueCode.LOG_BAD_VALUE,
                f"{what}{k}: values that are not numbers",
                lineno,
                line,
                has_nl,
            )
            p.bad = True
            return
        if not _finite(v):
            self._fail(
                IssueCode.LOG_NON_FINITE, f"{what}{k}: NaN or infinite value", lineno, line, has_nl
            )
            p.bad = True
            return
        las = self._laser(k, lineno)
        if las.count and len(v) != las.count:
            self._fail(
                IssueCode.LOG_WRONG_READING_COUNT,
                f"{what}{k}: has {len(v)} readings, sick{k}conf: says {las.count}",
                lineno,
                line,
                has_nl,
            )
            p.bad = True
            return
        store[k] = v

    def _finish_scan(
        self, k: int, rest: bytes, lineno: int, line: bytes, has_nl: bool, *, pairs: bool
    ) -> LaserScan | None:
        p = self._pending
        version = self._version
        rec: LaserScan | None = None
        what = f"scan{k}" if pairs else f"sick{k}"
        try:
            if p.bad:
                return None
            try:
                v = _numbers(rest)
            except ValueError:
                self._fail(
                    IssueCode.LOG_BAD_VALUE,
                    f"{what}: values that are not numbers",
                    lineno,
                    line,
                    has_nl,
                )
                return None
            if not _finite(v):
                self._fail(
                    IssueCode.LOG_NON_FINITE, f"{what}: NaN or infinite value", lineno, line, has_nl
                )
                return None
            las = self._laser(k, lineno)
            if pairs and len(v) % 2:
                self._fail(
                    IssueCode.LOG_WRONG_READING_COUNT,
                    f"{what}: odd number of values ({len(v)}): expects x y pairs",
                    lineno,
                    line,
                    has_nl,
                )
                return None
            n = len(v) // 2 if pairs else len(v)
            if las.count and n != las.count:
                self._fail(
                    IssueCode.LOG_WRONG_READING_COUNT,
                    f"{what}: has {n} readings, sick{k}conf: says {las.count}",
                    lineno,
                    line,
                    has_nl,
                )
                return None
            if "robot" not in p.poses or p.poses["robot"] is None:
                self._fail(
                    IssueCode.LOG_INCOMPLETE_RECORD,
                    f"{what}: the record has no robot: pose",
                    lineno,
                    line,
                    has_nl,
                )
                return None
            xy = None
            ranges = p.ranges.get(k)
            if pairs:
                xy = v.reshape(-1, 2)
                if version in (2, 3) and las.pose.th != 0.0:
                    # File pairs are robot-frame offsets (not rotated by the mount): rotate back.
                    t = math.radians(las.pose.th)
                    c, s = math.cos(t), math.sin(t)
                    zero = (xy[:, 0] == 0.0) & (xy[:, 1] == 0.0)
                    xy = xy @ np.array([[c, -s], [s, c]])
                    xy[zero] = 0.0
            else:
                ranges = v
            poses = p.poses
            vel = self._velocities if version >= 3 else p.v2_velocities
            if p.scan_id is not None:
                sid = p.scan_id
            elif version == 1:
                sid = (self._v1_id or 0) + 1
            else:
                sid = 0
            self._v1_id = sid
            rec = LaserScan(
                scan_id=sid,
                laser=k,
                robot=poses["robot"],  # type: ignore[arg-type]
                time=self._time if version >= 2 else None,
                velocities=vel,
                robot_global=poses.get("robotGlobal"),
                robot_raw=poses.get("robotRaw"),
                other_poses=tuple(
                    (nm, poses[nm])
                    for nm in p.pose_order
                    if nm not in ("robot", "robotGlobal", "robotRaw")
                ),
                xy=xy,
                ranges=ranges,
                reflectors=p.reflectors.get(k),
                extra=tuple(p.extra),
                line=lineno,
            )
            return rec
        finally:
            self._reset(lineno)
            if version < 4:
                self._time = None
                self._velocities = None


def _printable(s: bytes) -> bool:
    try:
        text = s.decode("utf-8")
    except UnicodeDecodeError:
        return False
    return text.isprintable()
