"""Fuzzing MKT/1 frames: against the sans-I/O core (every machine, both transports' framing)
and against a real `mapkit serve` over a real socket, before and after authentication.

The core may only ever raise :class:`~mapkit.errors.MapkitError`; the server must stay up, log
no internal error, and still serve an honest client afterwards. Seeded mutation loops bounded in
time (``MKT_FUZZ_SECONDS``, default 3 s each; ``MKT_FUZZ_SEED`` picks another seed).
"""

from __future__ import annotations

import hashlib
import os
import random
import socket
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from mkt_fuzz import HONEST, frame_types, mutate_bytes, mutate_payload
from mkt_helpers import SECRET, ServeProcess, client_options, make_map, raw_session

from mapkit.errors import MapkitError
from mapkit.transfer import fetch_file, list_maps, send_file
from mapkit.transfer.protocol import (
    Channel,
    ClientHandshake,
    Flag,
    Frame,
    FrameType,
    Offer,
    Out,
    Receiver,
    Request,
    Sender,
    ServerHandshake,
    rejected_from,
)

SECONDS = float(os.environ.get("MKT_FUZZ_SECONDS", "3"))
SEED = int(os.environ.get("MKT_FUZZ_SEED", "20261125"))
OFFER = Offer("office.map", 40, "ab" * 32, 16, "cd" * 16, "map")


def _encode(
    ch: Channel, ftype: int, payload: bytes, rng: random.Random, ref: int | None = None
) -> bytes:
    flags = rng.choice([0, 0, int(Flag.ACKREQ), int(Flag.RETX), rng.randrange(1 << 16)])
    out = Out(ftype, payload, ref=rng.randrange(4) if ref is None else ref, flags=flags)  # type: ignore[arg-type]
    data = ch.encode(out)
    return mutate_bytes(data, rng) if rng.random() < 0.3 else data


def _events(ch: Channel, data: bytes, ordered: bool) -> list[Any]:
    if ordered:
        ch.receive_data(data)
    else:
        ch.receive_message(data)
    out = []
    for _ in range(8):
        ev = ch.next_event()
        if ev is None:
            break
        out.append(ev)
    return out


def _look(ev: Any) -> None:
    """What applications do with a frame: decode it, read an offer or a refusal from it."""
    if isinstance(ev, Frame) and ev.type != FrameType.DATA:
        ev.json()
        if ev.type in (FrameType.OFFER, FrameType.NOT_MODIFIED):
            Offer.from_json(ev.json())
        if ev.type in (FrameType.REJECT, FrameType.CANCEL):
            rejected_from(ev)


def _pair(ordered: bool) -> tuple[Channel, Channel]:
    """A client and a server channel after an honest handshake (both keyed)."""
    c = Channel(initiator=True, session=0x5EED, ordered=ordered)
    s = Channel(initiator=False, ordered=ordered)
    ch, sh = ClientHandshake(c, SECRET), ServerHandshake(s, SECRET)
    to_s = ch.start(0.0)
    while not (ch.finished and sh.finished):
        to_c = []
        for ev in _events(s, b"".join(c.encode(o) for o in to_s), True):
            to_c += sh.handle(ev, 0.0)
        to_s = []
        for ev in _events(c, b"".join(s.encode(o) for o in to_c), True):
            to_s += ch.handle(ev, 0.0)
    assert ch.error is None and sh.error is None
    return c, s


def _handshake_frames(
    rng: random.Random,
    ordered: bool,
    machine: Any,
    mine: Channel,
    theirs: Channel,
    first: FrameType,
) -> None:
    """Feed a handshake machine 1-3 mutated frames (the first mostly of type ``first``)."""
    machine.start(0.0)
    for i in range(rng.randrange(1, 4)):
        t = first if i == 0 and rng.random() < 0.6 else frame_types(rng)
        for ev in _events(mine, _encode(theirs, t, mutate_payload(t, rng), rng, 0), ordered):
            machine.handle(ev, float(i))
        machine.poll(float(i) + rng.random() * 10)


