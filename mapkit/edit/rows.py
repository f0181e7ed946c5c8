"""Set operations on integer rows (points ``x y``, lines ``x1 y1 x2 y2``), vectorised.

Pairs of 32-bit coordinates are packed into one int64 each, so a point is one sortable integer
and a line two; membership is then one sort of both arrays together. ARIA's data rows are 32-bit
(``atoi``), so packing is exact; values outside that range fall back to sorting the raw columns.
"""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["first_occurrences", "isin_rows"]

_I32 = (-(2**31), 2**31 - 1)


def _columns(a: np.ndarray[Any, Any], b: np.ndarray[Any, Any]) -> list[np.ndarray[Any, Any]]:
    """Sort keys for the rows of ``a`` then ``b``: packed pairs when the values fit in 32 bits."""
    both = np.concatenate([np.asarray(a, dtype=np.int64), np.asarray(b, dtype=np.int64)])
    if both.size and _I32[0] <= both.min() and both.max() <= _I32[1] and both.shape[1] % 2 == 0:
        return [
            (both[:, k] << 32) | (both[:, k + 1] & 0xFFFFFFFF) for k in range(0, both.shape[1], 2)
        ]
    return [both[:, k] for k in range(both.shape[1])]


def isin_rows(
    a: np.ndarray[Any, Any], b: np.ndarray[Any, Any]
) -> np.ndarray[Any, np.dtype[np.bool_]]:
    """Mask of the rows of ``a`` that occur in ``b``.

    Examples:
        >>> isin_rows(np.array([[1, 2], [3, 4], [1, 2]]), np.array([[1, 2], [5, 6]])).tolist()
        [True, False, True]
        >>> isin_rows(np.array([[0, 0, 1, 1]]), np.array([[0, 0, 1, 2]])).tolist()
        [False]
    """
    n = len(a)
    if n == 0 or len(b) == 0:
        return np.zeros(n, dtype=bool)
    cols = _columns(a, b)
    if len(cols) == 1:  # one sort and a binary search (np.isin's hashing is slower here)
        ka, kb = cols[0][:n], np.sort(cols[0][n:])
        pos = np.minimum(np.searchsorted(kb, ka), len(kb) - 1)
        return np.asarray(kb[pos] == ka)
    order = np.lexsort(cols[::-1])
    srt = [c[order] for c in cols]
    new = np.ones(len(order), dtype=bool)
    new[1:] = np.any([s[1:] != s[:-1] for s in srt], axis=0)
    group = np.cumsum(new) - 1
    has_b = np.zeros(int(group[-1]) + 1, dtype=bool)
    has_b[group[order >= n]] = True
    out = np.empty(len(order), dtype=bool)
    out[order] = has_b[group]
    return out[:n]


def first_occurrences(a: np.ndarray[Any, Any]) -> np.ndarray[Any, np.dtype[np.bool_]]:
    """Mask keeping the first of each set of equal rows (file order kept).

    Examples:
        >>> first_occurrences(np.array([[1, 2], [3, 4], [1, 2]])).tolist()
        [True, True, False]
    """
    if len(a) == 0:
        return np.zeros(0, dtype=bool)
    cols = _columns(a, np.zeros((0, a.shape[1]), dtype=np.int64))
    order = np.lexsort(cols[::-1])  # stable: equal rows keep file order
    srt = [c[order] for c in cols]
    first = np.ones(len(order), dtype=bool)
    first[1:] = np.any([s[1:] != s[:-1] for s in srt], axis=0)
    out = np.empty(len(order), dtype=bool)
    out[order] = first
    return out
