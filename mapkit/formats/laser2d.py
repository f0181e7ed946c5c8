"""ARIA ``.2d`` laser logs: a streaming reader (strict and tolerant) and a writer per version.

Logger versions 1 to 4 are read and written (FORMATS.md part B): v1 (Saphira-era writers: raw
``sick1:`` ranges), v2 (``ArSickLogger``), v3 (ARIA 2.7 ``ArLaserLogger``) and v4 (ARIA 2.8+).
Records come out in one convention whatever the version (see :mod:`mapkit.model.scan`): hit
points in the laser frame, poses as :class:`~mapkit.model.Pose2D`, arrays per scan.

Reading streams: :func:`iter_log` returns a :class:`LogReader` whose ``header`` is read at once and
which yields one record at a time, so a log of any length is read in bounded memory.
:func:`read_log` loads a whole log strictly, :func:`recover_log` tolerantly (bad records are
skipped and reported as :class:`~mapkit.diagnostics.Issue` values with 7xx codes).

Choices where ARIA's writers are ambiguous:

* ``time:`` values are ``<seconds>.<milliseconds>``: v2/v3 do not zero-pad the milliseconds
  (``5.7`` is 5.007 s), v4 does; reading the part after the dot as an integer count of
  milliseconds (when it has at most three digits) is right for both.
* v3 writes raw ranges from the largest angle to the smallest while ``sick1conf:`` lists the
  smallest first; the reader turns that into ``start`` = largest angle, so reading ``i`` is always
  at ``start + i * increment``. In v2 the order cannot be told from the file; it is taken as
  written (first reading at the first ``sick1conf:`` angle).
* Unknown tags never stop the reader: inside a scan record they are kept on the scan
  (:attr:`~mapkit.model.LaserScan.extra`), after ``time:`` and poses they become a ``"tag"``
  event, alone an ``"info"`` event; all are written back. A line that is not a tag (a word ending
  in ``:``), a comment or a ``loop start|stop`` marker is garbage: an error in strict mode, skipped
  and reported in tolerant mode.

Examples:
    >>> text = '''LaserOdometryLog
    ... #Created by ArLaserLogger
    ... version: 4
    ... sick1pose: 100 0 90.00
    ... sick1conf: -90.00 90.00 2
    ... sick1name: laser_1
    ... scan1pose: 100 0 0 90.00
    ... scan1conf: -90.00 90.00 2
    ... scan1name: laser_1
    ... locationTypes: robot robotGlobal
    ... logTime: 0.100
    ... velocities: 0.00 0.00 0.00
    ... scanId: 0
    ... robot: 1000 0 90.00
    ... robotGlobal: 1000 0 90.00
    ... scan1: 500 0  0 0 
    ... # End of log
    ... '''
    >>> log = loads_log(text)
    >>> scan = log.scans[0]
    >>> scan.robot, scan.valid.tolist()
    (Pose2D(x=1000.0, y=0.0, th=90.0), [True, False])
    >>> scan.global_points(log.header.laser(1)).round(6).tolist()
    [[500.0, 100.0]]
    >>> dumps_log(log) == text
    True
"""

from __future__ import annotations

import io
import math
import os
import re
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from typing import IO, Any

import numpy as np

from mapkit._atomic import atomic_open
from mapkit._typing import PathLike
from mapkit.diagnostics import Issue, IssueCode
from mapkit.errors import LogFormatError
from mapkit.formats._numbers import token_double, token_long
from mapkit.formats.map import tokenize
from mapkit.model.scan import (
    LaserConfig,
    LaserLog,
    LaserScan,
    LogEvent,
    LogHeader,
    LogRecord,
    Pose2D,
)

__all__ = [
    "VERSIONS",
    "LogReader",
    "LogWriter",
    "dumps_log",
    "goal_event",
    "goal_fields",
    "iter_log",
    "log_summary",
    "loads_log",
    "loop_event",
    "read_log",
    "recover_log",
    "write_log",
]

