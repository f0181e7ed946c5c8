"""The sans-I/O core over an in-memory link: frames, handshake, and whole transfers under any
loss / corruption / duplication / reorder pattern (hypothesis)."""

from __future__ import annotations

import hashlib
import os
import random
import zlib
from dataclasses import dataclass, field

import pytest
from hypothesis import given, settings, strategies as st

from mapkit.errors import TransferError
from mapkit.transfer.protocol import (
    AUTH_METHODS,
    HEADER_SIZE,
    AuthenticationError,
    Channel,
    ChunkReceived,
    ClientHandshake,
    Damaged,
    Frame,
    FrameType,
    Offer,
    Out,
    ProtocolError,
    Receiver,
    Rejected,
    ReplayError,
    Sender,
    ServerHandshake,
    Status,
    TransferComplete,
    crc32_strip,
    decode_bitmap,
    dump_json,
    encode_bitmap,
    encode_frame,
    load_secret,
    prepare_payload,
    ranges_from_bitmap,
)

SECRET = b"0123456789abcdef-test-secret"


# -- frames ----------------------------------------------------------------------------------------


@given(
    st.binary(max_size=3000),
    st.integers(0, 2**32 - 1),
    st.sampled_from(list(FrameType)),
    st.booleans(),
    st.sampled_from(AUTH_METHODS),
)
def test_frame_round_trip(
    payload: bytes, ref: int, ftype: FrameType, keyed: bool, auth: str
) -> None:
    tx, rx = Channel(initiator=True, session=0xABCDEF), Channel(initiator=False)
    if keyed:
        tx.install_keys(b"k" * 32, b"s" * 32, auth)
        rx.install_keys(b"k" * 32, b"s" * 32, auth)
    wire = tx.encode(Out(ftype, payload, ref=ref))
    rx.receive_data(wire)
    ev = rx.next_event()
    assert isinstance(ev, Frame)
    assert (ev.type, ev.ref, ev.payload, ev.seq, ev.session) == (ftype, ref, payload, 1, 0xABCDEF)
    assert ev.authentic == (keyed and ftype not in (FrameType.HELLO, FrameType.HELLO_ACK))
    assert rx.next_event() is None


