"""The table of every finding code, generated from :class:`~mapkit.diagnostics.IssueCode`.

``docs/codes.md`` is this module's :func:`codes_markdown` output (``mapkit codes --markdown``);
a test fails when the file is stale.
"""

from __future__ import annotations

from typing import Any

from mapkit.diagnostics import CODE_SUMMARY, IssueCode

__all__ = ["RANGES", "code_rows", "codes_markdown"]

#: The numbered ranges and what they hold.
RANGES = {
    1: "syntax: what the tolerant reader (`mapkit.recover`) met in the file",
    2: "header consistency: counts, boxes, resolution, sorted flags, the intro line",
    3: "geometry: the points and lines themselves",
    4: "objects: names, types, headings, forbidden areas, goals in or near walls, homes",
    5: "navigation: reachability for a robot of a given radius",
    6: "info sections: type declarations, ArgDesc and CairnInfo lines",
    7: ".2d laser logs",
}


def code_rows() -> list[dict[str, Any]]:
    """One row per code, in numeric order: ``code``, ``name``, ``severity``, ``summary``.

    Examples:
        >>> code_rows()[0]["code"], code_rows()[0]["name"]
        ('MK101', 'JUNK_BEFORE_INTRO')
    """
    rows = []
    for code in sorted(IssueCode):
        severity, summary = CODE_SUMMARY[code]
        rows.append(
            {
                "code": f"MK{int(code)}",
                "number": int(code),
                "name": code.name,
                "severity": severity.value,
                "summary": summary,
            }
        )
    return rows


def codes_markdown() -> str:
    """``docs/codes.md``: one table of every code."""
    out = [
        "# Finding codes",
        "",
        "Every finding `mapkit validate` (and the tolerant reader) reports has a stable code.",
        "Codes are never renumbered; new ones are only added. The severity is the default one.",
        "This page is generated from `mapkit.diagnostics.IssueCode`: run",
        "`mapkit codes --markdown > docs/codes.md` after adding a code.",
        "",
        "Ranges:",
        "",
    ]
    used = sorted({int(c) // 100 for c in IssueCode})
    out += [f"* {r}xx {RANGES.get(r, '')}".rstrip() for r in used]
    out += ["", "| code | name | severity | summary |", "|---|---|---|---|"]
    for row in code_rows():
        summary = row["summary"].replace("|", "\\|")
        out.append(f"| {row['code']} | `{row['name']}` | {row['severity']} | {summary} |")
    return "\n".join(out) + "\n"