def _server_handshake(rng: random.Random, ordered: bool) -> None:
    s = Channel(initiator=False, ordered=ordered)
    secret = rng.choice([SECRET, None])
    sh = ServerHandshake(s, secret, insecure=secret is None or rng.random() < 0.5, timeout=5.0)
    c = Channel(initiator=True, session=rng.randrange(1, 1 << 64), ordered=ordered)
    _handshake_frames(rng, ordered, sh, s, c, FrameType.HELLO)


def _client_handshake(rng: random.Random, ordered: bool) -> None:
    c = Channel(initiator=True, session=77, ordered=ordered)
    ch = ClientHandshake(c, rng.choice([SECRET, None]))
    s = Channel(initiator=False, session=77, ordered=ordered)
    _handshake_frames(rng, ordered, ch, c, s, FrameType.HELLO_ACK)


def _receiver(rng: random.Random, ordered: bool) -> None:
    c, s = _pair(ordered)
    rx = Receiver(OFFER, ref=1)
    rx.accept(0.0)
    for i in range(rng.randrange(1, 6)):
        t = (
            rng.choice([FrameType.DATA, FrameType.DATA, FrameType.DONE, FrameType.OFFER])
            if rng.random() < 0.6
            else frame_types(rng)
        )
        ref = rng.choice([0, 1, 2, 3, 1 << 31]) if t == FrameType.DATA else rng.choice([1, 1, 2])
        payload = (
            bytes(rng.choice([16, 16, 8, 0, 17])) if t == FrameType.DATA else mutate_payload(t, rng)
        )
        for ev in _events(s, _encode(c, t, payload, rng, ref), ordered):
            _look(ev)
            rx.handle(ev, float(i))
            rx.pop_events()
        rx.poll(float(i))


def _sender(rng: random.Random, ordered: bool) -> None:
    c, s = _pair(ordered)
    tx = Sender(OFFER, lambda i: bytes(OFFER.chunk_len(i)), ref=1, window=2)
    tx.start(0.0)
    for i in range(rng.randrange(1, 6)):
        t = (
            rng.choice([FrameType.ACCEPT, FrameType.ACK, FrameType.VERIFIED, FrameType.REJECT])
            if rng.random() < 0.7
            else frame_types(rng)
        )
        for ev in _events(c, _encode(s, t, mutate_payload(t, rng), rng, 1), ordered):
            _look(ev)
            tx.handle(ev, float(i))
        tx.poll(float(i) * 3)


def _request(rng: random.Random, ordered: bool) -> None:
    c, s = _pair(ordered)
    kind, answers = rng.choice(
        [
            (FrameType.LIST, [FrameType.LISTING]),
            (FrameType.GET, [FrameType.OFFER, FrameType.NOT_MODIFIED]),
            (FrameType.LOAD, [FrameType.LOADED]),
            (FrameType.PING, [FrameType.PONG]),
        ]
    )
    req = Request(kind, HONEST.get(kind, {}), ref=1, answers=answers)
    req.start(0.0)
    for i in range(rng.randrange(1, 4)):
        t = rng.choice(answers) if rng.random() < 0.7 else frame_types(rng)
        for ev in _events(c, _encode(s, t, mutate_payload(t, rng), rng, 1), ordered):
            _look(ev)
            req.handle(ev, float(i))
        if req.finished and req.response is not None:
            _look(req.response)


TARGETS: list[Callable[[random.Random, bool], None]] = [
    _server_handshake,
    _client_handshake,
    _receiver,
    _sender,
    _request,
]


def test_fuzzed_frames_raise_nothing_but_mapkit_errors_in_the_core() -> None:
    end = time.monotonic() + SECONDS
    runs = {t.__name__: 0 for t in TARGETS}
    i = 0
    while time.monotonic() < end or i < 2 * len(TARGETS):
        seed = SEED + i
        rng = random.Random(seed)
        target = TARGETS[i % len(TARGETS)]
        ordered = rng.random() < 0.5
        try:
            target(rng, ordered)
        except MapkitError:
            pass
        except BaseException as err:
            raise AssertionError(
                f"{target.__name__} (seed {seed}, ordered={ordered}) raised "
                f"{type(err).__name__}: {err}"
            ) from err
        runs[target.__name__] += 1
        i += 1
    assert all(runs.values()), runs


