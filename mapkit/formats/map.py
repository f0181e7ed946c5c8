"""ARIA ``.map`` files: a lossless reader (strict and tolerant) and ARIA's canonical writer.

The reader follows ARIA's two-phase parse (FORMATS.md A.3): a keyword parser for the header up
to the first data tag, then a raw reader for ``DATA``/``LINES`` rows. The writer emits exactly the
bytes ARIA's ``ArMap::writeFile`` emits (A.9). Files are handled as bytes; names are ``str``
decoded as UTF-8 with ``surrogateescape``, so every byte survives.

Where ARIA loses data (a last row without newline) mapkit keeps it and reports it; where ARIA
crashes (NaN in an object) mapkit raises :class:`~mapkit.errors.MapFormatError` in strict mode and
reports it in tolerant mode (:func:`recover`).
"""

from __future__ import annotations

import hashlib
import math
import os
import re
import threading
import types
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from mapkit._atomic import atomic_open
from mapkit._typing import PathLike
from mapkit.diagnostics import Issue, IssueCode
from mapkit.errors import MapFormatError
from mapkit.formats._numbers import aria_double, aria_int, c_int
from mapkit.formats._rows import (
    RowReader,
    RowSink,
    column_extremes,
    iter_format_rows,
    ordered_map,
    worker_pool,
)
from mapkit.model import (
    CATEGORIES,
    INFO_KEYWORDS,
    MapData,
    MapObject,
    Provenance,
    Scan,
    ScanHeader,
)

__all__ = [
    "dumpb",
    "dumps",
    "iter_map_chunks",
    "load",
    "loads",
    "parse_map",
    "recover",
    "save",
    "written_category",
]

_WS = " \t\x0b\x0c"
_TOKEN = re.compile(r'"[^\n]*?"(?=[ \t\x0b\x0c]|$)|"[^\n]*|[^ \t\x0b\x0c]+')
_ASCII_LOWER = str.maketrans("ABCDEFGHIJKLMNOPQRSTUVWXYZ", "abcdefghijklmnopqrstuvwxyz")
_CAT_LOWER = {c.lower(): c for c in CATEGORIES}
_INFO_LOWER = {k.lower() + ":": k for k in INFO_KEYWORDS}
_INACTIVE_INFO_LOWER = {"_" + k.lower() + ":": k for k in INFO_KEYWORDS}
_OBJECT_KEYWORDS = {
    "cairn:": "objects",
    "_cairn:": "inactive_objects",
    "childcairn:": "child_objects",
}
_MAX_TOKENS = 511  # ARIA's argument builder keeps 511 arguments per line
_MAX_ARG_BYTES = 9_999  # ... copied from at most 9,999 bytes of argument text
_LINE_BUFFER = 12_000  # header lines are read with fgets() into a 12,000-byte buffer
_MAX_SPAN_MM = 2_000_000


def _decode(b: bytes) -> str:
    return b.decode("utf-8", "surrogateescape")


def _encode(s: str) -> bytes:
    return s.encode("utf-8", "surrogateescape")


def _lower(s: str) -> str:
    """ASCII-only lower case, as C's ``tolower``/``strcasecmp`` in the C locale."""
    return s.translate(_ASCII_LOWER)


def _unquote(tok: str) -> str:
    if len(tok) >= 2 and tok[0] == '"' and tok[-1] == '"':
        return tok[1:-1]
    return tok


def tokenize(text: str) -> list[str]:
    """Split a header line's arguments as ARIA does (FORMATS.md A.6.1).

    A token starting with ``"`` runs to the next ``"`` followed by whitespace or the end of the
    line and keeps its quotes; there is no escape.

    Examples:
        >>> tokenize('GoalType  Name=Goal "Label=A  B"')
        ['GoalType', 'Name=Goal', '"Label=A  B"']
        >>> tokenize('"say "hi" now"')
        ['"say "hi"', 'now"']
    """
    return _TOKEN.findall(text)


def _split_keyword(line: str) -> tuple[str, str]:
    s = line.lstrip(_WS)
    if s.startswith('"'):
        k = s.find('"', 1)
        if k == -1:
            return s[1:], ""
        return s[1:k], s[k + 1 :]
    for i, ch in enumerate(s):
        if ch in _WS:
            return s[:i], s[i:]
    return s, ""


@dataclass
class _ScanState:
    name: str
    prefix: str  # keyword prefix, "" for the default source
    header: dict[str, Any] = field(default_factory=dict)