#: Logger versions mapkit reads and writes.
VERSIONS = (1, 2, 3, 4)

_INTRO = b"LaserOdometryLog"
_END_MARK = "# End of log"
_CREATED = {
    1: None,
    2: "#Created by ARIA's ArSickLogger",
    3: "#Created by ARIA's ArLaserLogger",
    4: "#Created by ArLaserLogger",
}
_INT_CHARS = b"0123456789- \t"
_RECORD_TAGS = {b"scanId:", b"scan1Id:", b"time:", b"logTime:", b"robot:", b"velocities:"}


def _decode(b: bytes) -> str:
    return b.decode("utf-8", "surrogateescape")


# A line of plain decimal numbers (what ARIA's loggers write), which numpy reads exactly as C's
# strtod does; atomic groups keep the match linear whatever the line holds.
_PLAIN_NUMBERS = re.compile(
    rb"[ \t\r\x0b\x0c]*(?>[+-]?(?:[0-9]+(?:\.[0-9]*+)?+|\.[0-9]+)(?:[eE][+-]?[0-9]+)?+"
    rb"(?:[ \t\r\x0b\x0c]++|\Z))*+"
)


_BIG_INT = 10**18


def _numbers(rest: bytes) -> np.ndarray[Any, np.dtype[np.float64]]:
    """Whitespace-separated numbers to float64 (C's ``strtod``, any length in linear time).

    Every value is a double as ``strtod`` reads it (a 30-digit integer is 1e30); ValueError on
    a token that is not a whole number. The result may hold NaN or infinities only when
    :func:`_all_ints` is false.
    """
    if _all_ints(rest):
        ints = np.fromstring(rest, dtype=np.int64, sep=" ")
        if len(ints) == 0 or not ((ints >= _BIG_INT) | (ints <= -_BIG_INT)).any():
            return ints.astype(np.float64)
        # 19 digits or more: int64 may have saturated; strtod reads them as doubles (below).
    if _PLAIN_NUMBERS.fullmatch(rest):
        return np.array(rest.split(), dtype=np.float64)
    return np.array(_small(rest), dtype=np.float64)


def _all_ints(rest: bytes) -> bool:
    """True when ``rest`` is only optionally negative decimal integers separated by blanks."""
    if rest.translate(None, _INT_CHARS):
        return False
    n = rest.count(b"-")
    return n == 0 or (
        n == rest.count(b" -") + rest.count(b"\t-") + rest.startswith(b"-")
        and b"- " not in rest and b"-\t" not in rest and b"--" not in rest
        and not rest.endswith(b"-")
    )


def _finite(v: np.ndarray[Any, Any]) -> bool:
    return bool(np.isfinite(v).all()) if len(v) else True


def _small(rest: bytes) -> list[float]:
    """A few numbers (a pose line) as floats (C's ``strtod``); ValueError on a bad token."""
    return [_float(t) for t in rest.split()]


def _float(tok: bytes) -> float:
    """One whole token read by C's ``strtod``; ValueError when it is not a number."""
    v = token_double(tok.decode("latin-1"))
    if v is None:
        raise ValueError(f"not a number: {tok[:40]!r}")
    return v


def _int(tok: bytes) -> int:
    """One whole token read by C's ``strtol`` in base 10 (saturating); ValueError otherwise."""
    v = token_long(tok.decode("latin-1"))
    if v is None:
        raise ValueError(f"not an integer: {tok[:40]!r}")
    return v


def _time(tok: bytes) -> float:
    """``S.M`` with M milliseconds (ARIA's unpadded ``%ld.%ld``), else a decimal number."""
    s, dot, m = tok.partition(b".")
    if (dot and 0 < len(m) <= 3 and m.isdigit() and len(s) <= 16
            and (s.isdigit() or (s[:1] == b"-" and s[1:].isdigit()))):
        # (Longer seconds: milliseconds are below a double's precision; strtod reads them.)
        sec = int(s)
        ms = int(m)
        return (sec * 1000 + (ms if not s.startswith(b"-") else -ms)) / 1000.0
    return _float(tok)


