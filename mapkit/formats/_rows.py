"""Data rows of a ``.map`` (``DATA``: 2 integers, ``LINES``: 4) to numpy and back, vectorised.

ARIA's row rules (FORMATS.md A.8): a row is ``<int><ws+><int>...`` then anything; an int is an
optional ``-`` and decimal digits (a lone ``-`` is 0) read by ``atoi`` (``strtol``: a number
beyond 64 bits saturates; mapkit keeps the 64-bit value where ARIA cuts it to 32 bits); no ``+``,
hex or decimals; a row that starts with whitespace or does not fit is skipped silently. Here
every row is checked with those rules; rows that fail are reported by index.

How it is fast (no Python loop per row):

* **Reading.** Rows are taken in chunks of about 128 KiB (cut at a LF). A chunk is *canonical*
  when it holds only digits, ``-`` at the start of a number, single spaces between the numbers,
  ``LF`` (or ``CR LF``) line ends, exactly ``ncols`` numbers per row and at most 8 characters per
  number: what ARIA and mapkit write. A few whole-chunk checks on the bytes (``uint8``) and on the
  separator positions prove that; then each number is read as the 8 bytes that end it (one
  unaligned ``uint64``), masked to its length and turned into an integer by the SWAR
  digit-combining trick (3 multiplications for 8 digits). A leading ``-`` stays in the word as
  the digit 13: an n-character number starting with ``-`` reads as ``13 * 10**(n-1) + |value|``,
  above any run of n digits, so one range check gives the sign (and rejects a leading ``.`` or
  ``/``); the count of ``-``, ``.`` and ``/`` bytes in the chunk must equal the count of negative
  numbers, which proves there is no other. A chunk that is not canonical is split in halves (so
  one odd row does not slow its neighbours) down to a few KiB, and those pieces go to the
  per-line reference parser, which applies every rule and reports bad rows.
* **Writing.** Each number is split into two 4-digit halves that index a 10,000-entry table of
  ASCII digit words; the digits (with the padding ``0`` before them turned into ``-`` for a
  negative number) are shifted to the start of a ``uint64`` with the separator after them, and
  every word is stored at its offset in the output (a cumulative sum of the widths), in
  increasing order, so each word overwrites the spare bytes of the one before. Numbers of 8
  characters or more get their separator (and a 9th character) stored separately; numbers with
  more than 8 digits go through the reference formatter.
* **Threads.** Chunks are independent, so :func:`worker_pool` and :func:`ordered_map` let the map
  reader and writer run them on worker threads (numpy releases the GIL) and take the results in
  order.

``_parse_rows_reference`` and ``_format_rows_reference`` are the plain implementations the fast
ones are tested against.
"""

from __future__ import annotations

import contextlib
import os
import re
from collections import deque
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from typing import Any, TypeVar

import numpy as np

from mapkit.formats._numbers import atoi

__all__ = [
    "RowReader",
    "RowSink",
    "column_extremes",
    "format_rows",
    "iter_format_rows",
    "ordered_map",
    "parse_rows",
    "worker_pool",
]

IntArray = np.ndarray[Any, np.dtype[np.int64]]

# -- reference implementations (the oracles) ---------------------------------------------------

_WS = rb"[ \t\r\x0b\x0c]+"
_INT = rb"(-[0-9]*|[0-9]+)"
_ROW = {
    2: re.compile(rb"^" + _INT + _WS + _INT + rb"[^\n]?", re.M),
    4: re.compile(rb"^" + _INT + _WS + _INT + _WS + _INT + _WS + _INT + rb"[^\n]?", re.M),
}


def _int(tok: bytes) -> int:
    # strtol in base 10 (atoi before its int cast): a lone '-' is 0, beyond 64 bits saturates.
    return atoi(tok.decode("ascii"))


