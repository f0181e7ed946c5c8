"""Findings about a map: :class:`Issue` values with stable :class:`IssueCode` numbers.

The parser's tolerant mode (:func:`mapkit.recover`) and the validator both report
:class:`Issue` values. Codes are numbered in ranges and never renumbered:

* 1xx syntax (what the reader met in the file),
* 2xx header consistency,
* 3xx geometry,
* 4xx objects,
* 5xx navigation,
* 6xx info sections,
* 7xx ``.2d`` laser logs (reader and map builder).

The table of every code is generated from :class:`IssueCode` (``docs/codes.md``).
"""

from __future__ import annotations

import enum
from dataclasses import dataclass, field
from typing import Any

__all__ = ["Issue", "IssueCode", "Location", "Report", "Severity"]


class Severity(str, enum.Enum):
    """How bad a finding is."""

    ERROR = "error"
    WARNING = "warning"
    INFO = "info"

    @property
    def rank(self) -> int:
        """0 for errors, 1 for warnings, 2 for info (sort key)."""
        return {"error": 0, "warning": 1, "info": 2}[self.value]


class IssueCode(enum.IntEnum):
    """Stable numbers for every kind of finding. Never renumber; only add.

    Each member's docstring-like summary lives in :data:`CODE_SUMMARY`.
    """

    # 1xx: syntax (reader)
    JUNK_BEFORE_INTRO = 101
    UNKNOWN_LINE = 102
    BAD_DATA_ROW = 103
    LAST_ROW_WITHOUT_NEWLINE = 104
    HEADER_LINE_AFTER_DATA = 105
    LOSSY_OBJECT_LINE = 106
    NON_FINITE_NUMBER = 107
    DUPLICATE_HEADER_KEY = 108
    CR_IN_HEADER = 109
    BAD_HEADER_LINE = 110
    BAD_SOURCES_LINE = 111
    TOO_MANY_TOKENS = 112
    BOX_RECOMPUTED = 113
    LOSSY_QUOTE = 114
    NUMBER_OUT_OF_RANGE = 115

    # 2xx: header consistency (validator)
    NUM_POINTS_MISMATCH = 201
    NUM_LINES_MISMATCH = 202
    BOX_EXCLUDES_DATA = 203
    BOX_LARGER_THAN_DATA = 204
    BOX_MISSING = 205
    RESOLUTION_MISSING = 206
    RESOLUTION_IMPLAUSIBLE = 207
    NOT_MARKED_SORTED = 208
    SORTED_FLAG_WRONG = 209
    CATEGORY_OLDER_THAN_CONTENT = 210
    TEMPLATES_NEED_EX4 = 211
    CATEGORY_NEWER_THAN_ARIA_291 = 212
    COUNT_NOT_POSITIVE = 213
    MISSPELT_KEYWORD = 214

    # 3xx: geometry (validator)
    EMPTY_MAP = 301
    ZERO_LENGTH_LINES = 302
    POINTS_OFF_GRID = 303
    COORDINATE_OVERFLOW = 304

    # 4xx: objects (validator)
    DUPLICATE_NAME = 401
    EMPTY_NAME = 402
    UNDECLARED_TYPE = 403
    TYPE_NOT_LISTED = 404
    NON_FINITE_OBJECT = 405
    HEADING_NOT_NORMALISED = 406
    DEGENERATE_FORBIDDEN = 407
    OBJECT_OUTSIDE_MAP = 408
    GOAL_IN_WALL = 409
    GOAL_NEAR_WALL = 410
    GOAL_IN_FORBIDDEN_AREA = 411
    NO_ROBOT_HOME = 412
    SEVERAL_ROBOT_HOMES = 413
    UNWRITABLE_TEXT = 414
    WRONG_SHAPE_FOR_TYPE = 415
    INFINITE_OBJECT = 416

    # 5xx: navigation (validator)
    UNREACHABLE = 501
    NARROW_PASSAGE = 502
    NAVIGATION_SKIPPED = 503

    # 6xx: info sections (validator)
    TYPE_WITHOUT_NAME = 601
    TYPE_DECLARED_TWICE = 602
    ARGDESC_PARENT_MISMATCH = 603
    ARGDESC_BAD_TYPE = 604
    ARGDESC_BAD_VALUE = 605
    PARAMS_UNKNOWN_OBJECT = 606
    PARAMS_COUNT_MISMATCH = 607
    PARAMS_BAD_VALUE = 608
    GROUP_MEMBER_MISMATCH = 609

    # 7xx: .2d laser logs
    LOG_BAD_HEADER_LINE = 701
    LOG_BAD_VALUE = 702
    LOG_NON_FINITE = 703
    LOG_WRONG_READING_COUNT = 704
    LOG_INCOMPLETE_RECORD = 705
    LOG_TRUNCATED = 706
    LOG_UNKNOWN_TAG = 707
    LOG_GARBAGE_LINE = 708
    LOG_NO_END_MARK = 709
    LOG_UNKNOWN_LASER = 710
    LOG_UNKNOWN_VERSION = 711
    LOG_UNPAIRED_LOOP = 712