def goal_fields(event: LogEvent) -> tuple[str, str, str, str]:
    """``(type, description, icon, name)`` of a ``cairn:`` goal event (quotes removed).

    Examples:
        >>> e = goal_event("goal1", Pose2D(0, 0, 0))
        >>> e.text
        'cairn: GoalWithHeading "" ICON_GOALWITHHEADING "goal1"'
        >>> goal_fields(e)
        ('GoalWithHeading', '', 'ICON_GOALWITHHEADING', 'goal1')
    """
    toks = tokenize(event.text.split(":", 1)[1] if ":" in event.text else "")
    toks = [t[1:-1] if len(t) >= 2 and t[0] == t[-1] == '"' else t for t in toks]
    toks += [""] * (4 - len(toks))
    return toks[0] or "GoalWithHeading", toks[1], toks[2], " ".join(toks[3:]).strip()


def goal_event(
    name: str, robot: Pose2D, *, time: float | None = None, robot_global: Pose2D | None = None,
    type: str = "GoalWithHeading",
) -> LogEvent:
    """A goal event as ARIA's logger writes it (``cairn: GoalWithHeading "" ICON_... "name"``)."""
    icon = "ICON_" + type.upper()
    return LogEvent("goal", f'cairn: {type} "" {icon} "{name}"', time=time, robot=Pose2D(*robot),
                    robot_global=None if robot_global is None else Pose2D(*robot_global), name=name)


def loop_event(
    action: str, tag: str, robot: Pose2D, *, time: float | None = None,
    robot_global: Pose2D | None = None,
) -> LogEvent:
    """A loop marker (``loop: start 1`` / ``loop: stop 1``) as the robot's microcontroller logs it."""
    if action not in ("start", "stop", "end"):
        raise ValueError(f"loop action must be start, stop or end, not {action!r}")
    return LogEvent("loop", f"loop: {action} {tag}", time=time, robot=Pose2D(*robot),
                    robot_global=None if robot_global is None else Pose2D(*robot_global),
                    name=tag, action=action)


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


