"""The header parser: ARIA's keyword parse up to the first data tag, strict or tolerant, then the
rows of each scan."""

from __future__ import annotations

import hashlib
import math
import types
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from mapkit.diagnostics import Issue, IssueCode
from mapkit.errors import MapFormatError
from mapkit.formats._numbers import aria_double, aria_int, c_int
from mapkit.formats._rows import (
    RowReader,
    RowSink,
    ordered_map,
    worker_pool,
)
from mapkit.formats.map.data import (
    _BACKGROUND_MD5_BYTES,
    _KNOWN_KEYWORDS,
    _NONNUMERIC_LINE,
    _SCAN_KEYS,
    _aria_box,
    _BackgroundMD5,
    _parse_span,
    _short,
    _spans,
)
from mapkit.formats.map.tokens import (
    _CAT_LOWER,
    _INACTIVE_INFO_LOWER,
    _INFO_LOWER,
    _LINE_BUFFER,
    _MAX_ARG_BYTES,
    _MAX_SPAN_MM,
    _MAX_TOKENS,
    _OBJECT_KEYWORDS,
    _WS,
    _decode,
    _encode,
    _lower,
    _split_keyword,
    _unquote,
    tokenize,
)
from mapkit.model import (
    MapData,
    MapObject,
    Provenance,
    Scan,
    ScanHeader,
)

_DATA_CHUNK = 1 << 17  # bytes of the data section per vectorised step
_PARALLEL_SPANS = 16  # chunks from which worker threads parse the data section


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
