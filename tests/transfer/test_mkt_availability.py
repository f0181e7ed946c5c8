"""A robot stays reachable: a real `mapkit serve` process against peers that hold connections
without authenticating (silent, slow-loris, half-open, from one address or many), a sender
whose link was cut without a FIN, interrupted offers of huge files, and bad names on every
request that takes one.

Deadlines here are generous upper bounds ("closed before the 30 s idle timeout would have"),
never timings.
"""

from __future__ import annotations

import hashlib
import json
import os
import socket
import threading
import time
from pathlib import Path

import pytest
from mkt_helpers import (
    SECRET,
    FreezeProxy,
    ServeProcess,
    client_options,
    closed_by_peer,
    fails_once,
    make_map,
    raw_session,
    silent_connection,
)

from mapkit.transfer import Client, fetch_file, list_maps, load_map, send_file
from mapkit.transfer.protocol import (
    Channel,
    Flag,
    FrameType,
    Offer,
    Out,
    Rejected,
    Status,
    dump_json,
    encode_frame,
)

pytestmark = pytest.mark.network

HANDSHAKE = "1.5"  # --handshake-timeout of the servers here (seconds)
CLOSED_WITHIN = 15.0  # generous: half the 30 s idle timeout that used to hold such peers


@pytest.fixture
def secret_file(tmp_path: Path) -> Path:
    f = tmp_path / "secret"
    f.write_bytes(SECRET + b"\n")
    return f


@pytest.fixture
def serve(tmp_path: Path, robot_dir: Path, secret_file: Path):
    procs: list[ServeProcess] = []

    def start(*args: str, folder: Path | None = None) -> ServeProcess:
        p = ServeProcess(
            folder or robot_dir,
            secret_file,
            "--handshake-timeout",
            HANDSHAKE,
            *args,
            log_path=tmp_path / f"serve-{len(procs)}.log",
        )
        procs.append(p)
        return p

    yield start
    for p in procs:
        p.stop()
        assert "Traceback" not in p.log(), p.log()  # nothing escaped a session


def honest_round_trip(tmp_path: Path, address: tuple[str, int], tag: str) -> None:
    """An honest terminal pushes, lists and fetches (each call opens its own session)."""
    data = make_map(200, seed=len(tag))
    src = tmp_path / f"{tag}.map"
    src.write_bytes(data)
    send_file(src, *address, **client_options())
    assert f"{tag}.map" in [m["name"] for m in list_maps(*address, **client_options())["maps"]]
    out = tmp_path / f"{tag}-back.map"
    fetch_file(address[0], f"{tag}.map", out, port=address[1], **client_options())
    assert out.read_bytes() == data


# -- peers that never authenticate ----------------------------------------------------------------


def test_silent_connections_beyond_every_limit_do_not_lock_clients_out(tmp_path, serve) -> None:
    srv = serve()
    silent = [silent_connection(srv.address) for _ in range(80)]  # more than the 64 sessions
    try:
        honest_round_trip(tmp_path, srv.address, "first")
        # every silent one is closed at its handshake deadline, not after the idle timeout
        assert all(closed_by_peer(s, CLOSED_WITHIN) for s in silent)
    finally:
        for s in silent:
            s.close()
    log = srv.log()
    assert "evicted: too many connections in their handshake" in log
    assert "no handshake within 1.5 s" in log


def test_renewing_silent_connections_keeps_nobody_out(tmp_path, serve) -> None:
    srv = serve()
    stop = threading.Event()
    opened = [0]

    def attacker() -> None:  # re-opens what the robot closes, as fast as it can, forever
        held: list[socket.socket] = []
        while not stop.is_set():
            try:
                held.append(silent_connection(srv.address))
                opened[0] += 1
            except OSError:
                time.sleep(0.01)
            if len(held) > 200:
                held.pop(0).close()
        for s in held:
            s.close()

    t = threading.Thread(target=attacker, daemon=True)
    t.start()
    try:
        while opened[0] < 100:
            time.sleep(0.01)
        for i in range(3):
            honest_round_trip(tmp_path, srv.address, f"during{i}")
    finally:
        stop.set()
        t.join(10)
    assert srv.alive()


