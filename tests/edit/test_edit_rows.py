"""Row set operations against Python's sets."""

from __future__ import annotations

import numpy as np
from hypothesis import given, strategies as st
from hypothesis.extra import numpy as hnp

from mapkit.edit.rows import first_occurrences, isin_rows

small = st.integers(-3, 3)  # few values, so rows repeat and match often
wide = st.sampled_from([-(2**31), -1, 0, 1, 2**31 - 1, 2**40])  # 2**40 forces the unpacked path


def rows(cols: int, elements: st.SearchStrategy[int]) -> st.SearchStrategy[np.ndarray]:
    return hnp.arrays(np.int64, st.tuples(st.integers(0, 30), st.just(cols)), elements=elements)


@given(cols=st.sampled_from([2, 4]), data=st.data(), elements=st.sampled_from([small, wide]))
def test_isin_rows_and_first_occurrences_agree_with_sets(
    cols: int, data: st.DataObject, elements
) -> None:  # type: ignore[no-untyped-def]
    a = data.draw(rows(cols, elements))
    b = data.draw(rows(cols, elements))
    in_b = {tuple(r) for r in b.tolist()}
    assert isin_rows(a, b).tolist() == [tuple(r) in in_b for r in a.tolist()]
    seen: set[tuple[int, ...]] = set()
    want = []
    for r in map(tuple, a.tolist()):
        want.append(r not in seen)
        seen.add(r)
    assert first_occurrences(a).tolist() == want