def test_every_hostile_text_in_every_control_frame_type() -> None:
    """Deep nesting, 50,000-digit numbers, NaN, lone surrogates, bad UTF-8, non-objects: each
    in each control frame type, as the applications read them: a MapkitError or a value."""
    from mkt_fuzz import _RAW_TEXTS

    rng = random.Random(SEED)
    refused = 0
    for make in _RAW_TEXTS:
        for _ in range(3):
            payload = make(rng)
            for ftype in HONEST:
                try:
                    _look(Frame(ftype, 1, 1, payload))
                except MapkitError:
                    refused += 1
    assert refused > len(_RAW_TEXTS) * len(HONEST)


# -- a real server --------------------------------------------------------------------------------


@pytest.fixture
def secret_file(tmp_path: Path) -> Path:
    f = tmp_path / "secret"
    f.write_bytes(SECRET + b"\n")
    return f


def _drain(sock: socket.socket, seconds: float) -> None:
    sock.settimeout(seconds)
    try:
        while sock.recv(65536):
            pass
    except OSError:
        pass


@pytest.mark.network
def test_fuzzed_frames_never_end_a_real_server(tmp_path, robot_dir, secret_file) -> None:
    srv = ServeProcess(
        robot_dir, secret_file, "--handshake-timeout", "2", log_path=tmp_path / "serve.log"
    )
    try:
        rng = random.Random(SEED)
        end = time.monotonic() + SECONDS
        sessions = frames = 0
        while time.monotonic() < end:
            sessions += 1
            if rng.random() < 0.4:  # unauthenticated: the handshake's frames, mutated
                c = Channel(initiator=True, session=rng.randrange(1, 1 << 64))
                with socket.create_connection(srv.address, timeout=5) as s:
                    for i in range(rng.randrange(1, 4)):
                        t = FrameType.HELLO if i == 0 else frame_types(rng)
                        try:
                            s.sendall(_encode(c, t, mutate_payload(t, rng), rng, 0))
                        except OSError:
                            break
                        frames += 1
                    _drain(s, 0.02)
                continue
            link = raw_session(srv.address)  # authenticated: every request, mutated
            try:
                for _ in range(rng.randrange(1, 6)):
                    t = frame_types(rng)
                    payload = mutate_payload(t, rng)
                    if rng.random() < 0.15:
                        raw = link.channel.encode(Out(t, payload, ref=1))  # type: ignore[arg-type]
                        link.sock.sendall(mutate_bytes(raw, rng))
                    else:
                        link.send([Out(t, payload, ref=rng.choice([0, 1, 2, 7]))])  # type: ignore[arg-type]
                    frames += 1
                    try:
                        link.receive(0.02)
                    except (MapkitError, OSError):
                        break
            except (MapkitError, OSError):  # the server may end the session: a closed pipe
                pass
            finally:
                link.close()
        assert frames > 50, frames
        assert srv.alive(), srv.log()
        # the honest client still gets everything done
        data = make_map(300, 5)
        src = tmp_path / "after.map"
        src.write_bytes(data)
        send_file(src, *srv.address, **client_options())
        listed = list_maps(*srv.address, **client_options())["maps"]
        assert "after.map" in [m["name"] for m in listed]
        back = tmp_path / "back.map"
        fetch_file(srv.address[0], "after.map", back, port=srv.address[1], **client_options())
        assert hashlib.sha256(back.read_bytes()).digest() == hashlib.sha256(data).digest()
    finally:
        code = srv.stop()
    log = srv.log()
    assert "internal error" not in log and "Traceback" not in log, log[-3000:]
    assert code == 0
