"""The bounded JSON decoder every protocol message goes through (mapkit/transfer/wirejson.py)."""

from __future__ import annotations

import contextlib
import json
import sys

import pytest
from hypothesis import given, strategies as st

from mapkit.transfer.protocol import Frame, FrameType, ProtocolError, parse_json
from mapkit.transfer.wirejson import (
    MAX_DEPTH,
    SCHEMAS,
    WireJSONError,
    check_fields,
    decode_object,
    deeper_than,
    json_depth,
)

# what protocol payloads are made of: objects of strings, 64-bit integers, finite floats, lists
_scalars = (
    st.none()
    | st.booleans()
    | st.integers(-(1 << 63), 1 << 64)
    | st.floats(allow_nan=False, allow_infinity=False)
    | st.text()
)
_values = st.recursive(
    _scalars,
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(), inner, max_size=4),
    max_leaves=20,
)
_objects = st.dictionaries(st.text(), _values, max_size=6)


@given(_objects)
def test_round_trip_of_every_payload_within_the_limits(obj) -> None:
    text = json.dumps(obj, ensure_ascii=False).encode("utf-8")
    if json_depth(text) <= MAX_DEPTH:
        assert decode_object(text) == obj


@given(st.binary(max_size=300))
def test_any_bytes_give_an_object_or_wirejsonerror(data) -> None:
    with contextlib.suppress(WireJSONError):
        assert isinstance(decode_object(data), dict)


@given(st.text(alphabet='[]{}"\\ab,:', max_size=200))
def test_depth_is_an_upper_bound_of_what_json_reaches(text) -> None:
    data = text.encode()
    try:
        obj = json.loads(data)
    except ValueError:
        return

    def depth(v) -> int:
        if isinstance(v, list):
            return 1 + max((depth(x) for x in v), default=0)
        if isinstance(v, dict):
            return 1 + max((depth(x) for x in v.values()), default=0)
        return 0

    assert json_depth(data) == depth(obj)
    for limit in range(4):
        assert deeper_than(data, limit) == (depth(obj) > limit)


@pytest.mark.parametrize(
    "payload, why",
    [
        (b"[" * 100_000, "nested deeper than 16 levels"),
        (b'{"a":' * 100_000, "nested deeper than 16 levels"),
        (b'{"a":' + b"[" * 16 + b"]" * 16 + b"}", "nested deeper than 16 levels"),
        (b"[]" * 100_000 + b"[", "nested deeper than 16 levels"),
        (b'{"size":' + b"9" * 50_000 + b"}", "an integer of 50000 digits"),
        (b'{"size":' + b"9" * 21 + b"}", "an integer of 21 digits"),
        (b'{"t":1e400}', "out of range"),
        (b'{"t":-Infinity}', "-Infinity is not a JSON number"),
        (b'{"t":NaN}', "NaN is not a JSON number"),
        (b'{"t":0.' + b"1" * 50 + b"}", "a number of 52 characters"),
        (b'{"name":"\\udc00.map"}', "lone UTF-16 surrogate"),
        (b'{"\\ud800":1}', "lone UTF-16 surrogate"),
        (b"\xc3\x28", "not UTF-8 JSON"),
        (b"[1, 2]", "not a JSON object"),
        (b'"x"', "not a JSON object"),
        (b"{" + b" " * (1 << 20) + b"}", "bytes (at most 1048576)"),
    ],
)
def test_hostile_payloads_are_refused(payload, why) -> None:
    with pytest.raises(WireJSONError, match=why.replace("(", r"\(").replace(")", r"\)")):
        decode_object(payload)


def test_brackets_inside_strings_do_not_count_and_escapes_are_followed() -> None:
    assert decode_object(b'{"s":"' + b"[" * 100_000 + b'"}')["s"] == "[" * 100_000
    assert decode_object(b'{"a":' + b"[" * 15 + b"]" * 15 + b"}")  # 16 deep: the limit
    assert json_depth(b'{"s":"\\"[[[[","t":[1]}') == 2
    assert decode_object(b'{"pair":"\\ud83d\\ude00"}') == {"pair": "\U0001f600"}


def test_the_limits_leave_the_recursion_limit_far_away() -> None:
    assert sys.getrecursionlimit() > MAX_DEPTH * 4


def test_schemas_check_the_types_of_known_fields_only() -> None:
    check_fields({"name": "a.map", "size": 3, "future": [1, {"x": None}]}, SCHEMAS[FrameType.OFFER])
    for bad in (
        {"size": True},
        {"size": 1.5},
        {"name": 3},
        {"md5": 5},
        {"mtime": "x"},
        {"window": None},
    ):
        with pytest.raises(WireJSONError, match="must be"):
            check_fields(bad, SCHEMAS[FrameType.OFFER], "OFFER")
    with pytest.raises(WireJSONError, match=r"ACK.sack\[1\]\[0\] must be an integer"):
        check_fields({"sack": [[1, 2], ["a", 3]]}, SCHEMAS[FrameType.ACK], "ACK")
    with pytest.raises(WireJSONError, match=r"LISTING\.maps must be a list"):
        check_fields({"maps": {"name": "x"}}, SCHEMAS[FrameType.LISTING], "LISTING")
    with pytest.raises(WireJSONError, match=r"LISTING\.maps\[0\]\.active must be true or false"):
        check_fields({"maps": [{"name": "x", "active": 1}]}, SCHEMAS[FrameType.LISTING], "LISTING")


def test_every_control_frame_has_a_schema_and_frames_use_it() -> None:
    for t in FrameType:
        if t not in (
            FrameType.DATA,
            FrameType.PING,
            FrameType.PONG,
            FrameType.BYE,
            FrameType.DONE,
            FrameType.LIST,
        ):
            assert t in SCHEMAS, t.name
    with pytest.raises(ProtocolError, match=r"OFFER payload refused: OFFER\.size must be"):
        Frame(FrameType.OFFER, 1, 1, b'{"size":"12"}').json()
    with pytest.raises(ProtocolError, match="HELLO payload refused: nested"):
        parse_json(b"[" * 100_000, "HELLO")


def test_the_spec_states_the_limits_the_code_applies() -> None:
    from pathlib import Path

    from mapkit.transfer.wirejson import MAX_INT_DIGITS

    spec = (Path(__file__).resolve().parents[2] / "docs" / "transfer-protocol.md").read_text()
    assert f"at most **{MAX_DEPTH}** levels" in spec
    assert f"integers of at most **{MAX_INT_DIGITS}** digits" in spec
    refused = [
        b"[" * 100_000,
        b'{"a":' * 100_000,
        b'{"size":' + b"9" * 50_000 + b"}",
        b'{"t":1e400}',
        b'{"t":NaN}',
        b'{"name":"\\udc00.map"}',
        b"\xc3\x28",
        b"[1,2]",
    ]
    for vector in refused:
        with pytest.raises(WireJSONError):
            decode_object(vector)
    for vector in (b'{"size":"12"}', b'{"size":true}'):
        with pytest.raises(ProtocolError):
            Frame(FrameType.OFFER, 1, 1, vector).json()
    accepted = [
        b'{"s":"' + b"[" * 1000 + b'"}',
        b'{"pair":"\\ud83d\\ude00"}',
        b'{"unknown":[[[1]]],"x":{"y":true}}',
    ]
    for vector in accepted:
        decode_object(vector)