class _Parser:
    """One parse of one file. Strict mode raises on the first structural error."""

    def __init__(self, data: bytes, source: str, strict: bool) -> None:
        self.data = data
        self.source = source
        self.strict = strict
        self.issues: list[Issue] = []
        self.scans: list[_ScanState] = [_ScanState("", "")]
        self.objects: dict[str, list[MapObject]] = {v: [] for v in _OBJECT_KEYWORDS.values()}
        self.object_lines: dict[str, list[int]] = {v: [] for v in _OBJECT_KEYWORDS.values()}
        self.info: dict[str, list[tuple[str, ...]]] = {}
        self.inactive_info: dict[str, list[tuple[str, ...]]] = {}
        self.info_lines: dict[str, list[int]] = {}
        self.remainder: list[str] = []
        self.remainder_lines: list[int] = []
        self.header_lines: dict[str, int] = {}
        self.origin_lla: tuple[float, float, float] | None = None
        self.category = ""
        self.intro_line = 0
        self.first_data_line = 0
        self.md5: _BackgroundMD5 | None = None
        self.sinks: dict[tuple[int, str], RowSink] = {}
        self.data_end = 0

    # -- reporting ----------------------------------------------------------------------------

    def fail(self, lineno: int | None, message: str, text: str = "") -> None:
        """A structural error: raise in strict mode, record in tolerant mode."""
        if self.strict:
            raise MapFormatError(message, source=self.source, line=lineno, text=text)
        self.note(IssueCode.BAD_HEADER_LINE, lineno, message)

    def note(
        self, code: IssueCode, lineno: int | None, message: str, obj: str | None = None
    ) -> None:
        self.issues.append(Issue.make(code, message, source=self.source, line=lineno, object=obj))

    # -- tags ---------------------------------------------------------------------------------

    def tags(self) -> list[tuple[bytes, int, str]]:
        """(lower-case tag, scan index, "points"|"lines"), longest first for prefix matching."""
        out = []
        for i, s in enumerate(self.scans):
            p = b"" if not s.prefix else _encode(s.prefix) + b"_"
            out.append(((p + b"data").lower(), i, "points"))  # bytes.lower(): ASCII only
            out.append(((p + b"lines").lower(), i, "lines"))
        out.sort(key=lambda t: -len(t[0]))
        return out

    def match_tag(self, line: bytes) -> tuple[int, str] | None:
        low = line[: len(self._tags[0][0])].lower()  # the longest tag comes first
        for tag, idx, kind in self._tags:
            if low.startswith(tag):
                return idx, kind
        return None

    # -- parse --------------------------------------------------------------------------------

    def parse(self) -> MapData:
        data = self.data
        if not data:
            raise MapFormatError("the file is empty", source=self.source, line=None)
        pos = 0
        lineno = 0
        n = len(data)
        # Phase 0: find the intro line.
        while pos < n:
            end = data.find(b"\n", pos)
            end = n if end == -1 else end
            lineno += 1
            raw = data[pos:end]
            pos = end + 1
            text = _decode(raw.replace(b"\r", b""))
            kw, _ = _split_keyword(text)
            low = _lower(kw)
            if low in _CAT_LOWER:
                self.category = _CAT_LOWER[low]
                self.intro_line = lineno
                break
            if low.startswith("2d-map"):
                raise MapFormatError(
                    f"the map category {_short(kw)!r} is newer than mapkit supports "
                    "(up to '2D-Map-Ex4')",
                    source=self.source,
                    line=lineno,
                    text=text,
                )
            if text.strip(_WS):
                self.note(
                    IssueCode.JUNK_BEFORE_INTRO,
                    lineno,
                    f"skipped before the intro line: {text[:60]!r}",
                )
        if not self.category:
            hint = (
                " (it starts with a UTF-8 byte-order mark)"
                if data.startswith(b"\xef\xbb\xbf")
                else ""
            )
            raise MapFormatError(
                f"not an ARIA map: no intro line '2D-Map' ... '2D-Map-Ex4' found{hint}",
                source=self.source,
                line=None,
            )
        self._tags = self.tags()
        # Phase 1: header lines up to the first data tag.
        current: tuple[int, str] | None = None
        while pos < n:
            end = data.find(b"\n", pos)
            end = n if end == -1 else end
            lineno += 1
            raw = data[pos:end]
            pos = end + 1
            if b"\r" in raw:
                stripped = raw.rstrip(b"\r")
                if b"\r" in stripped:
                    self.note(
                        IssueCode.CR_IN_HEADER, lineno, "CR inside the line deleted, as ARIA does"
                    )
                raw = raw.replace(b"\r", b"")
            text = _decode(raw)
            if not text.strip(_WS):
                continue
            kw, rest = _split_keyword(text)
            low = _lower(kw)
            tag = self._header_tag(low)
            if tag is not None:
                current = tag
                self.first_data_line = lineno
                break
            self.header_line(lineno, kw, low, rest, text)
        if current is None:
            if self.strict:
                raise MapFormatError(
                    "no DATA or LINES section: a map must have at least one data tag (even an "
                    "empty DATA)",
                    source=self.source,
                    line=None,
                )
            self.note(
                IssueCode.BAD_HEADER_LINE, None, "no DATA or LINES section (ARIA refuses the file)"
            )
        else:
            self.data_phase(pos, lineno, current)
        return self.build()

    def _header_tag(self, low: str) -> tuple[int, str] | None:
        key = _encode(low)
        for tag, idx, kind in self._tags:
            if key == tag:
                return idx, kind
        return None

    def header_line(self, lineno: int, kw: str, low: str, rest: str, text: str) -> None:
        args = tokenize(rest)
        if len(args) >= _MAX_TOKENS or 4 * len(text) >= _MAX_ARG_BYTES:  # (+1: an unknown keyword)
            self.long_line(lineno, kw, low, args, text)
        if low in _OBJECT_KEYWORDS:
            self.object_line(lineno, kw, _OBJECT_KEYWORDS[low], args, text)
            return
        if low in _INFO_LOWER:
            key = _INFO_LOWER[low]
            self.info.setdefault(key, []).append(tuple(args))
            self.info_lines.setdefault(key, []).append(lineno)
            return
        if low in _INACTIVE_INFO_LOWER:
            key = _INACTIVE_INFO_LOWER[low]
            self.inactive_info.setdefault(key, []).append(tuple(args))
            self.info_lines.setdefault("_" + key, []).append(lineno)
            return
        if low == "sources:":
            self.sources_line(lineno, args, text)
            return
        if low == "originlatlongalt:":
            self.origin_line(lineno, args, text)
            return
        for scan in self.scans:
            if scan.prefix and not low.startswith(_lower(scan.prefix)):
                continue
            key = low[len(scan.prefix) :]
            if key in _SCAN_KEYS:
                self.scan_key(lineno, scan, key, kw, args, text)
                return
        # ARIA splits an unknown line from its first character (after an opening quote) and
        # writes the tokens back joined by single spaces: the keyword is one of them.
        body = text.lstrip(_WS)
        self.remainder.append(" ".join(tokenize(body[1:] if body.startswith('"') else body)))
        self.remainder_lines.append(lineno)
        self.note(IssueCode.UNKNOWN_LINE, lineno, f"unknown keyword {_short(kw)!r} kept")

    def long_line(self, lineno: int, kw: str, low: str, args: list[str], text: str) -> None:
        """Report a header line longer than ARIA reads; mapkit keeps all of it."""
        line_bytes = len(_encode(text))
        body = text.lstrip(_WS)
        known = (
            low in _KNOWN_KEYWORDS
            or self._header_tag(low) is not None
            or any(
                s.prefix and low.startswith(_lower(s.prefix)) and low[len(s.prefix) :] in _SCAN_KEYS
                for s in self.scans
            )
        )
        # ARIA tokenises the arguments of a known keyword, and the whole line of an unknown one.
        value = _encode(_split_keyword(text)[1].lstrip(_WS) if known else body)
        ntok = len(args) + (0 if known else 1)
        why = []
        if line_bytes >= _LINE_BUFFER:
            why.append(
                f"it is {line_bytes:,} bytes long: ARIA reads header lines in pieces of "
                f"{_LINE_BUFFER - 1:,} bytes and reads the rest as further lines"
            )
        if len(value) > _MAX_ARG_BYTES:
            why.append(
                f"its arguments are {len(value):,} bytes: ARIA splits only the first "
                f"{_MAX_ARG_BYTES:,}"
            )
        if ntok > _MAX_TOKENS:
            why.append(f"it has {ntok:,} arguments: ARIA keeps {_MAX_TOKENS}")
        if why:
            self.note(
                IssueCode.TOO_MANY_TOKENS,
                lineno,
                f"{_short(kw)} line: " + "; ".join(why) + " (mapkit keeps the whole line; "
                "ARIA will split or cut it)",
            )

    # -- header keywords -----------------------------------------------------------------------

    def _ints(
        self, lineno: int, kw: str, args: list[str], text: str, exact: int | None
    ) -> list[int] | None:
        want = exact if exact is not None else 1
        if (exact is not None and len(args) != exact) or len(args) < want:
            what = f"exactly {exact}" if exact is not None else "at least 1"
            self.fail(
                lineno,
                f"{kw} expects {what} integer{'s' if want > 1 else ''}, got "
                f"{len(args)} argument{'s' if len(args) != 1 else ''}: "
                f"{_short(' '.join(args))!r}",
                text,
            )
            return None
        vals = []
        for a in args[:want]:
            v = aria_int(a)
            if v is None:
                self.fail(lineno, f"{kw} expects integers, got {_short(a)!r}", text)
                return None
            iv = c_int(v)  # ARIA keeps strtol's long in an int
            if iv != v:
                self.note(
                    IssueCode.NUMBER_OUT_OF_RANGE,
                    lineno,
                    f"{kw} {_short(a)} is beyond 32 bits: read as {iv}, as ARIA reads it",
                )
            vals.append(iv)
        return vals

    def scan_key(
        self, lineno: int, scan: _ScanState, key: str, kw: str, args: list[str], text: str
    ) -> None:
        canon = scan.prefix + _SCAN_KEYS[key]
        if canon in self.header_lines:
            self.note(
                IssueCode.DUPLICATE_HEADER_KEY,
                lineno,
                f"{canon} given again (line {self.header_lines[canon]}); the last one wins",
            )
        value: Any
        if key in ("minpos:", "maxpos:", "lineminpos:", "linemaxpos:"):
            v = self._ints(lineno, canon, args, text, 2)
            if v is None:
                return
            value = (v[0], v[1])
        elif key in ("numpoints:", "numlines:"):
            v = self._ints(lineno, canon, args, text, None)
            if v is None:
                return
            value = v[0]
        elif key == "resolution:":
            v = self._ints(lineno, canon, args, text, 1)
            if v is None:
                return
            value = v[0]
        elif key in ("pointsaresorted:", "linesaresorted:"):
            if not args or _lower(args[0]) not in ("true", "false", "1", "0"):
                self.fail(
                    lineno,
                    f"{canon} expects true, false, 1 or 0, got "
                    f"{_short(args[0]) if args else 'nothing'!r}",
                    text,
                )
                return
            value = _lower(args[0]) in ("true", "1")
        else:  # display:
            if not args:
                self.fail(lineno, f"{canon} expects a label", text)
                return
            value = _unquote(args[0])
        scan.header[key] = value
        self.header_lines[canon] = lineno

    def sources_line(self, lineno: int, args: list[str], text: str) -> None:
        if not args:
            self.fail(lineno, "Sources: expects at least one source name", text)
            return
        names = [_unquote(a) for a in args]
        lowered = [_lower(x) for x in names]
        if any(not x for x in names) or len(set(lowered)) != len(lowered):
            self.note(
                IssueCode.BAD_SOURCES_LINE,
                lineno,
                "Sources: has empty or duplicate names; ARIA ignores the line",
            )
            return
        defaults = [i for i, x in enumerate(lowered) if x == "sicklaser"]
        if len(self.scans) != 1 or self.scans[0].header or self.header_lines:
            # Keywords seen so far belong to the default source: keep that state.
            pass
        old_default = self.scans[0]
        new: list[_ScanState] = []
        for i, name in enumerate(names):
            if defaults and i == defaults[0]:
                st = _ScanState(name, "")
                st.header = old_default.header
            else:
                st = _ScanState(name, name)
            new.append(st)
        self.scans = new
        self._tags = self.tags()
        self.header_lines["Sources:"] = lineno

    def origin_line(self, lineno: int, args: list[str], text: str) -> None:
        if not args:
            self.origin_lla = None
            return
        vals = [aria_double(a) for a in args[:3]]
        if len(args) < 3 or None in vals:
            self.fail(
                lineno,
                f"OriginLatLongAlt: expects 3 numbers (latitude longitude altitude), "
                f"got {_short(' '.join(args))!r}",
                text,
            )
            return
        lat, lon, alt = (float(v) for v in vals if v is not None)
        self.origin_lla = (lat, lon, alt)
        self.header_lines["OriginLatLongAlt:"] = lineno

    def object_line(self, lineno: int, kw: str, where: str, args: list[str], text: str) -> None:
        label = {
            "objects": "Cairn:",
            "inactive_objects": "_Cairn:",
            "child_objects": "ChildCairn:",
        }[where]
        if len(args) < 7:
            self.fail(
                lineno,
                f"{label} expects at least 7 fields (Type X Y Theta Desc Icon Name), got "
                f"{len(args)}",
                text,
            )
            return
        tokens = [args[1], args[2], args[3], *(args[7:11] if len(args) >= 11 else [])]
        values = []
        for tok in tokens:
            v = aria_double(tok)  # strtod: hex, inf and overflow read as ARIA reads them
            if v is None:
                self.fail(lineno, f"{label} expects a number, got {_short(tok)!r}", text)
                return
            values.append(v)
        x, y, th = values[:3]
        ft = (values[3], values[4], values[5], values[6]) if len(values) == 7 else None
        if any(math.isnan(v) for v in values):  # infinities are kept, as ARIA keeps them
            message = (
                f"{label} {_short(_unquote(args[6]))!r} has a NaN coordinate or heading "
                "(ARIA crashes on it)"
            )
            if self.strict:
                raise MapFormatError(message, source=self.source, line=lineno, text=text)
            self.note(
                IssueCode.NON_FINITE_NUMBER,
                lineno,
                message + "; object left out",
                _unquote(args[6]),
            )
            return
        desc = _unquote(args[4])
        if len(args) >= 11:
            if len(args) >= 12:
                desc = _unquote(args[11])
            if len(args) > 12:
                self.note(
                    IssueCode.LOSSY_OBJECT_LINE,
                    lineno,
                    f"{len(args) - 12} extra field(s) after the description dropped, as ARIA does",
                    _unquote(args[6]),
                )
        elif len(args) > 7:
            desc = _unquote(args[7])
            if len(args) > 8:
                self.note(
                    IssueCode.LOSSY_OBJECT_LINE,
                    lineno,
                    f"{len(args)} fields: not a line or rectangle (needs 4 corner numbers); "
                    "ARIA drops fields 9-10",
                    _unquote(args[6]),
                )
        name = _unquote(args[6])
        if name.count('"') or desc.count('"'):
            self.note(
                IssueCode.LOSSY_QUOTE,
                lineno,
                "a quote inside a quoted field: ARIA splits the "
                "field there; rewriting loses the original spelling",
                name,
            )
        obj = MapObject(args[0], x, y, th, name=name, description=desc, icon=args[5], from_to=ft)
        self.objects[where].append(obj)
        self.object_lines[where].append(lineno)

    # -- data phase ---------------------------------------------------------------------------

    def data_phase(self, pos: int, lineno: int, current: tuple[int, str]) -> None:
        data = self.data
        n = len(data)
        if n >= _BACKGROUND_MD5_BYTES:
            self.md5 = _BackgroundMD5(data)  # hashes on the other core while the rows are read
        end = n
        late_note = None
        if n > pos and not data.endswith(b"\n"):
            end = max(pos, data.rfind(b"\n", pos, n) + 1)
            if data[end : end + 1].isdigit() or data[end : end + 1] == b"-":
                late_note = len(self.issues)
        # The section is read in chunks cut at LF. A chunk of canonical rows (what ARIA writes) is
        # parsed in one vectorised step; any other chunk (a tag, a blank line, a row ARIA skips)
        # goes line by line through data_lines(). Rows go straight into one array per section.
        # Big sections are parsed by worker threads (numpy releases the GIL) and taken in order.
        reader = RowReader(data)
        self.data_end = end
        line = lineno + 1  # number of the line starting at s
        spans = _spans(data, pos, end, _DATA_CHUNK)
        with worker_pool(len(spans) >= _PARALLEL_SPANS) as pool:
            if pool is not None:
                parsed = ordered_map(pool, lambda span: _parse_span(reader, span), spans)
                for (s, e), got in zip(spans, parsed, strict=True):
                    k = 2 if current[1] == "points" else 4
                    if got is not None and got[0].shape[1] == k:
                        self.sink(current, end - s).append(*got)
                        line += len(got[0])
                    else:
                        current, line = self.data_lines(reader, s, e, current, line)
            else:
                for s, e in spans:
                    k = 2 if current[1] == "points" else 4
                    nrows = reader.fast_into(self.sink(current, end - s), s, e, k)
                    if nrows is not None:
                        line += nrows
                    else:
                        current, line = self.data_lines(reader, s, e, current, line)
        if end < n:  # the last line has no newline: read it with one added (ARIA drops it)
            if late_note is not None:
                issue = Issue.make(
                    IssueCode.LAST_ROW_WITHOUT_NEWLINE,
                    "the last data row has no newline: ARIA drops it, mapkit keeps it",
                    source=self.source,
                    line=line,
                )
                self.issues.insert(late_note, issue)
            tail = b"\n" * 8 + data[end:] + b"\n"
            self.data_lines(RowReader(tail), 8, len(tail), current, line)

    def data_lines(
        self, reader: RowReader, start: int, end: int, current: tuple[int, str], line: int
    ) -> tuple[tuple[int, str], int]:
        """Rows, tags and skipped lines of ``data[start:end]``; the section and the next line."""
        data = reader.data
        # Lines that do not start with a digit or '-': tags, blank lines and rows ARIA skips.
        seg_start = start
        seg_line = line
        for m in _NONNUMERIC_LINE.finditer(data, start, end):
            s = m.start()
            if s >= end:  # the empty "line" after the chunk's last LF
                break
            if s > seg_start:
                self.rows(reader, seg_start, s, current, seg_line)
            line_no = seg_line + data.count(b"\n", seg_start, s)
            raw = m.group()
            tag = self.match_tag(raw)
            if tag is not None:
                current = tag
            elif raw.strip(b" \t\r\x0b\x0c"):
                first = raw.split(None, 1)[0] if raw.split() else b""
                if first.endswith(b":") and not raw[:1].isspace():
                    self.note(
                        IssueCode.HEADER_LINE_AFTER_DATA,
                        line_no,
                        f"{_short(_decode(first))} after the first data tag: "
                        "ARIA ignores it "
                        "(header lines must come before DATA/LINES)",
                    )
                else:
                    self.note(
                        IssueCode.BAD_DATA_ROW,
                        line_no,
                        f"data row {_decode(raw[:40])!r} is skipped (ARIA skips it silently)",
                    )
            seg_start = m.end() + 1
            seg_line = line_no + 1
        if seg_start < end:
            seg_line += self.rows(reader, seg_start, end, current, seg_line)
        return current, seg_line

    def sink(self, current: tuple[int, str], left: int = 0) -> RowSink:
        """The growing array of the current section's rows (sized by the header's count)."""
        got = self.sinks.get(current)
        if got is None:
            idx, kind = current
            ncols = 2 if kind == "points" else 4
            count = self.scans[idx].header.get("numpoints:" if kind == "points" else "numlines:")
            expected = count if isinstance(count, int) and 0 < count <= left // (2 * ncols) else 0
            got = self.sinks[current] = RowSink(ncols, expected)
        return got

    def rows(
        self, reader: RowReader, start: int, end: int, current: tuple[int, str], first_line: int
    ) -> int:
        """Parse the rows of ``data[start:end]`` into the current section; returns the row count."""
        kind = current[1]
        sink = self.sink(current, max(end, self.data_end) - start)
        bad, nrows = reader.parse(start, end, 2 if kind == "points" else 4, sink)
        for b in bad:
            self.note(
                IssueCode.BAD_DATA_ROW,
                first_line + b,
                f"{'DATA' if kind == 'points' else 'LINES'} row skipped (ARIA skips it silently)",
            )
        return nrows

    # -- build the model ----------------------------------------------------------------------

    def build(self) -> MapData:
        scans = []
        too_wide = False
        built: list[tuple[int, _ScanState, np.ndarray[Any, Any], np.ndarray[Any, Any]]] = []
        for i, st in enumerate(self.scans):
            pts = self.sink((i, "points")).result()
            lns = self.sink((i, "lines")).result()
            pts.flags.writeable = lns.flags.writeable = False  # private arrays: Scan need not copy
            built.append((i, st, pts, lns))
        for i, st, pts, lns in built:
            h = st.header
            header = ScanHeader(
                min_pos=h.get("minpos:"),
                max_pos=h.get("maxpos:"),
                num_points=h.get("numpoints:"),
                points_sorted=h.get("pointsaresorted:"),
                resolution=h.get("resolution:"),
                line_min_pos=h.get("lineminpos:"),
                line_max_pos=h.get("linemaxpos:"),
                num_lines=h.get("numlines:"),
                lines_sorted=h.get("linesaresorted:"),
                display=h.get("display:"),
            )
            pmin, pmax = _aria_box(
                pts.reshape(-1, 2),
                header.min_pos,
                header.max_pos,
                header.num_points,
                self.sink((i, "points")).box(),
            )
            lmin, lmax = _aria_box(
                lns.reshape(-1, 2),
                header.line_min_pos,
                header.line_max_pos,
                header.num_lines,
                self.sink((i, "lines")).box(),
            )
            scan = Scan(
                name=st.name,
                display=header.display if header.display is not None else st.name,
                points=pts,
                lines=lns,
                resolution=0 if header.resolution is None else header.resolution,
                points_sorted=bool(header.points_sorted),
                lines_sorted=bool(header.lines_sorted),
                min_pos=pmin,
                max_pos=pmax,
                line_min_pos=lmin,
                line_max_pos=lmax,
                header=header,
            )
            corners = [c for c in (pmin, pmax, lmin, lmax) if c is not None]
            if corners:
                span = np.ptp(np.array(corners), axis=0)
                too_wide = too_wide or bool(np.any(span > _MAX_SPAN_MM))
            scans.append(scan)
        if too_wide:
            scans = self.recompute_wide(scans)
        md5 = self.md5.hexdigest() if self.md5 is not None else hashlib.md5(self.data).hexdigest()
        prov = Provenance(
            source=self.source,
            md5=md5,
            size=len(self.data),
            object_lines=tuple(self.object_lines["objects"]),
            inactive_object_lines=tuple(self.object_lines["inactive_objects"]),
            child_object_lines=tuple(self.object_lines["child_objects"]),
            info_lines=types.MappingProxyType({k: tuple(v) for k, v in self.info_lines.items()}),
            remainder_lines=tuple(self.remainder_lines),
            header_lines=types.MappingProxyType(dict(self.header_lines)),
            intro_line=self.intro_line,
            first_data_line=self.first_data_line,
        )
        return MapData(
            category=self.category,
            scans=tuple(scans),
            objects=tuple(self.objects["objects"]),
            inactive_objects=tuple(self.objects["inactive_objects"]),
            child_objects=tuple(self.objects["child_objects"]),
            info={k: tuple(v) for k, v in self.info.items()},
            inactive_info={k: tuple(v) for k, v in self.inactive_info.items()},
            origin_lla=self.origin_lla,
            remainder=tuple(self.remainder),
            provenance=prov,
        )

    def recompute_wide(self, scans: list[Scan]) -> list[Scan]:
        """ARIA 2.9.4's 2 km rule: recompute the boxes from the rows and sort them."""
        out = [s.with_data(sort=True) for s in scans]
        self.note(
            IssueCode.BOX_RECOMPUTED,
            None,
            "the header's bounding box spans more than 2 km: boxes recomputed from the data and "
            "the data sorted, as ARIA 2.9.4 does",
        )
        for s in out:
            b = s.data_bounds()
            if b is not None and (
                b[1][0] - b[0][0] > _MAX_SPAN_MM or b[1][1] - b[0][1] > _MAX_SPAN_MM
            ):
                self.note(
                    IssueCode.BOX_RECOMPUTED,
                    None,
                    "the data itself spans more than 2 km: ARIA 2.9.4 refuses this map "
                    "(ARIA 2.9.1 and mapkit load it)",
                )
                break
        return out