class LogReader:
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

    def __init__(self, fh: IO[bytes], *, source: str = "<stream>", strict: bool = True,
                 size: int | None = None, close: bool = False) -> None:
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

    def _next_line(self) -> tuple[int, bytes, bool] | None:
        if self._pushback is not None:
            item, self._pushback = self._pushback, None
            return item
        raw = self._fh.readline()
        if not raw:
            return None
        self.bytes_read += len(raw)
        self._lineno += 1
        has_nl = raw.endswith(b"\n")
        line = raw.rstrip(b"\r\n")
        return self._lineno, line, has_nl

    def _content_lines(self) -> Iterator[tuple[tuple[int, bytes, bool], bytes]]:
        """Each line that is not blank: ``((number, line, ends with LF), stripped line)``."""
        while True:
            item = self._next_line()
            if item is None:
                return
            s = item[1].strip()
            if s:
                yield item, s

    def _fail(self, code: IssueCode, message: str, lineno: int, text: bytes | str = b"",
              has_nl: bool = True) -> None:
        """Strict: raise. Tolerant: note the issue (and the record is dropped by the caller)."""
        if not has_nl:
            message += "; the file ends inside this line (truncated?)"
            code = IssueCode.LOG_TRUNCATED if code in (
                IssueCode.LOG_BAD_VALUE, IssueCode.LOG_WRONG_READING_COUNT) else code
        t = text if isinstance(text, str) else _decode(text)
        if len(t) > 120:
            t = t[:117] + "..."
        if self.strict:
            raise LogFormatError(message, source=self.source, line=lineno, text=t)
        self.issues.append(Issue.make(code, message, source=self.source, line=lineno))

    def _note(self, code: IssueCode, message: str, lineno: int | None) -> None:
        self.issues.append(Issue.make(code, message, source=self.source, line=lineno))

    # -- header --

    def _read_header(self) -> LogHeader:
        first = self._next_line()
        while first is not None and not first[1].strip():
            first = self._next_line()
        if first is None:
            raise LogFormatError("empty file: a .2d log starts with 'LaserOdometryLog'",
                                 source=self.source, line=1)
        lineno, line, _ = first
        if line.strip().lstrip(b"\xef\xbb\xbf") != _INTRO:
            raise LogFormatError(
                f"not a .2d laser log: expected 'LaserOdometryLog' on the first line, got "
                f"{_decode(line[:40])!r}", source=self.source, line=lineno, text=_decode(line))
        version: int | None = None
        poses: dict[int, tuple[float, float, float]] = {}
        poses3: dict[int, tuple[float, float, float, float]] = {}
        confs: dict[int, tuple[float, float, int]] = {}
        confs_scan: dict[int, tuple[float, float, int]] = {}
        names: dict[int, str] = {}
        location_types: tuple[str, ...] = ()
        use_encoder: bool | None = None
        comments: list[str] = []
        extra: list[str] = []
        for item, s in self._content_lines():
            lineno, line, has_nl = item
            if s.startswith(b"#"):
                if s.startswith(b"#scan") or s.startswith(b"#rawRobot:"):
                    self._pushback = item
                    break
                if s == _END_MARK.encode():
                    self._pushback = item
                    break
                comments.append(_decode(s[1:]))
                continue
            parts = s.split(None, 1)
            tag = parts[0]
            rest = parts[1] if len(parts) > 1 else b""
            if tag in _RECORD_TAGS or tag in (b"cairn:", b"loop", b"loop:") or (
                tag.startswith(b"scan") and _is_laser_no(tag[4:-1]) and tag.endswith(b":")
            ) or (version == 1 and tag.startswith(b"sick") and _is_laser_no(tag[4:-1])
                  and tag.endswith(b":")) or (tag.startswith(b"reflector")):
                self._pushback = item
                break
            try:
                if tag == b"version:":
                    v = _int(rest.split()[0])
                    if v not in VERSIONS:
                        self._note(IssueCode.LOG_UNKNOWN_VERSION,
                                   f"version {v} is not one mapkit knows (1-4); read as version 4",
                                   lineno)
                        v = 4
                    version = v
                elif tag == b"useEncoderPose:":
                    use_encoder = bool(_int(rest.split()[0]))
                elif tag == b"locationTypes:":
                    location_types = tuple(_decode(t) for t in rest.split())
                elif _laser_tag(tag, b"sick", b"pose:") or _laser_tag(tag, b"scan", b"pose:"):
                    k = _laser_no(tag)
                    vals = _numbers(rest)
                    if not np.all(np.isfinite(vals)):
                        raise ValueError("NaN or infinite value")
                    if tag.startswith(b"sick"):
                        if len(vals) != 3:
                            raise ValueError(f"expects 3 numbers (X Y Th), got {len(vals)}")
                        poses[k] = (float(vals[0]), float(vals[1]), float(vals[2]))
                    else:
                        if len(vals) not in (3, 4):
                            raise ValueError(f"expects 4 numbers (X Y Z Th), got {len(vals)}")
                        if len(vals) == 3:
                            vals = np.array([vals[0], vals[1], 0.0, vals[2]])
                        poses3[k] = (float(vals[0]), float(vals[1]), float(vals[2]), float(vals[3]))
                elif _laser_tag(tag, b"sick", b"conf:") or _laser_tag(tag, b"scan", b"conf:"):
                    k = _laser_no(tag)
                    vals = _numbers(rest)
                    if len(vals) != 3:
                        raise ValueError(f"expects 3 numbers (first angle, last angle, count), "
                                         f"got {len(vals)}")
                    if not np.all(np.isfinite(vals)) or vals[2] != int(vals[2]) or vals[2] < 0:
                        raise ValueError("expects finite angles and a whole count")
                    (confs if tag.startswith(b"sick") else confs_scan)[k] = (
                        float(vals[0]), float(vals[1]), int(vals[2]))
                elif _laser_tag(tag, b"sick", b"name:") or _laser_tag(tag, b"scan", b"name:"):
                    names.setdefault(_laser_no(tag), _decode(rest.strip()))
                else:
                    extra.append(_decode(s))
                    self._note(IssueCode.LOG_UNKNOWN_TAG,
                               f"unknown header line {_decode(tag)!r} kept", lineno)
            except (ValueError, IndexError) as err:
                what = str(err) if str(err).startswith("expects") else "has a value that is not a number"
                self._fail(IssueCode.LOG_BAD_HEADER_LINE, f"{_decode(tag)} {what}",
                           lineno, line, has_nl)
        if version is None:
            self._note(IssueCode.LOG_UNKNOWN_VERSION, "no 'version:' line; read as version 4"
                       if confs or poses3 else "no 'version:' line; read as version 4", None)
            version = 4
        self._version = version
        numbers = sorted(set(poses) | set(confs) | set(poses3) | set(confs_scan) | set(names)) or [1]
        lasers = []
        for k in numbers:
            if k in poses:
                px, py, pth = poses[k]
            elif k in poses3:
                px, py, _, pth = poses3[k]
            else:
                px = py = pth = 0.0
            a, b, n = confs.get(k) or confs_scan.get(k) or (-90.0, 90.0, 0)
            if version == 3:
                # Robot-frame min and max; ranges written from the largest angle down.
                lo, hi = min(a, b), max(a, b)
                a, b = hi - pth, lo - pth
            lasers.append(LaserConfig(number=k, pose=Pose2D(px, py, pth), start=a, end=b, count=n,
                                      name=names.get(k, ""),
                                      z=poses3[k][2] if k in poses3 else None))
        return LogHeader(version=version, lasers=tuple(lasers), location_types=location_types,
                         use_encoder_pose=use_encoder, comments=tuple(comments), extra=tuple(extra))

    # -- records --

    def _laser(self, k: int, lineno: int) -> LaserConfig:
        las = self._lasers.get(k)
        if las is None:
            if k not in self._warned_lasers:
                self._warned_lasers.add(k)
                self._note(IssueCode.LOG_UNKNOWN_LASER,
                           f"scan{k}: but the header describes no laser {k}", lineno)
            las = LaserConfig(number=k)
        return las

    def _reset(self, lineno: int) -> None:
        self._pending = _Pending(start_line=lineno)

    def _drop_incomplete(self, lineno: int, why: str) -> None:
        p = self._pending
        if not p.empty() and not p.bad:
            self._fail(IssueCode.LOG_INCOMPLETE_RECORD,
                       f"the record started on line {p.start_line} has no scanK: line ({why})",
                       p.start_line)
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
                    self._fail(IssueCode.LOG_BAD_VALUE, f"{_decode(tag)} expects an integer",
                               lineno, line, has_nl)
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
                    self._fail(IssueCode.LOG_BAD_VALUE,
                               f"{_decode(tag)} expects seconds.milliseconds", lineno, line, has_nl)
                    p.bad = True
                    continue
                if not math.isfinite(self._time):
                    self._fail(IssueCode.LOG_NON_FINITE, f"{_decode(tag)} NaN or infinite value",
                               lineno, line, has_nl)
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
                    self._fail(IssueCode.LOG_NON_FINITE, "velocities: NaN or infinite value",
                               lineno, line, has_nl)
                    p.bad = True
                    continue
                self._velocities = (v[0], v[1], v[2] if len(v) == 3 else math.nan)
                continue
            if tag.startswith(b"reflector") and _is_laser_no(tag[9:-1]) and tag[-1:] == b":":
                self._array_line(p.reflectors, int(tag[9:-1]), rest, lineno, line, has_nl,
                                 "reflector")
                continue
            if tag == b"cairn:":
                yield from self._event("goal", s, lineno)
                continue
            if tag in (b"loop:", b"loop"):
                words = rest.split()
                if len(words) >= 1 and words[0] in (b"start", b"stop", b"end"):
                    yield from self._event("loop", s, lineno, action=_decode(words[0]),
                                           name=_decode(b" ".join(words[1:])))
                    continue
            if tag == b"robot_id:" and version == 1:
                continue
            if tag[-1:] == b":" and len(tag) > 1:
                name = _decode(tag[:-1])
                if name in ("robot", "robotGlobal", "robotRaw") or name in self.header.location_types:
                    self._pose_line(name, [rest], lineno, line, has_nl)
                    continue
                # Unknown tag: part of the scan record, a tagged string, or an info line.
                if p.scan_id is not None:
                    p.extra.append(_decode(s))
                    self._note(IssueCode.LOG_UNKNOWN_TAG,
                               f"unknown tag {_decode(tag)!r} in a scan record kept", lineno)
                elif p.poses:
                    yield from self._event("tag", s, lineno)
                else:
                    self._note(IssueCode.LOG_UNKNOWN_TAG,
                               f"unknown tag {_decode(tag)!r} kept as an info line", lineno)
                    yield LogEvent("info", _decode(s), time=None, line=lineno)
                continue
            if p.poses and p.scan_id is None and _printable(s):
                yield from self._event("tag", s, lineno)
                continue
            self._fail(IssueCode.LOG_GARBAGE_LINE,
                       "expected a tag ('word:' then values), a comment ('#...') or a loop marker",
                       lineno, line, has_nl)
        if not self._pending.empty() and not self._pending.bad:
            self._fail(IssueCode.LOG_TRUNCATED,
                       f"the log ends inside the record started on line {self._pending.start_line} "
                       f"(no scanK: line follows; truncated?)", self._pending.start_line)
        if not self.complete:
            self._note(IssueCode.LOG_NO_END_MARK, "no '# End of log' line: the logger did not "
                       "shut down cleanly (or the file is truncated)", None)
        self._done = True

    def _event(self, kind: str, s: bytes, lineno: int, *, action: str = "",
               name: str = "") -> Iterator[LogEvent]:
        p = self._pending
        if p.bad:
            self._reset(lineno)
            return
        text = _decode(s)
        if kind == "goal":
            name = goal_fields(LogEvent("goal", text))[3]
        poses = p.poses
        ev = LogEvent(
            kind, text, time=self._time if p.has_time else None, robot=poses.get("robot"),
            robot_global=poses.get("robotGlobal"), robot_raw=poses.get("robotRaw"),
            other_poses=tuple((k, poses[k]) for k in p.pose_order
                              if k not in ("robot", "robotGlobal", "robotRaw")),
            name=name, action=action, line=lineno)
        self._reset(lineno)
        if self._version < 4:
            self._time = None
        yield ev

    def _pose_line(self, name: str, rest_parts: list[bytes], lineno: int, line: bytes,
                   has_nl: bool) -> None:
        p = self._pending
        if p.empty() and p.start_line == 0:
            p.start_line = lineno
        rest = rest_parts[0] if rest_parts else b""
        try:
            v = _small(rest)
        except ValueError:
            self._fail(IssueCode.LOG_BAD_VALUE, f"{name}: values that are not numbers",
                       lineno, line, has_nl)
            p.bad = True
            return
        if len(v) == 0 and name not in ("robot", "robotGlobal"):
            if name not in p.poses:
                p.pose_order.append(name)
            p.poses[name] = None
            return
        if len(v) not in (3, 5):
            self._fail(IssueCode.LOG_BAD_VALUE, f"{name}: expects 3 numbers (X Y Th), got {len(v)}",
                       lineno, line, has_nl)
            p.bad = True
            return
        if not all(map(math.isfinite, v)):
            self._fail(IssueCode.LOG_NON_FINITE, f"{name}: NaN or infinite value",
                       lineno, line, has_nl)
            p.bad = True
            return
        if name not in p.poses:
            p.pose_order.append(name)
        p.poses[name] = Pose2D(float(v[0]), float(v[1]), float(v[2]))
        if len(v) == 5 and name == "robot":
            p.v2_velocities = (float(v[3]), float(v[4]), math.nan)

    def _array_line(self, store: dict[int, np.ndarray[Any, Any]], k: int, rest: bytes, lineno: int,
                    line: bytes, has_nl: bool, what: str) -> None:
        p = self._pending
        if p.empty() and p.start_line == 0:
            p.start_line = lineno
        try:
            v = _numbers(rest)
        except ValueError:
            self._fail(IssueCode.LOG_BAD_VALUE, f"{what}{k}: values that are not numbers",
                       lineno, line, has_nl)
            p.bad = True
            return
        if not _finite(v):
            self._fail(IssueCode.LOG_NON_FINITE, f"{what}{k}: NaN or infinite value",
                       lineno, line, has_nl)
            p.bad = True
            return
        las = self._laser(k, lineno)
        if las.count and len(v) != las.count:
            self._fail(IssueCode.LOG_WRONG_READING_COUNT,
                       f"{what}{k}: has {len(v)} readings, sick{k}conf: says {las.count}",
                       lineno, line, has_nl)
            p.bad = True
            return
        store[k] = v

    def _finish_scan(self, k: int, rest: bytes, lineno: int, line: bytes, has_nl: bool, *,
                     pairs: bool) -> LaserScan | None:
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
                self._fail(IssueCode.LOG_BAD_VALUE, f"{what}: values that are not numbers",
                           lineno, line, has_nl)
                return None
            if not _finite(v):
                self._fail(IssueCode.LOG_NON_FINITE, f"{what}: NaN or infinite value",
                           lineno, line, has_nl)
                return None
            las = self._laser(k, lineno)
            if pairs and len(v) % 2:
                self._fail(IssueCode.LOG_WRONG_READING_COUNT,
                           f"{what}: odd number of values ({len(v)}): expects x y pairs",
                           lineno, line, has_nl)
                return None
            n = len(v) // 2 if pairs else len(v)
            if las.count and n != las.count:
                self._fail(IssueCode.LOG_WRONG_READING_COUNT,
                           f"{what}: has {n} readings, sick{k}conf: says {las.count}",
                           lineno, line, has_nl)
                return None
            if "robot" not in p.poses or p.poses["robot"] is None:
                self._fail(IssueCode.LOG_INCOMPLETE_RECORD,
                           f"{what}: the record has no robot: pose", lineno, line, has_nl)
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
                scan_id=sid, laser=k, robot=poses["robot"],  # type: ignore[arg-type]
                time=self._time if version >= 2 else None, velocities=vel,
                robot_global=poses.get("robotGlobal"), robot_raw=poses.get("robotRaw"),
                other_poses=tuple((nm, poses[nm]) for nm in p.pose_order
                                  if nm not in ("robot", "robotGlobal", "robotRaw")),
                xy=xy, ranges=ranges, reflectors=p.reflectors.get(k), extra=tuple(p.extra),
                line=lineno)
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


