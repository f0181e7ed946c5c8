"""The line plumbing and the header of a ``.2d`` log: what
:class:`~mapkit.formats.laser2d.reader.LogReader` reads before its first record."""

from __future__ import annotations

from collections.abc import Iterator
from typing import IO

import numpy as np

from mapkit.diagnostics import Issue, IssueCode
from mapkit.errors import LogFormatError
from mapkit.formats.laser2d.common import (
    _END_MARK,
    _INTRO,
    _RECORD_TAGS,
    VERSIONS,
    _decode,
    _int,
    _numbers,
)
from mapkit.model.scan import (
    LaserConfig,
    LogHeader,
    Pose2D,
)


class _HeaderReader:
    """Reads lines (with one line of pushback), reports problems, and parses the header; the
    records are :class:`~mapkit.formats.laser2d.reader.LogReader`'s."""

    source: str
    strict: bool
    issues: list[Issue]
    bytes_read: int
    _fh: IO[bytes]
    _lineno: int
    _has_nl: bool
    _pushback: tuple[int, bytes, bool] | None
    _version: int

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

    def _fail(
        self,
        code: IssueCode,
        message: str,
        lineno: int,
        text: bytes | str = b"",
        has_nl: bool = True,
    ) -> None:
        """Strict: raise. Tolerant: note the issue (and the record is dropped by the caller)."""
        if not has_nl:
            message += "; the file ends inside this line (truncated?)"
            code = (
                IssueCode.LOG_TRUNCATED
                if code in (IssueCode.LOG_BAD_VALUE, IssueCode.LOG_WRONG_READING_COUNT)
                else code
            )
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
            raise LogFormatError(
                "empty file: a .2d log starts with 'LaserOdometryLog'", source=self.source, line=1
            )
        lineno, line, _ = first
        if line.strip().lstrip(b"\xef\xbb\xbf") != _INTRO:
            raise LogFormatError(
                f"not a .2d laser log: expected 'LaserOdometryLog' on the first line, got "
                f"{_decode(line[:40])!r}",
                source=self.source,
                line=lineno,
                text=_decode(line),
            )
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
            if (
                tag in _RECORD_TAGS
                or tag in (b"cairn:", b"loop", b"loop:")
                or (tag.startswith(b"scan") and _is_laser_no(tag[4:-1]) and tag.endswith(b":"))
                or (
                    version == 1
                    and tag.startswith(b"sick")
                    and _is_laser_no(tag[4:-1])
                    and tag.endswith(b":")
                )
                or (tag.startswith(b"reflector"))
            ):
                self._pushback = item
                break
            try:
                if tag == b"version:":
                    v = _int(rest.split()[0])
                    if v not in VERSIONS:
                        self._note(
                            IssueCode.LOG_UNKNOWN_VERSION,
                            f"version {v} is not one mapkit knows (1-4); read as version 4",
                            lineno,
                        )
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
                        raise ValueError(
                            f"expects 3 numbers (first angle, last angle, count), got {len(vals)}"
                        )
                    if not np.all(np.isfinite(vals)) or vals[2] != int(vals[2]) or vals[2] < 0:
                        raise ValueError("expects finite angles and a whole count")
                    (confs if tag.startswith(b"sick") else confs_scan)[k] = (
                        float(vals[0]),
                        float(vals[1]),
                        int(vals[2]),
                    )
                elif _laser_tag(tag, b"sick", b"name:") or _laser_tag(tag, b"scan", b"name:"):
                    names.setdefault(_laser_no(tag), _decode(rest.strip()))
                else:
                    extra.append(_decode(s))
                    self._note(
                        IssueCode.LOG_UNKNOWN_TAG,
                        f"unknown header line {_decode(tag)!r} kept",
                        lineno,
                    )
            except (ValueError, IndexError) as err:
                what = (
                    str(err)
                    if str(err).startswith("expects")
                    else "has a value that is not a number"
                )
                self._fail(
                    IssueCode.LOG_BAD_HEADER_LINE, f"{_decode(tag)} {what}", lineno, line, has_nl
                )
        if version is None:
            self._note(IssueCode.LOG_UNKNOWN_VERSION, "no 'version:' line; read as version 4", None)
            version = 4
        self._version = version
        numbers = sorted(set(poses) | set(confs) | set(poses3) | set(confs_scan) | set(names)) or [
            1
        ]
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
            lasers.append(
                LaserConfig(
                    number=k,
                    pose=Pose2D(px, py, pth),
                    start=a,
                    end=b,
                    count=n,
                    name=names.get(k, ""),
                    z=poses3[k][2] if k in poses3 else None,
                )
            )
        return LogHeader(
            version=version,
            lasers=tuple(lasers),
            location_types=location_types,
            use_encoder_pose=use_encoder,
            comments=tuple(comments),
            extra=tuple(extra),
        )


def _is_laser_no(digits: bytes) -> bool:
    """A laser number in a tag (``scan12:``): 1 to 9 ASCII digits. A longer run is no laser
    number: such a tag is kept as an unknown tag (as text, nothing lost)."""
    return 0 < len(digits) <= 9 and digits.isdigit()


def _laser_tag(tag: bytes, prefix: bytes, suffix: bytes) -> bool:
    return (
        tag.startswith(prefix)
        and tag.endswith(suffix)
        and _is_laser_no(tag[len(prefix) : -len(suffix)])
    )


def _laser_no(tag: bytes) -> int:
    digits = bytes(ch for ch in tag[4:] if 48 <= ch <= 57)
    return int(digits)