_SCAN_KEYS = {
    "minpos:": "MinPos:",
    "maxpos:": "MaxPos:",
    "numpoints:": "NumPoints:",
    "pointsaresorted:": "PointsAreSorted:",
    "resolution:": "Resolution:",
    "lineminpos:": "LineMinPos:",
    "linemaxpos:": "LineMaxPos:",
    "numlines:": "NumLines:",
    "linesaresorted:": "LinesAreSorted:",
    "display:": "Display:",
}

_KNOWN_KEYWORDS = {
    *_OBJECT_KEYWORDS,
    *_INFO_LOWER,
    *_INACTIVE_INFO_LOWER,
    *_SCAN_KEYS,
    "sources:",
    "originlatlongalt:",
}


def _short(text: str, limit: int = 60) -> str:
    """Text for a message, cut to ``limit`` characters (a hostile line can be megabytes)."""
    return text if len(text) <= limit else text[:limit] + f"... ({len(text):,} characters)"


_NONNUMERIC_LINE = re.compile(rb"^(?![0-9-]).*$", re.M)
_BACKGROUND_MD5_BYTES = 1 << 20


class _BackgroundMD5:
    """MD5 of a buffer computed by a thread (hashlib releases the GIL on large buffers)."""

    def __init__(self, data: bytes) -> None:
        self._hash = hashlib.md5()
        self._thread = threading.Thread(target=self._hash.update, args=(data,), daemon=True)
        self._thread.start()

    def hexdigest(self) -> str:
        self._thread.join()
        return self._hash.hexdigest()