def _is_laser_no(digits: bytes) -> bool:
    """A laser number in a tag (``scan12:``): 1 to 9 ASCII digits. A longer run is no laser
    number: such a tag is kept as an unknown tag (as text, nothing lost)."""
    return 0 < len(digits) <= 9 and digits.isdigit()


def _laser_tag(tag: bytes, prefix: bytes, suffix: bytes) -> bool:
    return (tag.startswith(prefix) and tag.endswith(suffix)
            and _is_laser_no(tag[len(prefix):-len(suffix)]))


def _laser_no(tag: bytes) -> int:
    digits = bytes(ch for ch in tag[4:] if 48 <= ch <= 57)
    return int(digits)


def iter_log(source: PathLike | IO[bytes] | bytes, *, strict: bool = True,
             name: str | None = None) -> LogReader:
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
        return LogReader(io.BytesIO(data), source=name or "<bytes>", strict=strict,
                         size=len(data), close=True)
    if hasattr(source, "readline"):
        return LogReader(source, source=name or getattr(source, "name", "<stream>"),  # type: ignore[arg-type]
                         strict=strict)
    path = os.fspath(source)
    fh = open(path, "rb", buffering=1 << 20)
    try:
        size = os.fstat(fh.fileno()).st_size
    except OSError:
        size = None
    return LogReader(fh, source=name or path, strict=strict, size=size, close=True)