@given(
    st.one_of(st.binary(min_size=1, max_size=600), st.binary(min_size=4096, max_size=5000)),
    st.sampled_from(AUTH_METHODS),
    st.data(),
)
def test_any_single_bit_flip_is_detected(payload: bytes, auth: str, data: st.DataObject) -> None:
    # small payloads: CRC first; from 4 KiB: the tag first, the CRC only when the tag fails
    tx, rx = Channel(initiator=True, session=5), Channel(initiator=False, ordered=True)
    tx.install_keys(b"k" * 32, b"s" * 32, auth)
    rx.install_keys(b"k" * 32, b"s" * 32, auth)
    wire = bytearray(tx.encode(Out(FrameType.DATA, payload, ref=3)))
    bit = data.draw(st.integers(0, len(wire) * 8 - 1))
    wire[bit // 8] ^= 1 << (bit % 8)
    rx.receive_data(bytes(wire))
    ev = rx.next_event()
    # a flipped frame is never delivered as a frame: it is damaged or skipped as garbage
    assert not isinstance(ev, Frame)
    if bit // 8 >= HEADER_SIZE:
        assert ev == Damaged(FrameType.DATA, 1, 3)


def test_stream_resyncs_after_garbage_and_split_reads() -> None:
    tx, rx = Channel(initiator=True, session=9), Channel(initiator=False)
    frames = [tx.encode(Out(FrameType.PING, bytes([i]) * i, ref=i)) for i in range(1, 6)]
    wire = b"junk" + frames[0] + b"MKT1garbage" + b"".join(frames[1:])
    got = []
    for i in range(0, len(wire), 7):
        rx.receive_data(wire[i : i + 7])
        while (ev := rx.next_event()) is not None:
            got.append(ev)
    assert [f.ref for f in got] == [1, 2, 3, 4, 5]
    assert rx.stats["garbage"] == len(b"junk") + len(b"MKT1garbage")


@given(
    st.lists(st.tuples(st.binary(max_size=300), st.binary(max_size=20)), min_size=1, max_size=8),
    st.lists(st.integers(1, 200), min_size=1, max_size=10),
)
def test_stream_decoder_any_split_any_garbage(frames, splits) -> None:
    tx, rx = Channel(initiator=True, session=3), Channel(initiator=False)
    tx.install_keys(b"k" * 32, b"s" * 32)
    rx.install_keys(b"k" * 32, b"s" * 32)
    wire = b""
    for payload, junk in frames:
        wire += junk.replace(b"M", b"m") + tx.encode(Out(FrameType.DATA, payload, ref=len(payload)))
    got, pos, k = [], 0, 0
    while pos < len(wire):
        step = splits[k % len(splits)]
        rx.receive_data(wire[pos : pos + step])
        pos, k = pos + step, k + 1
        while (ev := rx.next_event()) is not None:
            got.append(ev)
    assert [f.payload for f in got] == [p for p, _ in frames]
    assert rx.stats["garbage"] == sum(len(j) for _, j in frames)


@given(
    st.lists(st.tuples(st.binary(max_size=2000), st.binary(max_size=20)), min_size=1, max_size=6),
    st.lists(st.integers(1, 3000), min_size=1, max_size=10),
    st.integers(1, 500),
    st.sampled_from([None, *AUTH_METHODS]),
)
def test_payloads_received_in_place_any_split(frames, reads, threshold, auth) -> None:
    """Large payloads go straight into their own buffer (receive_into), whatever the reads."""
    tx = Channel(initiator=True, session=3)
    rx = Channel(initiator=False, direct_threshold=threshold)
    if auth:
        tx.install_keys(b"k" * 32, b"s" * 32, auth)
        rx.install_keys(b"k" * 32, b"s" * 32, auth)
    wire = b""
    for payload, junk in frames:
        wire += junk.replace(b"M", b"m") + tx.encode(Out(FrameType.DATA, payload, ref=len(payload)))
    got, pos, k = [], 0, 0

    def recv(view: memoryview) -> int:
        n = min(len(view), reads[k % len(reads)], len(wire) - pos)
        view[:n] = wire[pos : pos + n]
        return n

    while pos < len(wire):
        n = rx.receive_into(recv, 1024)
        pos, k = pos + n, k + 1
        while (ev := rx.next_event()) is not None:
            got.append(ev)
    assert [bytes(f.payload) for f in got] == [p for p, _ in frames]
    assert all(f.authentic == bool(auth) for f in got)
    assert all(f.crc == zlib.crc32(p) for f, (p, _) in zip(got, frames, strict=True))
    assert rx.stats["garbage"] == sum(len(j) for _, j in frames) and rx.buffered == 0


def test_damaged_large_payload_received_in_place_is_reported() -> None:
    tx, rx = Channel(initiator=True, session=3), Channel(initiator=False, direct_threshold=100)
    tx.install_keys(b"k" * 32, b"s" * 32, "blake2b")
    rx.install_keys(b"k" * 32, b"s" * 32, "blake2b")
    good = tx.encode(Out(FrameType.DATA, bytes(range(256)) * 20, ref=7))
    bad = bytearray(tx.encode(Out(FrameType.DATA, bytes(range(256)) * 20, ref=8)))
    bad[HEADER_SIZE + 4000] ^= 0x10
    wire = bytes(bad) + good
    pos = 0
    events = []
    while pos < len(wire):
        piece = wire[pos : pos + 700]
        pos += rx.receive_into(lambda v, piece=piece: _fill(v, piece), 1024)
        while (ev := rx.next_event()) is not None:
            events.append(ev)
    assert events[0] == Damaged(FrameType.DATA, 2, 8)
    assert isinstance(events[1], Frame) and events[1].ref == 7
    assert isinstance(events[1].payload, bytearray)


def _fill(view: memoryview, data: bytes) -> int:
    n = min(len(view), len(data))
    view[:n] = data[:n]
    return n


@given(
    st.binary(max_size=3000),
    st.sampled_from([None, *AUTH_METHODS]),
    st.sampled_from([None, *AUTH_METHODS]),
    st.booleans(),
    st.integers(1, 2**32 - 1),
)
def test_prepared_payloads_encode_exactly_like_plain_ones(
    payload, prep_auth, auth, same_key, seq
) -> None:
    """Whatever was prepared (or for whichever key and algorithm), the frame is the same."""
    key = b"k" * 32 if auth else None
    p = prepare_payload(payload, b"k" * 32 if same_key else b"x" * 32, prep_auth or "none")
    alg = auth or "blake2b"
    plain = encode_frame(FrameType.DATA, payload, session=9, seq=seq, key=key, auth=alg)
    fast = encode_frame(FrameType.DATA, p, session=9, seq=seq, key=key, auth=alg)
    assert fast == plain


def test_spec_test_vectors_match_the_code_and_an_independent_tag() -> None:
    """The vectors in docs/transfer-protocol.md are what the code sends, and the tags follow
    from hashlib alone (payload first for BLAKE2b, header first for HMAC-SHA256)."""
    import hmac
    import re
    from pathlib import Path

    spec = (Path(__file__).resolve().parents[2] / "docs" / "transfer-protocol.md").read_text()
    row = r"^\| `(blake2b|hmac-sha256)` \| `([0-9a-f]{72})` \| `([0-9a-f]{32})` \|$"
    rows = re.findall(row, spec, re.M)
    assert [r[0] for r in rows] == ["blake2b", "hmac-sha256"]
    key, payload = bytes(range(32)), b"MKT1 test"
    for auth, head_hex, tag_hex in rows:
        head, body, tag = encode_frame(
            FrameType.DATA, payload, session=0x0102030405060708, seq=1, key=key, auth=auth
        )
        assert (head.hex(), bytes(body), tag.hex()) == (head_hex, payload, tag_hex)
        if auth == "blake2b":
            mine = hashlib.blake2b(payload + head[:28], digest_size=16, key=key).digest()
        else:
            mine = hmac.new(key, head[:28] + payload, hashlib.sha256).digest()[:16]
        assert mine == tag


def test_prepared_reader_falls_back_when_the_file_changed(tmp_path) -> None:
    from mapkit.transfer.store import PreparedReader

    f = tmp_path / "f.bin"
    f.write_bytes(b"a" * 10_000)
    ch = Channel(initiator=True, session=1)
    ch.install_keys(b"k" * 32, b"s" * 32, "blake2b")
    rx = Channel(initiator=False)
    rx.install_keys(b"k" * 32, b"s" * 32, "blake2b")
    fd = os.open(f, os.O_RDWR)
    try:
        reader = PreparedReader(fd, 10_000, 4096, ch.preparer()).start()
        reader._thread.join()
        os.pwrite(fd, b"B" * 10, 4096)  # chunk 1 changes after its pass
        chunks = [reader(i) for i in range(3)]
        reader.close()
    finally:
        os.close(fd)
    assert [c._state is not None for c in chunks] == [True, False, True]
    for i, c in enumerate(chunks):  # every frame still carries the right tag for its bytes
        rx.receive_data(ch.encode(Out(FrameType.DATA, c, ref=i)))
        ev = rx.next_event()
        assert isinstance(ev, Frame) and ev.authentic and bytes(ev.payload) == bytes(c.data)
    assert bytes(chunks[1].data)[:10] == b"B" * 10


@given(st.binary(max_size=3000), st.binary(max_size=64))
def test_crc32_strip_undoes_the_tail(data: bytes, tail: bytes) -> None:
    assert crc32_strip(zlib.crc32(data + tail), tail) == zlib.crc32(data)


def test_replayed_frame_is_refused_on_a_stream() -> None:
    tx, rx = Channel(initiator=True, session=1), Channel(initiator=False)
    tx.install_keys(b"k" * 32, b"s" * 32)
    rx.install_keys(b"k" * 32, b"s" * 32)
    a = tx.encode(Out(FrameType.PING, b"{}"))
    rx.receive_data(a + a)
    assert isinstance(rx.next_event(), Frame)
    with pytest.raises(ReplayError, match=r"replayed frame: PING seq 1"):
        rx.next_event()


def test_duplicates_are_dropped_on_a_message_transport() -> None:
    tx, rx = Channel(initiator=True, session=1), Channel(initiator=False, ordered=False)
    a, b = tx.encode(Out(FrameType.PING)), tx.encode(Out(FrameType.PING))
    for msg in (b, a, b, a):
        rx.receive_message(msg)
        rx.next_event()
    assert rx.stats["frames_in"] == 2 and rx.stats["duplicates"] == 2


def test_forged_and_untagged_frames_are_refused() -> None:
    tx, rx = Channel(initiator=True, session=1), Channel(initiator=False)
    rx.install_keys(b"k" * 32, b"s" * 32)
    tx.install_keys(b"x" * 32, b"y" * 32)  # another key
    rx.receive_data(tx.encode(Out(FrameType.LIST, b"{}")))
    with pytest.raises(AuthenticationError, match=r"LIST frame .seq 1. has a wrong tag"):
        rx.next_event()
    rx2 = Channel(initiator=False)
    rx2.install_keys(b"k" * 32, b"s" * 32)
    head, body, _ = encode_frame(FrameType.LIST, b"{}", session=1, seq=1)
    rx2.receive_data(head + body)
    with pytest.raises(AuthenticationError, match=r"has no tag"):
        rx2.next_event()


def test_oversized_and_foreign_frames() -> None:
    # a header (with valid CRCs) announcing a payload beyond every limit is refused at once
    head = bytearray(encode_frame(FrameType.DATA, b"", session=1, seq=1)[0])
    head[24:28] = (1 << 30).to_bytes(4, "big")
    head[32:36] = zlib.crc32(bytes(head[:32])).to_bytes(4, "big")
    rx = Channel(initiator=False)
    rx.receive_data(bytes(head))
    with pytest.raises(ProtocolError, match=r"DATA frame of 1073741824 bytes exceeds the limit"):
        rx.next_event()
    ordered = Channel(initiator=False, session=2)
    ordered.receive_data(b"".join(encode_frame(FrameType.PING, session=3, seq=1)))
    with pytest.raises(ProtocolError, match=r"frame for session 0000000000000003"):
        ordered.next_event()


def test_bitmaps() -> None:
    rng = random.Random(4)
    for n in (0, 1, 7, 8, 9, 100, 1001):
        have = bytearray(rng.random() < 0.5 for _ in range(n))
        assert decode_bitmap(encode_bitmap(have), n) == have
        assert sum(b - a for a, b in ranges_from_bitmap(have)) == sum(have)
    with pytest.raises(ProtocolError, match=r"bitmap has 1 bytes, expected 2"):
        decode_bitmap("AA==", 9)


def test_secret_sources(tmp_path) -> None:
    f = tmp_path / "s"
    f.write_text("a-long-enough-secret-value\n")
    assert load_secret(path=f, env={}) == b"a-long-enough-secret-value"
    assert load_secret(env={"MAPKIT_SECRET_FILE": str(f)}) == b"a-long-enough-secret-value"
    with pytest.raises(TransferError, match=r"the secret has 5 bytes; use at least 16"):
        load_secret(env={"MAPKIT_SECRET": "short"})
    with pytest.raises(TransferError, match=r"cannot read the secret"):
        load_secret(path=tmp_path / "missing", env={})


# -- simulated link -------------------------------------------------------------------------------


@dataclass
class Link:
    """Two one-way queues of messages with an adversary deciding each message's fate."""

    faults: list[tuple[str, int]]
    rate: float
    seed: int
    ordered: bool
    queues: dict[str, list[bytes]] = field(default_factory=lambda: {"c2s": [], "s2c": []})
    sent: int = 0

    def __post_init__(self) -> None:
        self.rng = random.Random(self.seed)

    def send(self, direction: str, msg: bytes) -> None:
        if self.sent < len(self.faults):
            action, arg = self.faults[self.sent]
        elif self.rng.random() < self.rate:
            action, arg = (
                self.rng.choice(["drop", "flip", "dup", "late"]),
                self.rng.randrange(1 << 30),
            )
        else:
            action, arg = "ok", 0
        self.sent += 1
        q = self.queues[direction]
        if self.ordered and action in ("dup", "late"):
            action = "ok"
        if action == "drop":
            return
        if action == "flip":
            m = bytearray(msg)
            bit = arg % (len(m) * 8)
            m[bit // 8] ^= 1 << (bit % 8)
            msg = bytes(m)
        if action == "dup":
            q.append(msg)
        if action == "late" and q:
            q.insert(arg % len(q), msg)
            return
        q.append(msg)


faults_st = st.lists(
    st.tuples(st.sampled_from(["ok", "drop", "flip", "dup", "late"]), st.integers(0, 1 << 30)),
    max_size=40,
)


def run_push(
    data: bytes,
    chunk_size: int,
    link: Link,
    *,
    secret: bytes | None,
    window: int = 4,
    have: bytearray | None = None,
    auth: tuple[str, ...] = AUTH_METHODS,
) -> tuple[Sender, Receiver | None, bytes, list[Exception]]:
    """Handshake + push over ``link`` in simulated time. Returns the machines and the bytes."""
    session = 0x1234
    cch = Channel(initiator=True, session=session, ordered=link.ordered)
    sch = Channel(initiator=False, ordered=link.ordered)
    chs = ClientHandshake(cch, secret, rto=1.0, max_tries=8, idle_timeout=60, auth_methods=auth)
    shs = ServerHandshake(sch, secret, insecure=secret is None, idle_timeout=60)
    offer = Offer.for_bytes("f.map", data, chunk_size=chunk_size)
    tx = Sender(
        offer,
        lambda i: data[i * chunk_size : (i + 1) * chunk_size],
        ref=1,
        window=window,
        rto=1.0,
        max_tries=10,
        idle_timeout=60,
    )
    rx: Receiver | None = None
    store = bytearray(len(data))
    for i in range(len(have or ())):
        if have[i]:  # the chunks a resumed receiver already holds
            store[i * chunk_size : (i + 1) * chunk_size] = data[
                i * chunk_size : (i + 1) * chunk_size
            ]
    errors: list[Exception] = []
    now = 0.0
    client = [chs, tx]  # machines in turn
    server_hs_done = False

    def deliver(channel: Channel, msg: bytes) -> list[Frame | Damaged]:
        out = []
        if link.ordered:
            channel.receive_data(msg)
        else:
            channel.receive_message(msg)
        while True:
            ev = channel.next_event()
            if ev is None:
                return out
            out.append(ev)

    def c_send(outs: list[Out]) -> None:
        for o in outs:
            link.send("c2s", cch.encode(o))

    def s_send(outs: list[Out]) -> None:
        for o in outs:
            link.send("s2c", sch.encode(o))

    c_send(chs.start(now))
    shs.start(now)
    for _step in range(20000):
        cur = client[0]
        if cur is chs and chs.finished and not chs.error:
            client.pop(0)
            cur = tx
            c_send(tx.start(now))
        if cur.finished and (rx is None or rx.finished or cur.error):
            break
        moved = False
        for direction in ("c2s", "s2c"):
            q = link.queues[direction]
            if not q:
                continue
            msg = q.pop(0)
            moved = True
            try:
                if direction == "c2s":
                    for ev in deliver(sch, msg):
                        if not server_hs_done:
                            s_send(shs.handle(ev, now))
                            server_hs_done = shs.finished
                            if shs.error:
                                raise shs.error
                            continue
                        if isinstance(ev, Frame) and ev.type == FrameType.AUTH:
                            s_send(shs.resend(ev))
                            continue
                        if rx is None and isinstance(ev, Frame) and ev.type == FrameType.OFFER:
                            rx = Receiver(
                                Offer.from_json(ev.json()), ref=ev.ref, have=have, window=window
                            )
                            s_send(rx.accept(now))
                        elif rx is not None:
                            s_send(rx.handle(ev, now))
                        if rx is not None:
                            for e in rx.pop_events():
                                if isinstance(e, ChunkReceived):
                                    assert data[e.offset : e.offset + len(e.data)] == e.data
                                    store[e.offset : e.offset + len(e.data)] = e.data
                                elif isinstance(e, TransferComplete):
                                    got = hashlib.sha256(store).hexdigest()
                                    assert got == e.offer.sha256  # the core never assembles wrong
                                    s_send(rx.verified({"sha256": got}, now))
                else:
                    for ev in deliver(cch, msg):
                        c_send(cur.handle(ev, now))
            except (ProtocolError, Rejected) as err:
                errors.append(err)
                return tx, rx, bytes(store), errors
        if not moved:
            deadlines = [
                d for d in (cur.deadline(), rx.deadline() if rx else None) if d is not None
            ]
            if not deadlines:
                break
            now = max(now, min(deadlines))
            c_send(cur.poll(now))
            if rx is not None:
                s_send(rx.poll(now))
        if cur.error is not None:
            break
    if chs.error is not None:
        errors.append(chs.error)
    return tx, rx, bytes(store), errors


@settings(max_examples=80)
@given(
    data=st.binary(max_size=5000),
    chunk_size=st.integers(1, 700),
    faults=faults_st,
    rate=st.sampled_from([0.0, 0.05, 0.2]),
    seed=st.integers(0, 1000),
    ordered=st.booleans(),
    auth=st.sampled_from([None, *AUTH_METHODS]),
    window=st.integers(1, 8),
)
def test_push_over_a_hostile_link_delivers_exactly_or_fails_cleanly(
    data: bytes,
    chunk_size: int,
    faults: list[tuple[str, int]],
    rate: float,
    seed: int,
    ordered: bool,
    auth: str | None,
    window: int,
) -> None:
    chunk_size = max(chunk_size, len(data) // 200 + 1)  # keep the number of chunks bounded
    link = Link(faults, rate, seed, ordered)
    tx, rx, got, errors = run_push(
        data,
        chunk_size,
        link,
        secret=SECRET if auth else None,
        window=window,
        auth=(auth,) if auth else AUTH_METHODS,
    )
    if tx.finished and tx.error is None:
        assert rx is not None and rx.finished and rx.error is None
        assert got == data
        assert tx.result["sha256"] == hashlib.sha256(data).hexdigest()
    else:
        # failing cleanly: a TransferError with a message, never a wrong file
        err = tx.error or (errors[0] if errors else None) or (rx.error if rx else None)
        assert isinstance(err, TransferError) and str(err)
        if rx is not None and rx.complete:
            assert got == data


@given(
    data=st.binary(min_size=1, max_size=4000),
    chunk_size=st.integers(1, 300),
    seed=st.integers(0, 99),
)
def test_resume_sends_only_missing_chunks(data: bytes, chunk_size: int, seed: int) -> None:
    offer = Offer.for_bytes("f.2d", data, chunk_size=chunk_size)
    rng = random.Random(seed)
    have = bytearray(rng.random() < 0.5 for _ in range(offer.chunks))
    tx, _, got, errors = run_push(
        data, chunk_size, Link([], 0.0, seed, True), secret=SECRET, have=have
    )
    assert not errors and tx.error is None
    # the receiver's store only got the chunks it lacked; they are exactly right
    assert tx.sent_indices == {i for i in range(offer.chunks) if not have[i]}
    assert tx.chunks_skipped == sum(have)
    for i in tx.sent_indices:
        assert (
            got[i * chunk_size : (i + 1) * chunk_size]
            == data[i * chunk_size : (i + 1) * chunk_size]
        )


def test_wrong_secret_is_refused_with_a_reason() -> None:
    cch, sch = Channel(initiator=True, session=1), Channel(initiator=False)
    chs = ClientHandshake(cch, b"x" * 20)
    shs = ServerHandshake(sch, SECRET)
    sch.receive_data(b"".join(cch.encode(o) for o in chs.start(0)))
    cch.receive_data(b"".join(sch.encode(o) for o in shs.handle(sch.next_event(), 0)))
    sch.receive_data(b"".join(cch.encode(o) for o in chs.handle(cch.next_event(), 0)))
    with pytest.raises(AuthenticationError, match=r"AUTH frame .seq 2. has a wrong tag"):
        sch.next_event()


@pytest.mark.parametrize(
    ("client_secret", "server_secret", "insecure", "match"),
    [
        (None, SECRET, False, "auth_required: this server requires authentication"),
        (SECRET, None, True, "auth_required: this server has no shared secret"),
    ],
)
def test_auth_mode_mismatch(client_secret, server_secret, insecure, match) -> None:
    cch, sch = Channel(initiator=True, session=1), Channel(initiator=False)
    chs = ClientHandshake(cch, client_secret)
    shs = ServerHandshake(sch, server_secret, insecure=insecure)
    sch.receive_data(b"".join(cch.encode(o) for o in chs.start(0)))
    cch.receive_data(b"".join(sch.encode(o) for o in shs.handle(sch.next_event(), 0)))
    chs.handle(cch.next_event(), 0)
    assert isinstance(chs.error, Rejected) and chs.error.status in (Status.AUTH_REQUIRED,)
    assert match in str(chs.error)


def _handshake(
    client: ClientHandshake, server: ServerHandshake, cch: Channel, sch: Channel, tamper=None
) -> None:
    """Run a handshake to its end; ``tamper`` may rewrite the HELLO (a man in the middle)."""
    hello = b"".join(cch.encode(o) for o in client.start(0))
    sch.receive_data(tamper(hello) if tamper else hello)
    for _ in range(3):
        cch.receive_data(b"".join(sch.encode(o) for o in server.handle(sch.next_event(), 0)))
        out = client.handle(cch.next_event(), 0)
        if client.finished or not out:
            return
        sch.receive_data(b"".join(cch.encode(o) for o in out))


@pytest.mark.parametrize(
    ("offered", "accepted", "chosen"),
    [
        (AUTH_METHODS, AUTH_METHODS, "blake2b"),
        (("hmac-sha256", "blake2b"), AUTH_METHODS, "hmac-sha256"),  # the client's preference wins
        (AUTH_METHODS, ("hmac-sha256",), "hmac-sha256"),
        (("blake2b",), ("blake2b",), "blake2b"),
    ],
)
def test_tag_algorithm_is_negotiated(offered, accepted, chosen) -> None:
    cch, sch = Channel(initiator=True, session=1), Channel(initiator=False)
    chs = ClientHandshake(cch, SECRET, auth_methods=offered)
    shs = ServerHandshake(sch, SECRET, auth_methods=accepted)
    _handshake(chs, shs, cch, sch)
    assert chs.finished and chs.error is None and shs.finished
    assert chs.auth == shs.auth == cch.auth == sch.auth == chosen
    # tagged with the chosen algorithm: a frame checks on the other side
    sch.receive_data(cch.encode(Out(FrameType.LIST, b"{}", ref=1)))
    ev = sch.next_event()
    assert isinstance(ev, Frame) and ev.authentic


def test_no_common_tag_algorithm_is_refused() -> None:
    cch, sch = Channel(initiator=True, session=1), Channel(initiator=False)
    chs = ClientHandshake(cch, SECRET, auth_methods=("blake2b",))
    shs = ServerHandshake(sch, SECRET, auth_methods=("hmac-sha256",))
    _handshake(chs, shs, cch, sch)
    assert isinstance(chs.error, Rejected) and chs.error.status == Status.AUTH_REQUIRED
    assert (
        "no common auth method: the client offers ['blake2b'], this server accepts ['hmac-sha256']"
    ) in str(chs.error)


def test_a_single_string_auth_is_still_understood() -> None:
    """A HELLO with ``"auth": "hmac-sha256"`` (the first MKT/1 clients) gets HMAC-SHA256."""
    sch = Channel(initiator=False)
    shs = ServerHandshake(sch, SECRET)
    hello = {
        "versions": [1],
        "nonce": "00" * 32,
        "auth": "hmac-sha256",
        "peer": "old",
        "software": "x",
    }
    old_client = Channel(initiator=True, session=4)
    sch.receive_data(old_client.encode(Out(FrameType.HELLO, dump_json(hello))))
    (ack,) = shs.handle(sch.next_event(), 0)
    assert ack.type == FrameType.HELLO_ACK and b'"auth":"hmac-sha256"' in bytes(ack.payload)
    assert sch.auth == "hmac-sha256"


def test_downgrade_of_the_tag_algorithm_is_detected() -> None:
    """A man in the middle who strips BLAKE2b from the HELLO breaks the proofs (transcript)."""
    cch, sch = Channel(initiator=True, session=1), Channel(initiator=False)
    chs = ClientHandshake(cch, SECRET)
    shs = ServerHandshake(sch, SECRET)

    def strip(wire: bytes) -> bytes:
        rx = Channel(initiator=False)
        rx.receive_data(wire)
        f = rx.next_event()
        d = f.json()
        d["auth"] = ["hmac-sha256"]
        return Channel(initiator=True, session=1).encode(Out(FrameType.HELLO, dump_json(d)))

    with pytest.raises(AuthenticationError, match=r"AUTH frame .seq 2. has a wrong tag"):
        _handshake(chs, shs, cch, sch, tamper=strip)
    assert shs.auth == "hmac-sha256" and not shs.finished


def test_server_that_cannot_prove_the_secret_is_refused() -> None:
    cch, sch = Channel(initiator=True, session=1), Channel(initiator=False)
    chs = ClientHandshake(cch, SECRET)
    shs = ServerHandshake(sch, SECRET)
    sch.receive_data(b"".join(cch.encode(o) for o in chs.start(0)))
    cch.receive_data(b"".join(sch.encode(o) for o in shs.handle(sch.next_event(), 0)))
    chs.handle(cch.next_event(), 0)
    # an impostor answers AUTH_OK untagged
    impostor = Channel(initiator=False, session=1)
    impostor._seq = 5
    cch.receive_data(impostor.encode(Out(FrameType.AUTH_OK, b'{"proof":""}')))
    with pytest.raises(AuthenticationError, match=r"AUTH_OK frame .seq 6. has no tag"):
        cch.next_event()


def test_receiver_protocol_violations() -> None:
    offer = Offer.for_bytes("a.2d", b"abcdef", chunk_size=4)
    rx = Receiver(offer, ref=1)
    out = rx.handle(Frame(FrameType.DATA, 1, 0, b"abcd"), 0)
    assert rx.error is not None and "DATA before ACCEPT" in str(rx.error)
    assert out and out[0].type == FrameType.CANCEL
    rx = Receiver(offer, ref=1)
    rx.accept(0)
    rx.handle(Frame(FrameType.DATA, 2, 1, b"toolong"), 0)
    assert "DATA for chunk 1 has 7 bytes, expected 2" in str(rx.error)
    rx = Receiver(offer, ref=1)
    rx.accept(0)
    rx.handle(Frame(FrameType.DATA, 2, 9, b"ab"), 0)
    assert "DATA for chunk 9, the file has 2" in str(rx.error)


def test_offer_checks() -> None:
    good = Offer.for_bytes("x.map", b"2D-Map\n").json()
    assert Offer.from_json(good).md5 == hashlib.md5(b"2D-Map\n").hexdigest()
    for key, value, match in [
        ("size", -1, "not a byte count"),
        ("chunk_size", 0, "outside"),
        ("sha256", "zz", "sha256 must be 32 bytes"),
        ("chunks", 5, "says 5 chunks"),
        ("name", None, "no name"),
    ]:
        with pytest.raises(ProtocolError, match=match):
            Offer.from_json({**good, key: value})