_DATA_CHUNK = 1 << 17  # bytes of the data section per vectorised step
_PARALLEL_SPANS = 16  # chunks from which worker threads parse the data section
_PARALLEL_ROWS = 100_000  # rows from which worker threads format a map


def _parse_span(
    reader: RowReader, span: tuple[int, int]
) -> tuple[np.ndarray[Any, Any], tuple[np.ndarray[Any, Any], np.ndarray[Any, Any]]] | None:
    """A worker thread's job: the rows of a canonical chunk and their extremes (or ``None``)."""
    values = reader.fast(*span)
    if values is None or len(values) == 0:
        return None
    return values, column_extremes(values)


def _spans(data: bytes, start: int, end: int, size: int) -> list[tuple[int, int]]:
    """``data[start:end]`` cut into pieces of about ``size`` bytes that end with LF."""
    out = []
    s = start
    while s < end:
        e = end
        if end - s > size:
            cut = data.rfind(b"\n", s, s + size)
            e = data.find(b"\n", s + size, end) + 1 if cut < 0 else cut + 1
            e = e or end
        out.append((s, e))
        s = e
    return out


def _aria_box(
    xy: np.ndarray[Any, Any],
    hmin: tuple[int, int] | None,
    hmax: tuple[int, int] | None,
    count: int | None,
    data_box: tuple[tuple[int, int], tuple[int, int]] | None = None,
) -> tuple[tuple[int, int] | None, tuple[int, int] | None]:
    """ARIA's box: the header box (or the origin) widened by the data; empty if ``NumX: 0``.

    ``data_box`` is the data's own box when already known (``None``: computed here).
    """
    if len(xy) == 0:
        return None, None  # nothing to bound; the writer writes no box then
    lo, hi = data_box or _column_bounds(xy)
    if count is not None and count <= 0:
        return lo, hi
    lo0 = hmin if hmin is not None else (0, 0)
    hi0 = hmax if hmax is not None else (0, 0)
    return (min(lo0[0], lo[0]), min(lo0[1], lo[1])), (max(hi0[0], hi[0]), max(hi0[1], hi[1]))