def test_connections_from_many_addresses(tmp_path, serve) -> None:
    """Silent peers spread over 40 addresses (the per-address limit does not apply) still
    cannot fill the handshake pool: the oldest silent one gives way to the honest client."""
    srv = serve()
    silent = [silent_connection(srv.address, f"127.0.0.{2 + i % 40}") for i in range(120)]
    try:
        honest_round_trip(tmp_path, srv.address, "many")
    finally:
        for s in silent:
            s.close()


def hello_bytes(session: int = 77) -> bytes:
    payload = dump_json(
        {"versions": [1], "nonce": "ab" * 32, "auth": ["blake2b"], "peer": "loris", "software": "x"}
    )
    return b"".join(encode_frame(FrameType.HELLO, payload, session=session, seq=1))


def test_slow_loris_handshake_is_cut_at_the_deadline(serve) -> None:
    srv = serve()
    hello = hello_bytes()
    s = socket.create_connection(srv.address)
    closed = False
    try:
        end = time.monotonic() + CLOSED_WITHIN
        for b in hello:  # one byte every 0.2 s: the HELLO would take ~40 s
            try:
                s.sendall(bytes([b]))
            except OSError:
                closed = True
                break
            if closed_by_peer(s, 0.2):
                closed = True
                break
            if time.monotonic() > end:
                break
    finally:
        s.close()
    assert closed
    assert "no handshake within 1.5 s" in srv.log() or "handshake not completed" in srv.log()


def test_repeating_hello_does_not_extend_the_handshake(serve) -> None:
    """Complete frames (the same HELLO again and again) refresh no deadline either."""
    srv = serve()
    s = socket.create_connection(srv.address)
    channel = Channel(initiator=True, session=99)
    payload = dump_json(
        {
            "versions": [1],
            "nonce": "cd" * 32,
            "auth": ["blake2b"],
            "peer": "repeater",
            "software": "x",
        }
    )
    closed = False
    try:
        end = time.monotonic() + CLOSED_WITHIN
        while time.monotonic() < end:
            try:
                s.sendall(channel.encode(Out(FrameType.HELLO, payload)))
            except OSError:
                closed = True
                break
            if closed_by_peer(s, 0.3):
                closed = True
                break
    finally:
        s.close()
    assert closed


def test_half_open_peer_after_a_partial_frame(serve) -> None:
    """A peer that sent half a header and then vanished (no FIN) is closed at the deadline."""
    srv = serve()
    s = socket.create_connection(srv.address)
    try:
        s.sendall(hello_bytes()[:20])
        assert closed_by_peer(s, CLOSED_WITHIN)
    finally:
        s.close()


def test_authenticated_sessions_keep_their_room(tmp_path, serve) -> None:
    srv = serve()
    clients = [Client(*srv.address, **client_options()) for _ in range(10)]
    silent = [silent_connection(srv.address, f"127.0.0.{2 + i % 20}") for i in range(150)]
    try:
        for c in clients:  # every authenticated session still answers
            assert c.list()["maps"] == []
        honest_round_trip(tmp_path, srv.address, "room")
    finally:
        for s in silent:
            s.close()
        for c in clients:
            c.close()


def _tcp_timers(local_port: int, remote_port: int) -> list[int]:
    """Timer kinds (/proc/net/tcp ``tr``) of sockets local_port -> remote_port on 127.0.0.1."""
    kinds = []
    with open("/proc/net/tcp") as fh:
        next(fh)
        for line in fh:
            f = line.split()
            local, remote, timer = f[1], f[2], f[5]
            if local.endswith(f":{local_port:04X}") and remote.endswith(f":{remote_port:04X}"):
                kinds.append(int(timer.split(":")[0], 16))
    return kinds


