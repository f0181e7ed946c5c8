"""The map linter: :func:`validate` checks a map and returns a :class:`ValidationReport`.

Every finding is an :class:`~mapkit.diagnostics.Issue` with a stable
:class:`~mapkit.diagnostics.IssueCode` (table in ``docs/codes.md``, or ``mapkit codes``):

* 1xx syntax: what the tolerant reader (:func:`mapkit.recover`) met in the file;
* 2xx header consistency: counts, boxes, resolution, sorted flags, the intro line;
* 3xx geometry: the points and lines themselves;
* 4xx objects: names, types, headings, forbidden areas, goals in or near walls, homes;
* 5xx navigation: every goal and dock reachable by a robot of the given radius;
* 6xx info sections: type declarations, ``ArgDesc`` and ``CairnInfo:`` lines.

Two views:

* ``validate(path)`` (or bytes) checks **the file as ARIA reads it**: the header values as
  written, line numbers for every finding, and the reader's own findings.
* ``validate(map)`` checks **the map as mapkit would write it** (:func:`mapkit.save`): header
  values are those the writer computes, objects are rounded as written, and anything the file
  format cannot hold is an error.

Nothing here prints or exits; ``mapkit validate`` renders the report.

Examples:
    >>> import mapkit
    >>> from mapkit.validate import validate
    >>> m = mapkit.loads(b"2D-Map\\nLineMinPos: 0 0\\nLineMaxPos: 4000 0\\nNumLines: 2\\n"
    ...                  b"Cairn: Goal 1000 0 0 \\"\\" ICON \\"A\\"\\nLINES\\n0 0 4000 0\\nDATA\\n")
    >>> report = validate(m, navigation=False)
    >>> [(i.code.name, i.severity.value) for i in report.issues]
    [('GOAL_IN_WALL', 'error'), ('NO_ROBOT_HOME', 'info')]
"""

from __future__ import annotations

import os
import sys
import types
from collections import defaultdict
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from mapkit._typing import PathLike
from mapkit.diagnostics import Issue, IssueCode, Report, Severity
from mapkit.formats.map import recover
from mapkit.model import MapData
from mapkit.validate import (
    geometry as _geometry,  # noqa: F401  (importing registers the rules)
    header as _header,  # noqa: F401
    info as _info,  # noqa: F401
    navigation as _navigation,  # noqa: F401
    objects as _objects,  # noqa: F401
)
from mapkit.validate._context import RULES, Context

__all__ = [
    "DEFAULT_ROBOT_RADIUS",
    "SYNTAX_GROUP_LIMIT",
    "ValidationReport",
    "codes_for_rules",
    "validate",
]

#: Robot radius (mm) used when none is given: ARIA's Pioneer 3-DX parameter file says 250.
DEFAULT_ROBOT_RADIUS = 250.0

#: At most this many findings per syntax code are listed one by one; the rest become one summary.
SYNTAX_GROUP_LIMIT = 10


@dataclass(frozen=True, slots=True)
class ValidationReport(Report):
    """A :class:`~mapkit.diagnostics.Report` plus what was checked.

    Attributes:
        source: The file checked (``None`` for an in-memory map).
        robot_radius: Robot radius in mm used for the clearance and reachability checks.
        checked: Facts about the run (goals checked, navigation grid cell size ...).
    """

    source: str | None = None
    robot_radius: float = DEFAULT_ROBOT_RADIUS
    checked: Mapping[str, Any] = field(default_factory=dict)

    def counts(self) -> dict[str, int]:
        """Number of findings per severity (``error``, ``warning``, ``info``)."""
        out = {s.value: 0 for s in Severity}
        for i in self.issues:
            out[i.severity.value] += 1
        return out

    def exit_code(self, strict: bool = False) -> int:
        """0 without errors, 1 with errors (or with warnings when ``strict``)."""
        if self.errors or (strict and self.warnings):
            return 1
        return 0

    def to_dict(self) -> dict[str, Any]:
        """The report as JSON-ready data."""
        return {
            "file": self.source,
            "robot_radius": self.robot_radius,
            "summary": self.counts(),
            "checked": dict(self.checked),
            "issues": [i.to_dict() for i in self.issues],
        }


def codes_for_rules() -> dict[str, tuple[IssueCode, ...]]:
    """Each rule (``module.function``) and the codes it reports."""
    return {f"{fn.__module__.rsplit('.', 1)[-1]}.{fn.__name__}": codes for fn, codes in RULES}


