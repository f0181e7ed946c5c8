"""The sans-I/O core: framing and ARIA's checksum, the field codec, the login state machine.

Checked against ARIA's own bytes (a capture of ARIA's client talking to ARIA's server,
``session.pcap`` in the aria-peer folder) and with hypothesis round trips.
"""

from __future__ import annotations

import contextlib
import hashlib
import struct
from pathlib import Path

import pytest
from hypothesis import given, strategies as st

from mapkit.arnet.connection import ClientConnection, State
from mapkit.arnet.errors import AriaPermissionError, AriaProtocolError
from mapkit.arnet.events import Accepted, Data, Introduced, Ready, Rejected
from mapkit.arnet.packet import MAX_DATA, MAX_LENGTH, Fields, Payload, checksum, encode
from mapkit.arnet.reader import PacketReader
from mapkit.arnet.services import MapId, put_payloads
from tests.arnet.peer import PEER, require_peer


def reference_checksum(frame: bytes) -> int:
    """ArNetPacket::calcCheckSum as ARIA writes it (a plain loop)."""
    c, i, n = 0, 3, len(frame) - 4
    while n > 3:
        c = (c + ((frame[i] << 8) | frame[i + 1])) & 0xFFFF
        i += 2
        n -= 2
    if n > 0:
        c ^= frame[i]
    return c


def test_checksum_matches_captured_examples() -> None:
    assert encode(264) == bytes.fromhex("0f0c080008010009")  # getMapName request
    assert encode(264, b"office.map\0") == bytes.fromhex(
        "0f0c13000801"
    ) + b"office.map\0" + bytes.fromhex("a3bf")
    assert encode(268, b"\0")[-2:] == bytes.fromhex("000d")  # odd length: last byte not covered
    assert encode(6, b"\x01\x00\x00") == bytes.fromhex("0f0c0b000600010000" + "0007")


@given(st.integers(0, 0xFFFF), st.binary(max_size=2000))
def test_checksum_equals_arias_loop(command: int, data: bytes) -> None:
    frame = encode(command, data)
    assert struct.unpack(">H", frame[-2:])[0] == reference_checksum(frame) == checksum(frame)


@given(
    st.lists(st.tuples(st.integers(0, 0xFFFF), st.binary(max_size=3000)), max_size=8),
    st.lists(st.integers(1, 5000), min_size=1, max_size=20),
)
def test_reader_reassembles_any_split(packets: list[tuple[int, bytes]], cuts: list[int]) -> None:
    stream = b"".join(encode(c, d) for c, d in packets)
    r = PacketReader()
    got = []
    pos, k = 0, 0
    while pos < len(stream):
        step = cuts[k % len(cuts)]
        got.extend(r.feed(stream[pos : pos + step]))
        assert r.pending < MAX_LENGTH + step
        pos, k = pos + step, k + 1
    assert [(p.command, p.data) for p in got] == packets
    assert r.pending == 0


@given(st.binary(min_size=1, max_size=200), st.integers(0, 199))
def test_any_flipped_byte_is_caught(data: bytes, at: int) -> None:
    frame = bytearray(encode(300, data))
    i = at % len(frame)
    if len(frame) % 2 == 1 and i == len(frame) - 3:
        return  # ARIA's checksum does not cover the last data byte of an odd-length packet
    frame[i] ^= 0x40
    if i in (2, 3):  # a changed length: refused, or waited for (the driver's timeout ends it)
        with contextlib.suppress(AriaProtocolError):
            assert PacketReader().feed(bytes(frame)) == []
        return
    with pytest.raises(AriaProtocolError):
        PacketReader().feed(bytes(frame))


def test_reader_refuses_bad_headers_at_once() -> None:
    with pytest.raises(AriaProtocolError, match="where a packet must start with 0f0c"):
        PacketReader().feed(b"GET / HTTP/1.0\r\n")
    for length in (0, 7, MAX_LENGTH + 1, 0xFFFF):
        with pytest.raises(AriaProtocolError, match=f"announced a {length}-byte packet"):
            PacketReader().feed(b"\x0f\x0c" + struct.pack("<H", length))
    with pytest.raises(ValueError, match="do not fit one packet"):
        encode(300, b"x" * (MAX_DATA + 1))