#: One line per code: (default severity, summary). Extended by the validator's ranges.
CODE_SUMMARY: dict[IssueCode, tuple[Severity, str]] = {
    IssueCode.JUNK_BEFORE_INTRO: (
        Severity.WARNING,
        "lines before the intro line (ARIA skips them)",
    ),
    IssueCode.UNKNOWN_LINE: (
        Severity.INFO,
        "unknown header keyword, kept and written after the objects",
    ),
    IssueCode.BAD_DATA_ROW: (Severity.WARNING, "data row ARIA skips silently"),
    IssueCode.LAST_ROW_WITHOUT_NEWLINE: (
        Severity.WARNING,
        "last data row has no newline: ARIA drops it, mapkit keeps it",
    ),
    IssueCode.HEADER_LINE_AFTER_DATA: (
        Severity.WARNING,
        "header line after the first data tag: ARIA ignores it",
    ),
    IssueCode.LOSSY_OBJECT_LINE: (Severity.WARNING, "object line with tokens ARIA drops"),
    IssueCode.NON_FINITE_NUMBER: (Severity.ERROR, "NaN or infinite number"),
    IssueCode.DUPLICATE_HEADER_KEY: (Severity.WARNING, "header key given twice; the last one wins"),
    IssueCode.CR_IN_HEADER: (Severity.INFO, "CR inside a header line (ARIA deletes it)"),
    IssueCode.BAD_HEADER_LINE: (Severity.ERROR, "header line ARIA rejects (the load fails)"),
    IssueCode.BAD_SOURCES_LINE: (Severity.WARNING, "Sources: line with duplicate or empty names"),
    IssueCode.TOO_MANY_TOKENS: (
        Severity.WARNING,
        "header line longer than ARIA reads (12,000-byte line, 9,999 bytes or 511 arguments): "
        "mapkit keeps it whole, ARIA splits or cuts it",
    ),
    IssueCode.BOX_RECOMPUTED: (
        Severity.WARNING,
        "bounding box wider than 2 km: ARIA 2.9.4 recomputes it and sorts the data",
    ),
    IssueCode.LOSSY_QUOTE: (
        Severity.WARNING,
        "a quote inside a quoted token: ARIA splits it there",
    ),
    IssueCode.NUMBER_OUT_OF_RANGE: (
        Severity.WARNING,
        "header integer beyond 32 bits: read as ARIA reads it (strtol saturates, the int wraps)",
    ),
    # 2xx
    IssueCode.NUM_POINTS_MISMATCH: (
        Severity.WARNING,
        "NumPoints: differs from the DATA rows (ARIA's ArMap recounts; ArMapSimple trusts it)",
    ),
    IssueCode.NUM_LINES_MISMATCH: (Severity.WARNING, "NumLines: differs from the LINES rows"),
    IssueCode.BOX_EXCLUDES_DATA: (
        Severity.WARNING,
        "MinPos/MaxPos or LineMinPos/LineMaxPos do not enclose the data",
    ),
    IssueCode.BOX_LARGER_THAN_DATA: (
        Severity.INFO,
        "bounding box larger than the data it describes",
    ),
    IssueCode.BOX_MISSING: (
        Severity.INFO,
        "data without its bounding-box keywords: ARIA's box then includes (0, 0)",
    ),
    IssueCode.RESOLUTION_MISSING: (Severity.WARNING, "points but no Resolution: (ARIA assumes 0)"),
    IssueCode.RESOLUTION_IMPLAUSIBLE: (
        Severity.WARNING,
        "Resolution: not a plausible grid size for the points (1 to 1000 mm)",
    ),
    IssueCode.NOT_MARKED_SORTED: (
        Severity.INFO,
        "PointsAreSorted:/LinesAreSorted: false or absent",
    ),
    IssueCode.SORTED_FLAG_WRONG: (Severity.WARNING, "sorted flag true but the rows are not sorted"),
    IssueCode.CATEGORY_OLDER_THAN_CONTENT: (
        Severity.INFO,
        "2D-Map-Ex2/Ex3 content under an older intro: read by ARIA, intro changed by ARIA 2.9.1 "
        "on save",
    ),
    IssueCode.TEMPLATES_NEED_EX4: (
        Severity.WARNING,
        "template content (2D-Map-Ex4) under an older intro: ARIA 2.9.1 and older ignore it",
    ),
    IssueCode.CATEGORY_NEWER_THAN_ARIA_291: (
        Severity.WARNING,
        "intro newer than ARIA 2.9.1 reads (2D-Map-Ex4): older robots refuse the file",
    ),
    IssueCode.COUNT_NOT_POSITIVE: (
        Severity.WARNING,
        "NumPoints:/NumLines: 0 or negative: AriaCoda refuses the file",
    ),
    IssueCode.MISSPELT_KEYWORD: (
        Severity.WARNING,
        "unknown header keyword that looks like a misspelt ARIA keyword",
    ),
    # 3xx
    IssueCode.EMPTY_MAP: (Severity.WARNING, "no points and no lines"),
    IssueCode.ZERO_LENGTH_LINES: (Severity.INFO, "LINES rows whose two ends are the same point"),
    IssueCode.POINTS_OFF_GRID: (Severity.INFO, "points not on the Resolution: lattice"),
    IssueCode.COORDINATE_OVERFLOW: (
        Severity.ERROR,
        "data coordinates outside the 32-bit range ARIA reads rows with",
    ),
    # 4xx
    IssueCode.DUPLICATE_NAME: (
        Severity.ERROR,
        "goals/docks with the same name (ARIA compares names case-insensitively)",
    ),
    IssueCode.EMPTY_NAME: (Severity.WARNING, "goal, dock or NameRequired object without a name"),
    IssueCode.UNDECLARED_TYPE: (
        Severity.WARNING,
        "object type neither built in nor declared in MapInfo:",
    ),
    IssueCode.TYPE_NOT_LISTED: (
        Severity.WARNING,
        "built-in goal/dock type used but not listed while the map declares its goal/dock types",
    ),
    IssueCode.NON_FINITE_OBJECT: (Severity.ERROR, "object with a NaN coordinate or heading"),
    IssueCode.HEADING_NOT_NORMALISED: (
        Severity.INFO,
        "heading outside (-180, 180] in the file (ARIA normalises it)",
    ),
    IssueCode.DEGENERATE_FORBIDDEN: (
        Severity.WARNING,
        "forbidden area without area or forbidden line without length",
    ),
    IssueCode.OBJECT_OUTSIDE_MAP: (Severity.WARNING, "object outside the map's data"),
    IssueCode.GOAL_IN_WALL: (Severity.ERROR, "goal, dock or home on an obstacle"),
    IssueCode.GOAL_NEAR_WALL: (
        Severity.WARNING,
        "goal, dock or home closer to an obstacle than the robot radius",
    ),
    IssueCode.GOAL_IN_FORBIDDEN_AREA: (
        Severity.ERROR,
        "goal, dock or home inside a forbidden area",
    ),
    IssueCode.NO_ROBOT_HOME: (Severity.INFO, "no RobotHome"),
    IssueCode.SEVERAL_ROBOT_HOMES: (Severity.INFO, "more than one RobotHome"),
    IssueCode.UNWRITABLE_TEXT: (
        Severity.ERROR,
        "type, name or description the .map format cannot hold (newline, quote, blank in a type)",
    ),
    IssueCode.WRONG_SHAPE_FOR_TYPE: (
        Severity.WARNING,
        "object drawn as point/line/rectangle against its type's declaration",
    ),
    IssueCode.INFINITE_OBJECT: (
        Severity.WARNING,
        "object with an infinite coordinate or heading (ARIA reads and writes it as inf): "
        "nothing can reach it and it is left out of every drawing and check",
    ),
    # 5xx
    IssueCode.UNREACHABLE: (
        Severity.ERROR,
        "goal or dock the robot cannot reach from RobotHome (or from the other goals)",
    ),
    IssueCode.NARROW_PASSAGE: (
        Severity.WARNING,
        "the way to a goal passes a gap barely wider than the robot",
    ),
    IssueCode.NAVIGATION_SKIPPED: (Severity.INFO, "reachability not checked, and why"),
    # 6xx
    IssueCode.TYPE_WITHOUT_NAME: (Severity.WARNING, "MapInfo: type line without Name="),
    IssueCode.TYPE_DECLARED_TWICE: (Severity.WARNING, "MapInfo: type declared on two lines"),
    IssueCode.ARGDESC_PARENT_MISMATCH: (
        Severity.WARNING,
        "ArgDesc whose Parent= is not the type or task declared above it",
    ),
    IssueCode.ARGDESC_BAD_TYPE: (
        Severity.WARNING,
        "ArgDesc without Name= or with a Type= ARIA does not know",
    ),
    IssueCode.ARGDESC_BAD_VALUE: (
        Severity.WARNING,
        "ArgDesc Value/Min/Max that does not fit its Type=, or Value outside Min..Max",
    ),
    IssueCode.PARAMS_UNKNOWN_OBJECT: (
        Severity.WARNING,
        "CairnInfo: Params for an object the map lacks",
    ),
    IssueCode.PARAMS_COUNT_MISMATCH: (
        Severity.WARNING,
        "CairnInfo: Params with another number of values than the type has ArgDesc lines",
    ),
    IssueCode.PARAMS_BAD_VALUE: (
        Severity.WARNING,
        "CairnInfo: Params value that does not fit its ArgDesc Type=",
    ),
    IssueCode.GROUP_MEMBER_MISMATCH: (
        Severity.WARNING,
        "CairnInfo: GroupMember naming an unknown object, type, group type or argument",
    ),
    IssueCode.LOG_BAD_HEADER_LINE: (
        Severity.ERROR,
        "log header line with values that cannot be read (ignored)",
    ),
    IssueCode.LOG_BAD_VALUE: (
        Severity.ERROR,
        "log record with a value that is not a number (record skipped)",
    ),
    IssueCode.LOG_NON_FINITE: (
        Severity.ERROR,
        "NaN or infinite number in a log record (record skipped)",
    ),
    IssueCode.LOG_WRONG_READING_COUNT: (
        Severity.ERROR,
        "scan with another number of readings than its laser's sickKconf: (record skipped)",
    ),
    IssueCode.LOG_INCOMPLETE_RECORD: (
        Severity.ERROR,
        "log record without its closing scanK: line (record skipped)",
    ),
    IssueCode.LOG_TRUNCATED: (Severity.ERROR, "log ends in the middle of a record or line"),
    IssueCode.LOG_UNKNOWN_TAG: (Severity.INFO, "unknown tag in a log, kept and written back"),
    IssueCode.LOG_GARBAGE_LINE: (
        Severity.WARNING,
        "log line that is neither a tag nor a comment (skipped)",
    ),
    IssueCode.LOG_NO_END_MARK: (
        Severity.INFO,
        "log without '# End of log': the logger did not shut down cleanly",
    ),
    IssueCode.LOG_UNKNOWN_LASER: (
        Severity.WARNING,
        "scan from a laser the header does not describe (mount taken as 0 0 0)",
    ),
    IssueCode.LOG_UNKNOWN_VERSION: (
        Severity.WARNING,
        "log version mapkit does not know (read as version 4)",
    ),
    IssueCode.LOG_UNPAIRED_LOOP: (
        Severity.WARNING,
        "loop: start without stop (or stop without start)",
    ),
}