def _group_syntax(issues: list[Issue], limit: int) -> list[Issue]:
    """Keep the first ``limit`` findings of each code; summarise the rest in one finding."""
    by_code: dict[IssueCode, list[Issue]] = defaultdict(list)
    for i in issues:
        by_code[i.code].append(i)
    out: list[Issue] = []
    done: set[IssueCode] = set()
    for i in issues:
        group = by_code[i.code]
        if len(group) <= limit:
            out.append(i)
            continue
        if i.code in done:
            continue
        done.add(i.code)
        out.extend(group[: limit - 1])
        rest = group[limit - 1 :]
        lines = [r.location.line for r in rest if r.location.line is not None]
        span = f" (lines {min(lines)} .. {max(lines)})" if lines else ""
        first = rest[0]
        out.append(
            Issue(
                first.code,
                first.severity,
                f"{len(rest)} more like this{span}: {first.message}",
                first.location,
            )
        )
    return out


def validate(
    map_or_file: MapData | PathLike | bytes,
    *,
    robot_radius: float = DEFAULT_ROBOT_RADIUS,
    navigation: bool = True,
    source: str | None = None,
) -> ValidationReport:
    """Check a map and report every finding with a stable code.

    Args:
        map_or_file: A path or the file's bytes (checked as ARIA reads the file, with the
            tolerant reader's findings and line numbers), or a :class:`MapData` (checked as
            :func:`mapkit.save` would write it).
        robot_radius: Robot radius in mm for the clearance and reachability checks (0 checks
            connectivity only).
        navigation: Run the reachability checks (5xx), which rasterise the map.
        source: Name used in locations (defaults to the path, or the map's provenance).

    Returns:
        The report; ``report.exit_code(strict)`` gives the CLI's exit code.

    Raises:
        MapFormatError: When the file is not a map at all (no intro line, empty).
        OSError: When the file cannot be read.
        ValueError: For a negative or non-finite robot radius.
    """
    if not (robot_radius >= 0 and robot_radius != float("inf")):
        raise ValueError(f"robot radius must be a finite number of mm >= 0, got {robot_radius!r}")
    syntax: list[Issue] = []
    raw: bytes | None = None
    if isinstance(map_or_file, MapData):
        m = map_or_file
        name = (
            source
            if source is not None
            else (
                m.provenance.source
                if m.provenance is not None and m.provenance.source != "<string>"
                else None
            )
        )
        ctx = Context(m, file_view=False, source=name)
    else:
        if isinstance(map_or_file, (bytes, bytearray, memoryview)):
            raw = bytes(map_or_file)
            name = source or "<bytes>"
        else:
            name = source or os.fspath(map_or_file)
            with open(map_or_file, "rb") as fh:
                raw = fh.read()
        m, syntax = recover(raw, source=name)
        prov = m.provenance
        head = prov.first_data_line if prov is not None and prov.first_data_line else None
        raw_lines = raw.split(b"\n", head)[:head] if head else raw.split(b"\n")
        ctx = Context(m, file_view=True, source=name, raw_lines=raw_lines)
    ctx.robot_radius = float(robot_radius)
    ctx.navigation = navigation
    for fn, _codes in sorted(RULES, key=lambda r: min(r[1])):  # by range: 2xx first ... 6xx
        fn(ctx)
    replaced = ctx.cache.get("misspelt_lines", set())
    syntax = [
        i for i in syntax if not (i.code is IssueCode.UNKNOWN_LINE and i.location.line in replaced)
    ]
    issues = _group_syntax(syntax, SYNTAX_GROUP_LIMIT) + ctx.issues
    return ValidationReport(
        tuple(issues), source=ctx.source, robot_radius=ctx.robot_radius, checked=dict(ctx.stats)
    )


class _CallableModule(types.ModuleType):
    """``mapkit.validate(m)`` calls :func:`validate`: the package is also the function."""

    def __call__(
        self,
        map_or_file: MapData | PathLike | bytes,
        *,
        robot_radius: float = DEFAULT_ROBOT_RADIUS,
        navigation: bool = True,
        source: str | None = None,
    ) -> ValidationReport:
        return validate(
            map_or_file, robot_radius=robot_radius, navigation=navigation, source=source
        )


sys.modules[__name__].__class__ = _CallableModule