def _parse_rows_reference(seg: bytes, ncols: int) -> tuple[IntArray, list[int]]:
    """Parse rows one line at a time with regular expressions (the reference for parse_rows).

    Examples:
        >>> v, bad = _parse_rows_reference(b"1 2\\n12 34.7\\n1.5 2\\n- 3\\n", 2)
        >>> v.tolist(), bad
        ([[1, 2], [12, 34], [0, 3]], [2])
    """
    pattern = _ROW[ncols]
    lines = seg.split(b"\n")
    if lines and lines[-1] == b"":
        lines.pop()
    out: list[list[int]] = []
    bad: list[int] = []
    for i, line in enumerate(lines):
        m = pattern.match(line + b"\n")
        if m is None:
            bad.append(i)  # not a row
        else:
            out.append([_int(g) for g in m.groups()])
    values = np.array(out, dtype=np.int64).reshape(-1, ncols)
    return values, bad


def _format_rows_reference(values: np.ndarray[Any, Any]) -> bytes:
    """Rows formatted with ``%d`` one at a time (the reference for :func:`format_rows`).

    Examples:
        >>> _format_rows_reference(np.array([[1, -2], [30, 4]]))
        b'1 -2\\n30 4\\n'
    """
    if len(values) == 0:
        return b""
    fmt = " ".join(["%d"] * values.shape[1]) + "\n"
    return "".join(fmt % tuple(row) for row in values.tolist()).encode("ascii")


# -- constants of the fast paths ----------------------------------------------------------------

_U64 = np.uint64
_PARSE_CHUNK = 1 << 17  # bytes of text per vectorised step (stays in the L2 cache)
_MIN_SPLIT = 1 << 12  # non-canonical pieces below this go to the reference parser
_FORMAT_CHUNK = 1 << 14  # rows per vectorised formatting step
_MAX_FAST = 10**8  # |value| below this has at most 8 digits

# Separator bytes per row, read as one little-endian word: b" \n" and b"   \n".
_SEP_WORD = {2: (np.uint16, 0x0A20), 4: (np.uint32, 0x0A202020)}
_SEP_PATTERN_CRLF = {k: np.array([32] * (k - 1) + [13, 10], np.uint8) for k in (2, 4)}
# For a number of n = ell - 1 characters ending at byte 7 of its word: keep those n bytes, low
# nibble only ('0'..'9' -> 0..9, '-' -> 13).
_DIGIT_MASK = np.array(
    [0] + [int.from_bytes(b"\x00" * (9 - e) + b"\x0f" * (e - 1), "little") for e in range(1, 10)],
    dtype=_U64,
)
# 10**(n-1) for a number of n = ell - 1 characters (see _values).
_LEAD_UNIT = np.array([0, 0] + [10 ** (e - 2) for e in range(2, 10)], dtype=_U64)
_B45 = np.uint8(45)  # '-'
_B3 = np.uint8(3)
_B12 = np.uint8(12)

# Writing: ASCII of 0..9999 as 4 digits (most significant first) in the low or the high half of
# a word, and digit counts; separators of rows of 2 and 4 values, one per value.
_ASCII4_HI = np.array([int.from_bytes(b"%04d" % i, "little") for i in range(10000)], dtype=_U64)
_ASCII4_LO = _ASCII4_HI << _U64(32)
_NDIG = np.array([len(str(i)) for i in range(10000)], dtype=np.int64)
_NDIG_HI = np.where(np.arange(10000) > 0, _NDIG + 4, 0).astype(np.int64)


# -- reading --------------------------------------------------------------------------------