def _collect(reader: LogReader) -> LaserLog:
    with reader:
        records = list(reader)
    return LaserLog(header=reader.header, records=tuple(records), complete=reader.complete,
                    source=reader.source)


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


def recover_log(source: PathLike | IO[bytes] | bytes, *,
                name: str | None = None) -> tuple[LaserLog, list[Issue]]:
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


def log_summary(source: PathLike | IO[bytes] | bytes, *, strict: bool = True,
                name: str | None = None) -> dict[str, Any]:
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
        "lasers": [{"number": las.number, "name": las.name, "pose": list(las.pose),
                    "first_angle": las.start, "last_angle": las.end, "readings": las.count}
                   for las in h.lasers],
        "location_types": list(h.location_types),
        "scans": scans,
        "scans_per_laser": {str(k): v for k, v in sorted(per_laser.items())},
        "readings": readings,
        "valid_fraction": round(valid / readings, 4) if readings else 0.0,
        "events": events,
        "goals": goals,
        "time_span_s": round(t_last - t_first, 3) if t_first is not None and t_last is not None else None,
        "path_length_m": round(length / 1000.0, 3),
        "complete": reader.complete,
        "issues": [i.to_dict() for i in reader.issues],
    }


def loads_log(text: str | bytes, *, name: str = "<string>") -> LaserLog:
    """Read a ``.2d`` log from text (strict); see :func:`read_log`."""
    data = text.encode("utf-8", "surrogateescape") if isinstance(text, str) else bytes(text)
    return read_log(data, name=name)