def _column_bounds(xy: np.ndarray[Any, Any]) -> tuple[tuple[int, int], tuple[int, int]]:
    # Column by column: numpy's min(axis=0) over an (N, 2) array is ten times slower.
    x, y = xy[:, 0], xy[:, 1]
    return (int(x.min()), int(y.min())), (int(x.max()), int(y.max()))


# -- public reading API ----------------------------------------------------------------------


def _as_bytes(data: str | bytes) -> bytes:
    return _encode(data) if isinstance(data, str) else bytes(data)


def parse_map(data: str | bytes, *, source: str = "<string>") -> MapData:
    """Parse map text strictly: the first structural error raises.

    Args:
        data: The file's bytes (or text).
        source: File name for error messages.

    Returns:
        The map.

    Raises:
        MapFormatError: Naming the source, the line and what was expected.
    """
    return _Parser(_as_bytes(data), source, strict=True).parse()


def loads(data: str | bytes, *, source: str = "<string>") -> MapData:
    """Parse a map from text or bytes (strict).

    Args:
        data: Map text or bytes.
        source: Name used in error messages.

    Returns:
        The map.

    Raises:
        MapFormatError: When the text is not a map ARIA would load.

    Examples:
        >>> m = loads("2D-Map\\nDATA\\n1 2\\n")
        >>> m.points.tolist(), m.md5
        ([[1, 2]], '688ea5a151f70b05bdfb3e892a0574ec')
    """
    return parse_map(data, source=source)