@pytest.mark.skipif(not os.path.exists("/proc/net/tcp"), reason="needs Linux /proc/net/tcp")
def test_server_sockets_probe_dead_peers_with_keepalive(serve) -> None:
    """The robot's end of an idle session runs TCP's keepalive timer (kind 2 in /proc/net/tcp),
    so a peer that vanished without a FIN is found."""
    srv = serve()
    with Client(*srv.address, **client_options()) as c:
        c.list()
        mine = c.link.sock.getsockname()[1]
        end = time.monotonic() + 10
        kinds: list[int] = []
        while time.monotonic() < end and 2 not in kinds:
            kinds = _tcp_timers(srv.port, mine)
            time.sleep(0.05)
        assert 2 in kinds, kinds


# -- a network cut mid-send -----------------------------------------------------------------------


def test_resend_after_a_cut_without_fin_takes_over_at_once(tmp_path, serve, robot_dir) -> None:
    srv = serve()
    data = os.urandom(4 << 20)
    src = tmp_path / "scan.2d"
    src.write_bytes(data)
    proxy = FreezeProxy(srv.address, freeze_after=1 << 20)
    first: dict[str, BaseException] = {}

    def doomed() -> None:  # the laptop whose Wi-Fi drops after 1 MiB
        try:
            send_file(src, *proxy.address, chunk_size=64 * 1024, **client_options())
        except BaseException as err:
            first["err"] = err

    t = threading.Thread(target=doomed, daemon=True)
    t.start()
    try:
        assert proxy.frozen.wait(30)
        # another file for the same name is still refused while the writer might be alive
        other = tmp_path / "other" / "scan.2d"
        other.parent.mkdir()
        other.write_bytes(os.urandom(1 << 20))
        with pytest.raises(Rejected, match="busy") as e:
            send_file(other, *srv.address, **client_options())
        assert e.value.status == Status.BUSY
        # the same file from the same sender: the same transfer, resumed at once
        r = send_file(src, *srv.address, chunk_size=64 * 1024, **client_options())
        assert r["verified"]
        assert (robot_dir / "scan.2d").read_bytes() == data
        assert "taking it over" in srv.log()
    finally:
        proxy.close()
        t.join(30)


# -- interrupted offers and abandoned partial files -----------------------------------------------


def _disk_bytes(folder: Path) -> int:
    return sum(os.lstat(p).st_blocks * 512 for p in folder.iterdir())