values = st.lists(
    st.one_of(
        st.tuples(st.just("byte"), st.integers(-128, 127)),
        st.tuples(st.just("ubyte"), st.integers(0, 255)),
        st.tuples(st.just("byte2"), st.integers(-(1 << 15), (1 << 15) - 1)),
        st.tuples(st.just("ubyte2"), st.integers(0, 0xFFFF)),
        st.tuples(st.just("byte4"), st.integers(-(1 << 31), (1 << 31) - 1)),
        st.tuples(st.just("ubyte4"), st.integers(0, 0xFFFFFFFF)),
        st.tuples(
            st.just("string"),
            st.text(st.characters(codec="utf-8", blacklist_characters="\0"), max_size=40),
        ),
    ),
    max_size=30,
)


@given(values)
def test_fields_round_trip(items: list[tuple[str, object]]) -> None:
    p = Payload()
    for kind, v in items:
        getattr(p, kind)(v)
    f = Fields(p.bytes())
    assert [(kind, getattr(f, kind)()) for kind, _ in items] == items
    assert f.remaining == 0


@given(
    st.binary(max_size=100_000),
    st.text(st.characters(codec="utf-8", blacklist_characters="\0/"), min_size=1, max_size=30),
)
def test_put_payloads_carry_the_file(data: bytes, name: str) -> None:
    parts = list(put_payloads(name, data))
    assert all(len(encode(300, p)) <= MAX_LENGTH for p in parts)
    start, *chunks, done = (Fields(p) for p in parts)
    assert (start.ubyte2(), start.string(), done.ubyte2(), done.string()) == (0, name, 2, name)
    body = b""
    for c in chunks:
        assert c.ubyte2() == 1 and c.string() == name
        n = c.ubyte4()
        body += c.rest()
        assert n == len(c._data) - c._pos + n  # the count is the chunk's size
    assert body == data


def server_intro(key: bytes = b"k3y") -> bytes:
    return encode(
        2,
        Payload()
        .string("alpha")
        .ubyte2(7272)
        .ubyte4(1)
        .ubyte4(2)
        .raw(key + b"\0")
        .string("")
        .bytes(),
    )


def lists(names: dict[str, int], groups: str = "Map") -> bytes:
    a, b, c = (Payload().ubyte2(len(names)) for _ in range(3))
    for n, i in names.items():
        a.ubyte2(i).string(n).string("desc")
        b.ubyte2(i).string("args").string("rets")
        c.ubyte2(i).string(groups).string("RETURN_SINGLE|SLOW_PACKET")
    return encode(129, a.bytes()) + encode(131, b.bytes()) + encode(133, c.bytes())


def test_login_state_machine() -> None:
    conn = ClientConnection("admin", "secret1")
    assert conn.state is State.AWAIT_INTRODUCTION
    ev = conn.receive_data(server_intro(b"abc"))
    assert ev == [Introduced(7272, b"abc")]
    out = PacketReader().feed(conn.data_to_send())
    assert [p.command for p in out] == [2, 5]  # INTRODUCTION, then TCP_ONLY
    f = out[0].fields()
    assert (f.ubyte2(), f.string(), f.raw(16)) == (0, "admin", hashlib.md5(b"abcsecret1").digest())
    with pytest.raises(AriaProtocolError, match="cannot send 'getMapName'"):
        conn.request("getMapName")
    ev = conn.receive_data(encode(5) + lists({"getMapName": 300, "mapUpdated": 301}))
    assert ev[0] == Accepted() and isinstance(ev[1], Ready)
    assert conn.state.name == "READY"
    info = conn.commands["getMapName"]
    assert (info.id, info.group, info.flags, info.arguments) == (
        300,
        "Map",
        ("RETURN_SINGLE", "SLOW_PACKET"),
        "args",
    )
    conn.request("getMapName")
    conn.start_request("mapUpdated")
    sent = PacketReader().feed(conn.data_to_send())
    assert [(p.command, p.data) for p in sent] == [(300, b""), (129, struct.pack("<Hi", 301, -1))]
    assert conn.receive_data(encode(300, b"a.map\0")) == [Data("getMapName", 300, b"a.map\0")]
    with pytest.raises(AriaPermissionError, match="does not offer 'getFile' to user 'admin'"):
        conn.request("getFile")
    with pytest.raises(AriaProtocolError, match="command 999, which is not in"):
        conn.receive_data(encode(999))
    conn.close()
    assert PacketReader().feed(conn.data_to_send())[0].command == 1


def test_rejection_and_out_of_order_packets() -> None:
    conn = ClientConnection("admin", "x")
    conn.receive_data(server_intro())
    assert conn.receive_data(encode(6, b"\x01\x00\0")) == [Rejected(1, "")]
    with pytest.raises(
        AriaProtocolError, match="sent CONNECTED while waiting for the server's intro"
    ):
        ClientConnection().receive_data(encode(5))
    with pytest.raises(
        AriaProtocolError, match=r"sent data .* while waiting for the server's intro"
    ):
        ClientConnection().receive_data(encode(300))


