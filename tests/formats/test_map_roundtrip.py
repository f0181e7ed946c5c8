"""Property round trips: model → text → model is the identity; mapkit reads back what it writes."""

from __future__ import annotations

import hashlib

from hypothesis import given

import mapkit
from mapkit.model import MapData
from tests.strategies import maps


@given(maps())
def test_model_text_model_is_identity(m: MapData) -> None:
    back = mapkit.loads(mapkit.dumpb(m))
    assert back == m


@given(maps())
def test_written_text_reads_back_the_same(m: MapData) -> None:
    text = mapkit.dumpb(m)
    again = mapkit.loads(text)
    assert mapkit.dumpb(again) == text
    assert again.md5 == hashlib.md5(text).hexdigest()
    _m, issues = mapkit.recover(text)
    assert [i for i in issues if i.code != mapkit.IssueCode.UNKNOWN_LINE] == []
