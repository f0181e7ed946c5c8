"""Which chunks a receiver holds: bitmaps, ranges, and their wire encodings."""

from __future__ import annotations

import base64
import binascii
from collections.abc import Iterable
from typing import Any

from mapkit.transfer.protocol.errors import ProtocolError

__all__ = ["bitmap_from_ranges", "decode_bitmap", "encode_bitmap", "ranges_from_bitmap"]


# -- bitmaps and ranges ---------------------------------------------------------------------------


def ranges_from_bitmap(
    have: bytes | bytearray, start: int = 0, limit: int | None = None
) -> list[list[int]]:
    """Half-open ``[a, b)`` ranges of set entries (value 1) in a byte-per-chunk bitmap.

    Examples:
        >>> ranges_from_bitmap(bytearray([1, 1, 0, 1, 0, 0, 1]))
        [[0, 2], [3, 4], [6, 7]]
        >>> ranges_from_bitmap(bytearray([1, 1, 0, 1, 0, 0, 1]), start=1, limit=1)
        [[1, 2]]
    """
    out: list[list[int]] = []
    n = len(have)
    i = start
    while i < n and (limit is None or len(out) < limit):
        a = have.find(1, i)
        if a < 0:
            break
        b = have.find(0, a)
        if b < 0:
            b = n
        out.append([a, b])
        i = b
    return out


def bitmap_from_ranges(n: int, ranges: Iterable[Any]) -> bytearray:
    """A byte-per-chunk bitmap of ``n`` entries with the given ``[a, b)`` ranges set.

    Raises:
        ProtocolError: When a range is malformed or out of bounds.
    """
    have = bytearray(n)
    for r in ranges:
        if not (
            isinstance(r, list)
            and len(r) == 2
            and all(isinstance(v, int) for v in r)
            and 0 <= r[0] <= r[1] <= n
        ):
            raise ProtocolError(f"bad chunk range {r!r} for {n} chunks")
        have[r[0] : r[1]] = b"\x01" * (r[1] - r[0])
    return have


_TO_01 = bytes.maketrans(b"\x00\x01", b"01")
_FROM_01 = bytes.maketrans(b"01", b"\x00\x01")


def encode_bitmap(have: bytes | bytearray) -> str:
    """Pack a byte-per-chunk bitmap into base64 bits, most significant bit first.

    Examples:
        >>> encode_bitmap(bytearray([1, 0, 1, 1, 0, 0, 0, 0, 1]))
        'sIA='
    """
    n = len(have)
    if n == 0 or not any(have):
        return ""
    pad = (-n) % 8
    bits = bytes(have).translate(_TO_01) + b"0" * pad
    return base64.b64encode(int(bits, 2).to_bytes((n + pad) // 8, "big")).decode("ascii")


def decode_bitmap(text: Any, n: int) -> bytearray:
    """Unpack :func:`encode_bitmap` output into a byte-per-chunk bitmap of ``n`` entries.

    Raises:
        ProtocolError: When the text is not base64 of the right length.

    Examples:
        >>> list(decode_bitmap('sIA=', 9))
        [1, 0, 1, 1, 0, 0, 0, 0, 1]
    """
    if text in ("", None):
        return bytearray(n)
    try:
        raw = base64.b64decode(text, validate=True)
    except (binascii.Error, ValueError, TypeError) as err:
        raise ProtocolError(f"bad chunk bitmap: {err}") from err
    if len(raw) != (n + 7) // 8:
        raise ProtocolError(f"chunk bitmap has {len(raw)} bytes, expected {(n + 7) // 8}")
    bits = format(int.from_bytes(raw, "big"), f"0{len(raw) * 8}b").encode("ascii")
    out = bytearray(bits[:n].translate(_FROM_01))
    if any(bits[n:].translate(_FROM_01)):
        raise ProtocolError("chunk bitmap has bits set past the last chunk")
    return out