def load(path: PathLike) -> MapData:
    """Read a ``.map`` file (strict).

    Args:
        path: The file.

    Returns:
        The map, with its provenance (file name, MD5, line numbers).

    Raises:
        MapFormatError: When the file is not a map ARIA would load.
        OSError: When the file cannot be read.
    """
    with open(path, "rb") as fh:
        data = fh.read()
    return parse_map(data, source=os.fspath(path))


def recover(data: PathLike | bytes, *, source: str | None = None) -> tuple[MapData, list[Issue]]:
    """Read a map tolerantly: load what ARIA would load and list every problem met.

    Lines ARIA would reject are skipped and reported; data ARIA would lose is kept and reported.
    Only a file with no intro line at all (or an empty one) still raises.

    Args:
        data: A path, or the file's bytes.
        source: Name for the issues (defaults to the path).

    Returns:
        ``(map, issues)``.

    Raises:
        MapFormatError: When there is nothing to load.
        OSError: When the file cannot be read.

    Examples:
        >>> m, issues = recover(b"2D-Map\\nNumPoints: x\\nDATA\\n1 1\\n2 2")
        >>> m.points.tolist(), [int(i.code) for i in issues]
        ([[1, 1], [2, 2]], [110, 104])
    """
    if isinstance(data, (bytes, bytearray, memoryview)):
        raw, name = bytes(data), source or "<bytes>"
    else:
        with open(data, "rb") as fh:
            raw = fh.read()
        name = source or os.fspath(data)
    p = _Parser(raw, name, strict=False)
    m = p.parse()
    return m, p.issues