class RowReader:
    """Parses data rows in place inside one buffer (the whole file), chunk by chunk.

    Args:
        data: The buffer. Rows passed to :meth:`parse` must start at offset 8 or later (the
            8 bytes before a number are read with it and masked off).
    """

    def __init__(self, data: bytes) -> None:
        self.data = data
        self.buf = np.frombuffer(data, np.uint8)
        n = len(data)
        # win[i] is the little-endian uint64 of data[i:i + 8].
        self.win = np.ndarray(shape=(max(n - 7, 0),), dtype="<u8", buffer=data, strides=(1,))

    def parse(self, start: int, end: int, ncols: int, sink: RowSink) -> tuple[list[int], int]:
        """Parse the rows of ``data[start:end]`` (each starts with a digit or ``-``, ends with LF).

        The rows ARIA keeps are appended to ``sink``.

        Returns:
            ``(bad, nrows)``: the 0-based indices of the skipped rows and the number of rows seen.
        """
        bad: list[int] = []
        nrows = 0
        data = self.data
        s = start
        while s < end:
            e = end
            if end - s > _PARSE_CHUNK:
                cut = data.rfind(b"\n", s, s + _PARSE_CHUNK)
                if cut < 0:
                    cut = data.find(b"\n", s + _PARSE_CHUNK, end)
                e = end if cut < 0 else cut + 1
            nrows = self._piece(s, e, ncols, sink, bad, nrows)
            s = e
        return bad, nrows

    def _piece(self, s: int, e: int, k: int, sink: RowSink, bad: list[int], nrows: int) -> int:
        n = self.fast_into(sink, s, e, k) if s >= 8 else None
        if n is not None:
            return nrows + n
        if e - s > _MIN_SPLIT:
            mid = self.data.rfind(b"\n", s, (s + e) // 2) + 1
            if s < mid < e:
                nrows = self._piece(s, mid, k, sink, bad, nrows)
                return self._piece(mid, e, k, sink, bad, nrows)
        seg = self.data[s:e]
        values, skipped = _parse_rows_reference(seg, k)
        sink.append(values)
        bad.extend(nrows + i for i in skipped)
        return nrows + seg.count(b"\n") + (0 if seg.endswith(b"\n") else 1)

    def fast(self, s: int, e: int, k: int | None = None) -> IntArray | None:
        """Rows of ``data[s:e]`` as an ``(n, k)`` array if the text is canonical, else ``None``.

        With ``k=None`` the number of values per row is taken from the first row (2 or 4).
        """
        found = self._canonical(s, e, k)
        if found is None:
            return None
        k, ends, ell, n_minus = found
        out = np.empty((ell.size // k, k), np.int64)
        return out if self._values(ends, ell, n_minus, out.reshape(-1)) else None

    def fast_into(self, sink: RowSink, s: int, e: int, k: int) -> int | None:
        """Append the rows of ``data[s:e]`` to ``sink`` if the text is canonical.

        ``data[s:e]`` must end with LF and ``s >= 8``.

        Returns:
            The number of rows, or ``None`` (and nothing appended) if the text is not canonical.
        """
        found = self._canonical(s, e, k)
        if found is None:
            return None
        k, ends, ell, n_minus = found
        nrows = ell.size // k
        if not self._values(ends, ell, n_minus, sink.reserve(nrows).reshape(-1)):
            return None
        sink.commit(nrows)
        return nrows

    def _canonical(
        self, s: int, e: int, k: int | None
    ) -> tuple[int, IntArray, IntArray, int] | None:
        """Check that ``data[s:e]`` is canonical; ``(k, ends, ell, n_minus)`` if it is.

        ``ends`` are the offsets of the 8-byte words that end each number, ``ell`` is 1 + the
        length of each number, ``n_minus`` the count of bytes '-', '.' and '/' (see _values).
        """
        c = self.buf[s:e]
        if c.size == 0 or c[-1] != 10 or s < 8:
            return None
        # Bytes '-' . / 0..9 become 0..12; every other byte (separators, letters) is above 12.
        t = c - _B45
        ends = np.flatnonzero(t > _B12)
        nsep = ends.size
        seps = c[ends]
        if k is None:  # the first row says: "a b\n", "a b\r\n", "a b c d\n", "a b c d\r\n"
            k = next((j for j in (2, 4) if nsep > j and 10 in (seps[j - 1], seps[j])), 0)
        if k not in _SEP_WORD or nsep < k:
            return None
        dtype, word = _SEP_WORD[k]
        if nsep % k == 0 and seps[k - 1] == 10:
            if not (seps.view(dtype) == word).all():
                return None
            ell = _gaps(ends)
        elif nsep % (k + 1) == 0 and seps[k - 1] == 13:  # CR LF line ends
            if not (seps.reshape(-1, k + 1) == _SEP_PATTERN_CRLF[k]).all():
                return None
            ell = np.ascontiguousarray(_gaps(ends).reshape(-1, k + 1)[:, :k]).ravel()
            ends = np.ascontiguousarray(ends.reshape(-1, k + 1)[:, :k]).ravel()
        else:
            return None
        # ell = 1 + characters of the number ending at each separator: 1 to 8 characters.
        if ell.min() < 2 or ell.max() > 9:
            return None
        # Inside numbers only digits and a leading '-': every byte in '-'..'/' must be the first
        # character of a number that reads as negative (checked by _values).
        n_minus = int(np.count_nonzero(t < _B3))
        ends += s - 8
        return k, ends, ell, n_minus

    def _values(self, ends: IntArray, ell: IntArray, n_minus: int, out: IntArray) -> bool:
        """The numbers into ``out`` (flat int64); ``False`` when a '-' is not where it may be."""
        w = self.win[ends]
        w &= _DIGIT_MASK[ell]
        # SWAR: 8 digit bytes (most significant first) -> pairs -> quads -> value.
        w *= _U64(10 * 256 + 1)
        w >>= _U64(8)
        w &= _U64(0x00FF00FF00FF00FF)
        w *= _U64(100 * 65536 + 1)
        w >>= _U64(16)
        w &= _U64(0x0000FFFF0000FFFF)
        w *= _U64((10000 << 32) + 1)
        np.right_shift(w, _U64(32), out=out.view(_U64))
        if n_minus:
            # A leading '-' reads as 13 * unit + |value| with |value| < unit; a leading '.' or
            # '/' (14, 15) reads at least 14 * unit, a leading digit less than 13 * unit.
            unit = _LEAD_UNIT[ell]
            d = unit * _U64(13)
            np.subtract(out.view(_U64), d, out=d)
            neg = d < unit
            d = d.view(np.int64)
            if np.count_nonzero(neg) != n_minus:  # a '-' elsewhere, a '.' or a '/'
                return False
            d += out  # v - (v + d) = -d where negative
            d *= neg
            out -= d
        return True


def _gaps(ends: IntArray) -> IntArray:
    out = np.empty_like(ends)
    out[0] = ends[0] + 1
    np.subtract(ends[1:], ends[:-1], out=out[1:])
    return out


class RowSink:
    """Rows appended block by block into one array that grows as needed (no final concatenation).

    Args:
        ncols: Values per row.
        expected: Rows to make room for at the first append (e.g. the header's count).
    """

    def __init__(self, ncols: int, expected: int = 0) -> None:
        self.ncols = ncols
        self.expected = expected
        self.buf = np.zeros((0, ncols), np.int64)
        self.n = 0
        # Per-column minimum and maximum of the rows, while every block came with them.
        self.lo: IntArray | None = np.full(ncols, np.iinfo(np.int64).max)
        self.hi: IntArray | None = np.full(ncols, np.iinfo(np.int64).min)

    def reserve(self, m: int) -> IntArray:
        """Room for ``m`` more rows (a view to fill); they count once :meth:`commit` is called."""
        need = self.n + m
        if need > len(self.buf):
            size = max(need, self.expected, len(self.buf) * 3 // 2 + 1024)
            grown = np.empty((size, self.ncols), np.int64)
            grown[: self.n] = self.buf[: self.n]
            self.buf = grown
        return self.buf[self.n : need]

    def commit(self, m: int) -> None:
        """Count ``m`` rows written into the last :meth:`reserve`."""
        self.n += m
        self.lo = self.hi = None

    def append(self, values: IntArray, extremes: tuple[IntArray, IntArray] | None = None) -> None:
        """Add rows at the end (with their :func:`column_extremes`, if known)."""
        if len(values) == 0:
            return
        self.reserve(len(values))[...] = values
        self.n += len(values)
        if extremes is None or self.lo is None or self.hi is None:
            self.lo = self.hi = None
        else:
            np.minimum(self.lo, extremes[0], out=self.lo)
            np.maximum(self.hi, extremes[1], out=self.hi)

    def box(self) -> tuple[tuple[int, int], tuple[int, int]] | None:
        """Min and max corner of the rows read as points (x y [x y]), if known and not empty."""
        if self.lo is None or self.hi is None or self.n == 0:
            return None
        lo, hi = self.lo.reshape(-1, 2).min(axis=0), self.hi.reshape(-1, 2).max(axis=0)
        return (int(lo[0]), int(lo[1])), (int(hi[0]), int(hi[1]))

    def result(self) -> IntArray:
        """The rows as one ``(n, ncols)`` array (a copy only when much of the room is unused)."""
        if self.n == len(self.buf):
            return self.buf
        if len(self.buf) - self.n > max(self.n // 8, 4096):
            return self.buf[: self.n].copy()
        return self.buf[: self.n]


def column_extremes(values: IntArray) -> tuple[IntArray, IntArray]:
    """Per-column minimum and maximum of an ``(n, k)`` array (``n > 0``), column by column.

    (``values.min(axis=0)`` on a narrow array is many times slower.)
    """
    cols = range(values.shape[1])
    return (
        np.array([values[:, j].min() for j in cols]),
        np.array([values[:, j].max() for j in cols]),
    )


def parse_rows(seg: bytes, ncols: int) -> tuple[IntArray, list[int]]:
    """Parse complete data rows with ARIA's rules.

    Args:
        seg: LF-separated rows, each starting with a digit or ``-``. Every row, the last included,
            ends with LF.
        ncols: 2 for ``DATA`` rows, 4 for ``LINES`` rows.

    Returns:
        ``(values, bad)``: an ``(K, ncols)`` int64 array of the rows ARIA keeps, and the 0-based
        indices (within ``seg``) of the rows it skips.

    Examples:
        >>> v, bad = parse_rows(b"1 2\\n12 34.7\\n1.5 2\\n- 3\\n", 2)
        >>> v.tolist(), bad
        ([[1, 2], [12, 34], [0, 3]], [2])
    """
    data = b"\n" * 8 + bytes(seg)
    sink = RowSink(ncols, int(np.count_nonzero(np.frombuffer(data, np.uint8) == 10)))
    bad, _ = RowReader(data).parse(8, len(data), ncols, sink)
    return sink.result(), bad


# -- writing ----------------------------------------------------------------------------------


_SEP = {k: np.tile(np.array([32] * (k - 1) + [10], _U64), _FORMAT_CHUNK) for k in (2, 4)}


def _format_fast(values: np.ndarray[Any, Any]) -> np.ndarray[Any, np.dtype[np.uint8]] | None:
    """The text of an ``(n, k)`` block of rows, or ``None`` if a value has more than 8 digits."""
    k = values.shape[1]
    v = np.ascontiguousarray(values, dtype=np.int64).ravel()
    a = np.abs(v)
    if a.size == 0 or a.view(_U64).max() >= _MAX_FAST:  # abs(-2**63) reads 2**63 here
        return None
    neg = v < 0
    hi = a // 10000
    lo = a - hi * 10000
    word = _ASCII4_HI[hi]
    word |= _ASCII4_LO[lo]
    chars = np.maximum(_NDIG_HI[hi], _NDIG[lo])  # digits, then characters without the separator
    chars += neg
    # Keep the last `chars` bytes of the 8 digits (leading '0's included), moved to the start of
    # the word; for a negative number the first of them is a padding '0': make it '-'.
    bits = chars << 3
    word >>= (64 - bits).view(_U64)
    word -= neg * _U64(ord("0") - ord("-"))
    word |= _SEP[k][: v.size] << bits.view(_U64)  # shifts of 64 bits give 0: no room, see below
    chars += 1
    end = np.cumsum(chars)
    total = int(end[-1])
    out = np.empty(total + 8, np.uint8)
    start = end - chars
    # Increasing offsets: each word's spare (zero) bytes are overwritten by the words after it.
    np.ndarray(shape=(total + 1,), dtype="<u8", buffer=out, strides=(1,))[start] = word
    long = bits >= 64
    if long.any():  # 8 characters or more: the separator (and a 9th character) come separately
        _format_long(out, a[long], neg[long], start[long], end[long], _SEP[k][: v.size][long])
    text = out[:total]
    # numpy stores fancy-indexed words in index order; were that ever not so, spare zero bytes
    # would be left in the text: then take the safe path.
    return text if text.all() else None


def _format_long(
    out: np.ndarray[Any, Any], a: IntArray, neg: Any, start: IntArray, end: IntArray, sep: Any
) -> None:
    hi = a // 10000
    word = _ASCII4_HI[hi] | _ASCII4_LO[a - hi * 10000]
    nine = neg & (a >= 10**7)  # '-' and 8 digits: the digits start one byte later
    if nine.any():
        words = np.ndarray(shape=(len(out) - 7,), dtype="<u8", buffer=out, strides=(1,))
        words[start[nine] + 1] = word[nine]
        out[start[nine]] = ord("-")
    out[end - 1] = sep.astype(np.uint8)


def _format_block(block: np.ndarray[Any, Any]) -> bytes:
    text = _format_fast(block)
    return _format_rows_reference(block) if text is None else text.tobytes()


def iter_format_rows(
    values: np.ndarray[Any, Any], pool: ThreadPoolExecutor | None = None
) -> Iterator[bytes]:
    """The text of rows as ARIA writes them, in pieces of about 200 KB.

    Args:
        values: ``(n, k)`` integers.
        pool: Threads to format the pieces on (they come out in order); ``None``: this thread.
    """
    blocks = (values[i : i + _FORMAT_CHUNK] for i in range(0, len(values), _FORMAT_CHUNK))
    yield from ordered_map(pool, _format_block, blocks)


# -- worker threads ---------------------------------------------------------------------------

_MAX_WORKERS = 4
T = TypeVar("T")
R = TypeVar("R")


@contextlib.contextmanager
def worker_pool(big: bool) -> Iterator[ThreadPoolExecutor | None]:
    """Threads for the vectorised steps of a big job (numpy and hashlib release the GIL).

    Yields ``None`` (work on the calling thread) for small jobs or a single CPU. Pending work is
    cancelled if the caller stops early.
    """
    cpus = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    workers = min(cpus or 1, _MAX_WORKERS)
    if not big or workers < 2:
        yield None
        return
    pool = ThreadPoolExecutor(workers, thread_name_prefix="mapkit-rows")
    try:
        yield pool
    finally:
        pool.shutdown(wait=True, cancel_futures=True)


def ordered_map(
    pool: ThreadPoolExecutor | None, fn: Callable[[T], R], items: Iterable[T]
) -> Iterator[R]:
    """``map(fn, items)``, run on ``pool`` when given, in order, with a few items in flight.

    Examples:
        >>> with worker_pool(True) as pool:
        ...     list(ordered_map(pool, abs, range(-3, 3)))
        [3, 2, 1, 0, 1, 2]
    """
    if pool is None:
        yield from map(fn, items)
        return
    pending: deque[Future[R]] = deque()
    for item in items:
        pending.append(pool.submit(fn, item))
        if len(pending) > 2 * _MAX_WORKERS + 2:  # bounds the memory of finished pieces
            yield pending.popleft().result()
    while pending:
        yield pending.popleft().result()


def format_rows(values: np.ndarray[Any, Any]) -> bytes:
    """Rows of integers as ARIA writes them: single spaces, one row per line, LF-terminated.

    Examples:
        >>> format_rows(np.array([[1, -2], [30, 4]]))
        b'1 -2\\n30 4\\n'
    """
    return b"".join(iter_format_rows(values))
