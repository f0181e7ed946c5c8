"""Keywords and tokens as ARIA's ``.map`` parser sees them: bytes to names, quoting, limits."""

from __future__ import annotations

import re

from mapkit.model import (
    CATEGORIES,
    INFO_KEYWORDS,
)

__all__ = ["tokenize"]


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
