"""5xx: reachability on the inflated grid (filled in with the navigation rule)."""

from __future__ import annotations

from mapkit.diagnostics import IssueCode

NAV_CODES = {IssueCode.UNREACHABLE, IssueCode.NARROW_PASSAGE, IssueCode.NAVIGATION_SKIPPED}