@dataclass(frozen=True, slots=True)
class Location:
    """Where a finding is. Every field is optional.

    Attributes:
        source: File name.
        line: 1-based line number in the file.
        object: Name of the map object concerned.
        xy: World coordinates in millimetres.
    """

    source: str | None = None
    line: int | None = None
    object: str | None = None
    xy: tuple[float, float] | None = None

    def __str__(self) -> str:
        parts = []
        if self.source is not None or self.line is not None:
            parts.append(
                f"{self.source or ''}{':' if self.line is not None else ''}"
                f"{self.line if self.line is not None else ''}"
            )
        if self.object is not None:
            parts.append(f'object "{self.object}"')
        if self.xy is not None:
            parts.append(f"at ({self.xy[0]:.0f}, {self.xy[1]:.0f})")
        return " ".join(parts)

    def to_dict(self) -> dict[str, Any]:
        """The location as JSON-ready data (absent fields omitted)."""
        out: dict[str, Any] = {}
        for key in ("source", "line", "object"):
            value = getattr(self, key)
            if value is not None:
                out[key] = value
        if self.xy is not None:
            out["xy"] = [self.xy[0], self.xy[1]]
        return out


@dataclass(frozen=True, slots=True)
class Issue:
    """One finding.

    Attributes:
        code: Stable number, see :class:`IssueCode`.
        severity: error, warning or info.
        message: One line for a person.
        location: Where it is.
    """

    code: IssueCode
    severity: Severity
    message: str
    location: Location = field(default_factory=Location)

    @classmethod
    def make(cls, code: IssueCode, message: str, **where: Any) -> Issue:
        """An issue with the code's default severity, located by keyword arguments of Location."""
        return cls(code, CODE_SUMMARY[code][0], message, Location(**where))

    def __str__(self) -> str:
        where = str(self.location)
        prefix = f"{where}: " if where else ""
        return f"{prefix}{self.severity.value} MK{int(self.code)}: {self.message}"

    def to_dict(self) -> dict[str, Any]:
        """The issue as JSON-ready data."""
        return {
            "code": int(self.code),
            "name": self.code.name,
            "severity": self.severity.value,
            "message": self.message,
            "location": self.location.to_dict(),
        }


@dataclass(frozen=True, slots=True)
class Report:
    """A list of findings with helpers for counting and exit codes."""

    issues: tuple[Issue, ...] = ()

    def by_severity(self, severity: Severity) -> tuple[Issue, ...]:
        """The findings of one severity, in order."""
        return tuple(i for i in self.issues if i.severity is severity)

    @property
    def errors(self) -> tuple[Issue, ...]:
        """Error findings."""
        return self.by_severity(Severity.ERROR)

    @property
    def warnings(self) -> tuple[Issue, ...]:
        """Warning findings."""
        return self.by_severity(Severity.WARNING)

    def codes(self) -> list[int]:
        """The codes of all findings, in order."""
        return [int(i.code) for i in self.issues]

    def __len__(self) -> int:
        return len(self.issues)

    def __bool__(self) -> bool:
        return bool(self.issues)