# -- writer -------------------------------------------------------------------------------------


def _f0(v: float) -> str:
    return "%.0f" % v


def _f2(v: float) -> str:
    return "%.2f" % v


_INT64_SAFE = 2.0**62  # |values| below this convert to int64 exactly


def _rounded(a: np.ndarray[Any, Any]) -> list[Any]:
    """Values rounded half to even (as ``%.0f``), as ints; as ``%.0f`` text beyond 64 bits."""
    flat = np.asarray(a, dtype=np.float64).reshape(-1)
    if len(flat) and not np.abs(flat).max() < _INT64_SAFE:  # huge (a 50-digit number reads 1e50)
        return ["%.0f" % v for v in flat.tolist()]
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
        total = int(round(t * 1000))
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
                    out.append("velocities: " + " ".join(
                        _f2(x if math.isfinite(x) else 0.0) for x in rec.velocities))
                self._last_time = key
            out.append(f"scanId: {rec.scan_id}")
        elif v in (2, 3):
            out.append(f"scan1Id: {rec.scan_id}")
            if rec.time is not None:
                out.append(f"time: {_time_text(rec.time, v)}")
            if v == 3 and rec.velocities is not None:
                out.append("velocities: " + " ".join(
                    _f2(x if math.isfinite(x) else 0.0) for x in rec.velocities))
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
    log: LaserLog | tuple[LogHeader, Iterable[LogRecord]], path: PathLike, *,
    version: int | None = None, backup: bool = False,
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