def test_interrupted_huge_offers_hold_only_what_arrived(tmp_path, serve, robot_dir) -> None:
    srv = serve()
    free = os.statvfs(robot_dir).f_bavail * os.statvfs(robot_dir).f_frsize
    size = min(900_000_000, free // 8)  # three of them must pass the free-space check
    assert size > 8 << 20, "too little disk for this test"
    chunk = 1 << 20
    for k in range(3):
        link = raw_session(srv.address)
        offer = Offer(f"huge{k}.2d", size, hashlib.sha256(b"%d" % k).hexdigest(), chunk, None, "2d")
        link.send([Out(FrameType.OFFER, dump_json(offer.json()), ref=1)])
        ev = link.receive(10)
        assert ev is not None and ev.type == FrameType.ACCEPT, ev
        link.send([Out(FrameType.DATA, os.urandom(chunk), ref=0, flags=Flag.ACKREQ)])
        end = time.monotonic() + 10  # its ACK says it is on disk (or will be at the checkpoint)
        while time.monotonic() < end:
            ev = link.receive(1)
            if ev is not None and ev.type == FrameType.ACK:
                break
        link.close()  # cut after 1 MiB
    end = time.monotonic() + 20  # each session saves its journal when it ends
    while time.monotonic() < end and len(list(robot_dir.glob(".*.mkpart.json"))) < 3:
        time.sleep(0.05)
    assert len(list(robot_dir.glob(".*.mkpart.json"))) == 3
    for k in range(3):
        assert os.path.getsize(robot_dir / f".huge{k}.2d.mkpart") == size  # resumable
    assert _disk_bytes(robot_dir) < 3 * chunk + (4 << 20)  # not 3 x size


def _partial(folder: Path, name: str, age: float) -> None:
    for p in (folder / f".{name}.mkpart", folder / f".{name}.mkpart.json"):
        p.write_bytes(b"{}")
        t = time.time() - age
        os.utime(p, (t, t))


def test_abandoned_partials_are_deleted_when_the_server_starts(serve, robot_dir) -> None:
    _partial(robot_dir, "old.map", 3 * 3600)
    _partial(robot_dir, "young.map", 60)
    _partial(robot_dir, "orphan.map", 3 * 3600)
    os.unlink(robot_dir / ".orphan.map.mkpart")  # a journal left alone
    (robot_dir / "office.map").write_bytes(make_map(10))
    (robot_dir / ".notes.tmp").write_bytes(b"not ours")
    srv = serve("--partial-ttl", "3600")
    end = time.monotonic() + 10
    while time.monotonic() < end and (robot_dir / ".orphan.map.mkpart.json").exists():
        time.sleep(0.05)
    assert sorted(os.listdir(robot_dir)) == [
        ".notes.tmp",
        ".young.map.mkpart",
        ".young.map.mkpart.json",
        "office.map",
    ]
    assert "deleted the abandoned partial file of old.map" in srv.log()


def test_partials_expire_while_serving_but_never_under_a_writer(make_server, robot_dir) -> None:
    from mapkit.transfer.store import PartialFile

    srv = make_server(partial_ttl=3600, sweep_interval=0.1)
    held = PartialFile.open(
        str(robot_dir), "busy.2d", Offer("busy.2d", 10, "0" * 64, 4, None, "2d")
    )
    held.write(0, b"abcd")
    held.checkpoint()
    _partial(robot_dir, "gone.2d", 7200)
    for p in robot_dir.glob(".busy.2d.mkpart*"):
        os.utime(p, (time.time() - 7200,) * 2)
    end = time.monotonic() + 10
    while time.monotonic() < end and (robot_dir / ".gone.2d.mkpart").exists():
        time.sleep(0.05)
    assert not (robot_dir / ".gone.2d.mkpart").exists()
    assert (robot_dir / ".busy.2d.mkpart").exists()  # its lock is held: not abandoned
    held.close()
    assert srv.sessions == 0


def test_concurrent_offers_cannot_overcommit_the_disk(robot_dir) -> None:
    from mapkit.transfer import MapFolder
    from mapkit.transfer.store import StoreError

    folder = MapFolder(robot_dir, max_size=1 << 50)
    free = os.statvfs(robot_dir).f_bavail * os.statvfs(robot_dir).f_frsize
    big = free * 6 // 10
    a = folder.begin_write(Offer("a.2d", big, "1" * 64, 1 << 20, None, "2d"))
    try:
        with pytest.raises(StoreError) as e:  # fits alone, not beside a's promise
            folder.begin_write(Offer("b.2d", big, "2" * 64, 1 << 20, None, "2d"))
        assert e.value.status == Status.NO_SPACE
    finally:
        a.close(keep=False)
    b = folder.begin_write(Offer("b.2d", big, "2" * 64, 1 << 20, None, "2d"))
    b.close(keep=False)


# -- names and offers every request checks --------------------------------------------------------

LONG_NAMES = [
    "a" * 252 + ".map",  # 256 bytes: over the file system's 255
    "b" * 300 + ".2d",
    "é" * 120 + ".map",  # 124 characters, 244 bytes
    "c" * 197 + ".map",  # 201 bytes
]


def test_long_names_are_bad_names_on_every_request(serve, robot_dir) -> None:
    srv = serve()
    for name in LONG_NAMES:
        link = raw_session(srv.address)
        try:
            offer = Offer.for_bytes(name, make_map(5))
            requests = [
                (FrameType.OFFER, offer.json()),
                (FrameType.GET, {"name": name}),
                (FrameType.LOAD, {"name": name, "md5": offer.md5}),
            ]
            for ref, (ftype, payload) in enumerate(requests, 1):
                link.send([Out(ftype, dump_json(payload), ref=ref)])
                ev = link.receive(10)
                assert ev is not None and ev.type == FrameType.REJECT, (name, ftype, ev)
                d = ev.json()
                assert d["reason"] == "bad_name", (name, ftype, d)
                assert "bytes" in d["message"]
            # the session goes on
            link.send([Out(FrameType.LIST, b"{}", ref=9)])
            ev = link.receive(10)
            assert ev is not None and ev.type == FrameType.LISTING
        finally:
            link.close()
    assert os.listdir(robot_dir) == []


def test_listing_skips_files_whose_names_are_too_long(tmp_path, serve, robot_dir) -> None:
    (robot_dir / ("d" * 240 + ".map")).write_bytes(make_map(5))
    (robot_dir / "ok.map").write_bytes(make_map(5))
    srv = serve()
    assert [m["name"] for m in list_maps(*srv.address, **client_options())["maps"]] == ["ok.map"]
    with pytest.raises(Rejected, match="bad_name"):
        load_map(
            srv.address[0],
            "d" * 240 + ".map",
            port=srv.address[1],
            md5="0" * 32,
            **client_options(),
        )


def test_a_map_offer_must_carry_its_md5_and_kind(serve, robot_dir) -> None:
    srv = serve()
    for change in ({"md5": None}, {"md5": ""}, {"kind": "file"}, {"kind": "2d"}):
        offer = Offer.for_bytes("office.map", make_map(20)).json()
        for k, v in change.items():
            if v is None:
                offer.pop(k)
            else:
                offer[k] = v
        link = raw_session(srv.address)
        try:
            link.send([Out(FrameType.OFFER, json.dumps(offer).encode(), ref=1)])
            ev = link.receive(10)
            assert ev is not None and ev.type == FrameType.REJECT, change
            assert ev.json()["reason"] == "protocol", (change, ev.json())
        finally:
            link.close()
    assert os.listdir(robot_dir) == []


def test_a_slow_tls_handshake_is_cut_too(make_server, cert) -> None:
    from mapkit.transfer import server_tls_context

    crt, key = cert
    srv = make_server(tls=server_tls_context(str(crt), str(key)), handshake_timeout=1.0)
    s = socket.create_connection(srv.address)
    closed = False
    try:
        end = time.monotonic() + CLOSED_WITHIN
        hello = bytes.fromhex("16030100c8010000c40303") + bytes(200)  # a ClientHello's start
        for b in hello:  # a byte every 0.2 s: each read alone is well within a socket timeout
            try:
                s.sendall(bytes([b]))
            except OSError:
                closed = True
                break
            if closed_by_peer(s, 0.2) or time.monotonic() > end:
                closed = time.monotonic() <= end
                break
    finally:
        s.close()
    assert closed


def test_an_unexpected_error_in_a_request_ends_only_that_session(
    make_server, robot_dir, tmp_path, caplog
) -> None:
    """A bug met by one request (here: the listing raises RuntimeError) is logged, told to the
    client as `internal`, and the server goes on serving everyone else."""
    srv = make_server()
    srv.folder.listing = fails_once(srv.folder.listing, RuntimeError("a bug"))  # type: ignore[method-assign]
    with pytest.raises(Rejected, match="internal") as e:
        list_maps(*srv.address, **client_options())
    assert e.value.status == Status.INTERNAL
    assert "internal error in LIST" in caplog.text and "RuntimeError: a bug" in caplog.text
    honest_round_trip(tmp_path, srv.address, "after-bug")