# -- writer ----------------------------------------------------------------------------------


def written_category(m: MapData) -> str:
    """The intro line ARIA writes for this map (FORMATS.md A.2).

    Upgraded to ``2D-Map-Ex4`` when the map uses templates; ``2D-Map-Ex`` with only the default
    source is written as ``2D-Map``; never downgraded otherwise.
    """
    cat = m.category
    if _uses_templates(m):
        return "2D-Map-Ex4"
    if cat == "2D-Map-Ex" and len(m.scans) == 1 and m.scans[0].is_default:
        return "2D-Map"
    return cat


def _uses_templates(m: MapData) -> bool:
    if m.info.get("MacroInfo"):
        return True
    for line in m.info.get("MapInfo", ()):
        if line and line[0] == "CairnGroupType":
            return True
    for line in m.info.get("RouteInfo", ()):
        if line and line[0] == "MacroTemplate":
            return True
    for line in m.info.get("MetaInfo", ()):
        if line and line[0] == "Feature" and any(_unquote(t) == "Name=templates" for t in line[1:]):
            return True
    return False


def _printf(spec: str, v: float) -> str:
    """C's printf of one double: as Python's %, but a NaN with its sign bit set is ``-nan``."""
    text = spec % v
    return "-" + text if math.isnan(v) and math.copysign(1.0, v) < 0 else text