def test_map_id_layout() -> None:
    data = (
        Payload()
        .string("")
        .string("office.map")
        .ubyte4(16)
        .raw(bytes(range(16)))
        .ubyte4(2291)
        .byte4(-5)
        .bytes()
    )
    mid = MapId.parse(Fields(data))
    assert (mid.file_name, mid.md5, mid.size, mid.timestamp) == (
        "office.map",
        bytes(range(16)).hex(),
        2291,
        -5,
    )
    with pytest.raises(AriaProtocolError, match="a 4096-byte map checksum"):
        MapId.parse(Fields(Payload().string("").string("x").ubyte4(4096).bytes()))


# -- ARIA's own session ----------------------------------------------------------------------


def tcp_streams(path: Path, port: int) -> list[tuple[bytes, bytes]]:
    """(client->server, server->client) bytes of each TCP connection to ``port`` in a pcap."""
    raw = path.read_bytes()
    endian = "<" if struct.unpack("<I", raw[:4])[0] in (0xA1B2C3D4, 0xA1B23C4D) else ">"
    link = struct.unpack(endian + "I", raw[20:24])[0]
    conns: dict[int, dict[str, dict[int, bytes]]] = {}
    order: list[int] = []
    off = 24
    while off + 16 <= len(raw):
        incl = struct.unpack(endian + "I", raw[off + 8 : off + 12])[0]
        frame = raw[off + 16 : off + 16 + incl]
        off += 16 + incl
        ip = frame[14:] if link == 1 else frame[16:] if link == 113 else frame[4:]
        if len(ip) < 20 or ip[0] >> 4 != 4 or ip[9] != 6:
            continue
        ihl = (ip[0] & 15) * 4
        tcp = ip[ihl : struct.unpack(">H", ip[2:4])[0]]
        sport, dport, seq = struct.unpack(">HHI", tcp[:8])
        payload = tcp[(tcp[12] >> 4) * 4 :]
        if port not in (sport, dport):
            continue
        client = dport if sport == port else sport
        if client not in conns:
            conns[client] = {"c": {}, "s": {}}
            order.append(client)
        if payload:
            conns[client]["c" if dport == port else "s"].setdefault(seq, payload)

    def join(segs: dict[int, bytes]) -> bytes:
        return b"".join(segs[k] for k in sorted(segs))

    return [(join(conns[c]["c"]), join(conns[c]["s"])) for c in order]


@pytest.fixture(scope="module")
def capture() -> list[tuple[bytes, bytes]]:
    require_peer()
    return tcp_streams(PEER / "session.pcap", 7273)


def test_arias_capture_decodes(capture: list[tuple[bytes, bytes]]) -> None:
    assert len(capture) == 9
    total = 0
    for c2s, s2c in capture:
        for stream in (c2s, s2c):
            r = PacketReader()
            total += len(r.feed(stream))  # every checksum verified
            assert r.pending == 0
    assert total > 200  # the TCP part of the 261 packets (the rest are UDP datagrams)
    # our login answer to each captured challenge is ARIA's own, byte for byte (but the UDP port)
    names: list[str] = []
    for c2s, s2c in capture[:8]:
        conn = ClientConnection("admin", "secret1")
        events = conn.receive_data(s2c)
        ours = PacketReader().feed(conn.data_to_send())[0]
        arias = PacketReader().feed(c2s)[0]
        assert ours.command == arias.command == 2 and ours.data[2:] == arias.data[2:]
        assert isinstance(events[1], Accepted) and isinstance(events[2], Ready)
        assert len(events[2].commands) == 40 and events[2].commands["getMapName"].id == 264
        names.extend(e.name for e in events if isinstance(e, Data))
    assert names[0] == "getMapName" and "getFile" in names and "mapUpdated" in names
    conn = ClientConnection("admin", "secret1")
    events = conn.receive_data(capture[8][1])
    assert events[-1] == Rejected(1, "")


def test_names_that_cannot_be_sent() -> None:
    from mapkit.arnet.errors import AriaValueError

    for bad in ("a\0b", "\ud800"):
        with pytest.raises(AriaValueError, match="cannot be sent to the robot"):
            Payload().string(bad)
    assert (
        Payload().string("caf\udce9").bytes() == b"caf\xe9\0"
    )  # undecodable bytes go back as they came