def _f0(v: float) -> str:
    return _printf("%.0f", v)


def _object_line(keyword: str, o: MapObject) -> str:
    th = _printf("%f", o.theta)
    s = f'{keyword} {o.type} {_f0(o.x)} {_f0(o.y)} {th} "{o.description}" {o.icon} "{o.name}"'
    if o.from_to is not None:
        s += " " + " ".join(_f0(v) for v in o.from_to)
    return s


def _pair(p: tuple[int, int] | None) -> str:
    p = p or (0, 0)
    return f"{p[0]} {p[1]}"


def _scan_prefix(scan: Scan) -> str:
    return "" if scan.is_default else scan.name


def iter_header_lines(m: MapData) -> Iterator[str]:
    """The header lines ARIA writes, in its order (without newlines)."""
    yield written_category(m)
    if m.scans[0].name:
        yield "Sources: " + " ".join(s.name for s in m.scans)
    for s in m.scans:
        p = _scan_prefix(s)
        if s.display:
            yield f'{p}Display: "{s.display}"'
        if s.num_points:
            yield f"{p}MinPos: {_pair(s.min_pos)}"
            yield f"{p}MaxPos: {_pair(s.max_pos)}"
            yield f"{p}NumPoints: {s.num_points}"
            yield f"{p}PointsAreSorted: {'true' if s.points_sorted else 'false'}"
        if s.resolution != -1:
            yield f"{p}Resolution: {s.resolution}"
        if s.num_lines:
            yield f"{p}LineMinPos: {_pair(s.line_min_pos)}"
            yield f"{p}LineMaxPos: {_pair(s.line_max_pos)}"
            yield f"{p}NumLines: {s.num_lines}"
            yield f"{p}LinesAreSorted: {'true' if s.lines_sorted else 'false'}"
    if m.origin_lla is not None:
        lat, lon, alt = m.origin_lla
        yield "OriginLatLongAlt: " + " ".join(_printf("%f", v) for v in (lat, lon, alt))
    for key in INFO_KEYWORDS:
        for line in m.info.get(key, ()):
            yield f"{key}: " + " ".join(line)
    for o in m.objects:
        yield _object_line("Cairn:", o)
    for key in INFO_KEYWORDS:
        for line in m.inactive_info.get(key, ()):
            yield f"_{key}: " + " ".join(line)
    for o in m.inactive_objects:
        yield _object_line("_Cairn:", o)
    for o in m.child_objects:
        yield _object_line("ChildCairn:", o)
    yield from m.remainder


def iter_map_chunks(m: MapData) -> Iterator[bytes]:
    """The canonical file as byte chunks (header, then each data section).

    For a big map, worker threads format the rows ahead of the consumer (numpy releases the GIL),
    so that writing and hashing the chunks overlap with formatting the next ones.
    """
    with worker_pool(sum(s.num_points + s.num_lines for s in m.scans) >= _PARALLEL_ROWS) as pool:
        yield from _map_chunks(m, pool)


def _map_chunks(m: MapData, pool: ThreadPoolExecutor | None) -> Iterator[bytes]:
    yield _encode("".join(line + "\n" for line in iter_header_lines(m)))
    for s in m.scans:
        if s.num_lines:
            yield _encode(_scan_prefix(s) + "_LINES\n" if _scan_prefix(s) else "LINES\n")
            yield from iter_format_rows(s.lines, pool)
    for s in m.scans:
        yield _encode(_scan_prefix(s) + "_DATA\n" if _scan_prefix(s) else "DATA\n")
        yield from iter_format_rows(s.points, pool)


def dumpb(m: MapData) -> bytes:
    """The map as ARIA's writer emits it, as bytes.

    Examples:
        >>> dumpb(MapData())
        b'2D-Map\\nResolution: 0\\nDATA\\n'
    """
    return b"".join(iter_map_chunks(m))


def dumps(m: MapData) -> str:
    """The map as ARIA's writer emits it, as text (undecodable bytes as surrogates)."""
    return _decode(dumpb(m))


def save(m: MapData, path: PathLike, *, backup: bool = False) -> str:
    """Write a map atomically (temp file beside it, fsync, rename) in ARIA's canonical form.

    Args:
        m: The map.
        path: Destination file.
        backup: Keep the previous file as ``path.bak``.

    Returns:
        The MD5 (hex) of the bytes written: ARIA's checksum of the new file.

    Raises:
        OSError: When the file cannot be written; any previous file is then unchanged.
    """
    md5 = hashlib.md5()
    with atomic_open(path, backup=backup) as fh:
        for chunk in iter_map_chunks(m):
            md5.update(chunk)
            fh.write(chunk)
    return md5.hexdigest()
