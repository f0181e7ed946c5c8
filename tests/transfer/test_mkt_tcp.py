"""MKT/1 over real TCP sockets on 127.0.0.1: round trips, cuts and resume, bit flips, refusals,
concurrency, TLS, load/rollback, full disks."""

from __future__ import annotations

import errno
import hashlib
import json
import os
import subprocess
import threading
from concurrent.futures import ThreadPoolExecutor

import pytest
from mkt_helpers import client_options, listing, make_map, wait_idle

import mapkit.transfer.reading as reading_mod
import mapkit.transfer.store as store_mod
from mapkit.errors import LocalTransferError, TransferError
from mapkit.transfer import (
    Client,
    MapFolder,
    Rejected,
    Status,
    client_tls_context,
    fetch_file,
    list_maps,
    load_map,
    send_file,
    server_tls_context,
)
from mapkit.transfer.protocol import Channel, FrameType, Out
from mapkit.transfer.store import partial_paths


def sha(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


# -- round trips -----------------------------------------------------------------------------------


@pytest.mark.parametrize("size", [0, 1, 4096, 4097, 3 * 4096, 100_000])
def test_push_and_pull_are_byte_identical(tmp_path, robot_dir, make_server, size) -> None:
    data = os.urandom(size)
    src = tmp_path / "log.2d"
    src.write_bytes(data)
    srv = make_server()
    r = send_file(src, *srv.address, chunk_size=4096, **client_options())
    assert (robot_dir / "log.2d").read_bytes() == data
    assert r["sha256"] == sha(data) and r["chunks_sent"] == -(-size // 4096)
    assert r["verified"]["sha256"] == sha(data)
    out = tmp_path / "back.2d"
    f = fetch_file(
        *srv.address[:1], "log.2d", out, port=srv.address[1], chunk_size=4096, **client_options()
    )
    assert out.read_bytes() == data and f["modified"] is True
    assert listing(robot_dir) == ["log.2d"]  # no temp files, no journal left behind


def test_real_sample_map_push_load_fetch(tmp_path, real_sample, robot_dir, make_server) -> None:
    srv = make_server()
    host, port = srv.address
    r = send_file(real_sample, host, port, load=True, **client_options())
    assert r["md5"] == hashlib.md5(real_sample.read_bytes()).hexdigest()
    assert r["loaded"]["name"] == real_sample.name
    assert (robot_dir / "active.map").read_bytes() == real_sample.read_bytes()
    maps = list_maps(host, port, **client_options())["maps"]
    assert [(m["name"], m["active"], m["md5"]) for m in maps] == [
        (real_sample.name, True, r["md5"])
    ]
    out = tmp_path / "copy.map"
    fetch_file(host, "active.map", out, port=port, **client_options())
    assert out.read_bytes() == real_sample.read_bytes()
    again = fetch_file(host, real_sample.name, out, port=port, if_changed=True, **client_options())
    assert again["modified"] is False


def test_one_session_many_requests(tmp_path, robot_dir, make_server) -> None:
    srv = make_server()
    a, b = tmp_path / "a.map", tmp_path / "b.map"
    a.write_bytes(make_map(50, 1))
    b.write_bytes(make_map(60, 2))
    with Client(*srv.address, **client_options()) as c:
        c.send(a)
        c.send(b)
        first = c.load("a.map")
        second = c.load("b.map")
        assert second["previous"]["name"] == "a.map" and first["name"] == "a.map"
        back = c.load(rollback=True)
        assert back["name"] == "a.map"
        assert c.list()["active"] == "a.map"
    assert (robot_dir / "active.map").read_bytes() == a.read_bytes()
    assert (robot_dir / "previous.map").read_bytes() == b.read_bytes()


# -- cut connections and resume --------------------------------------------------------------------


@pytest.mark.parametrize("threads", [False, True], ids=["inline", "threads"])
def test_push_cut_at_many_points_resumes_and_resends_only_missing(
    tmp_path, robot_dir, make_server, proxy, monkeypatch, threads
) -> None:
    if threads:  # the robot writes, hashes and checkpoints in background threads even for this
        # file, and the terminal prepares each chunk's CRC and tag in a background pass
        monkeypatch.setattr(store_mod, "THREADS_FROM", 0)
        monkeypatch.setattr(reading_mod, "PREPARE_FROM", 0)
    chunk, n = 16 * 1024, 40
    data = os.urandom(chunk * n - 123)
    src = tmp_path / "big.2d"
    src.write_bytes(data)
    srv = make_server(window=4)
    _, journal = partial_paths(str(robot_dir), "big.2d")
    held_before = 0
    crossed = 0
    cuts = [3_000, 40_000, 90_000, 150_000, 100_000, 70_000]  # bytes per attempt; 655 KB in all
    for cut in cuts:
        p = proxy(srv.address, cut_c2s=cut)
        with pytest.raises(TransferError):
            send_file(src, *p.address, chunk_size=chunk, window=4, **client_options())
        wait_idle(srv)
        crossed += p.c2s
        assert not (robot_dir / "big.2d").exists()  # never a partial file under the final name
        if os.path.exists(journal):
            with open(journal) as fh:
                held = sum(store_mod.decode_bitmap(json.load(fh)["have"], n))
            assert held >= held_before  # what was received is kept
            held_before = held
    assert held_before > n // 3
    p = proxy(srv.address)
    r = send_file(src, *p.address, chunk_size=chunk, window=4, **client_options())
    crossed += p.c2s
    assert (robot_dir / "big.2d").read_bytes() == data
    assert r["chunks_skipped"] == held_before
    assert r["chunks_distinct"] == n - held_before  # no chunk the robot held crossed again
    # everything that crossed: the file once, plus at most what was in flight at each cut
    assert (
        crossed
        <= len(data) + len(cuts) * (4 + 1) * (chunk + 100) + (r["chunks_resent"] + 2) * chunk
    )
    assert listing(robot_dir) == ["big.2d"]


@pytest.mark.parametrize("ahead", [False, True], ids=["plain", "prepared"])
def test_pull_cut_then_resumed(tmp_path, robot_dir, make_server, proxy, monkeypatch, ahead) -> None:
    if ahead:  # the robot prepares CRCs and tags in a background pass (PreparedReader)
        monkeypatch.setattr(reading_mod, "PREPARE_FROM", 0)
    chunk, n = 8 * 1024, 30
    data = make_map(20_000)[: chunk * n]
    data = data[: data.rfind(b"\n") + 1]
    (robot_dir / "site.map").write_bytes(data)
    srv = make_server(window=2)
    out = tmp_path / "site.map"
    for cut in (40_000, 120_000):
        p = proxy(srv.address, cut_s2c=cut)
        with pytest.raises(TransferError):
            fetch_file(
                *p.address[:1],
                "site.map",
                out,
                port=p.address[1],
                chunk_size=chunk,
                window=2,
                **client_options(),
            )
        assert not out.exists()
    r = fetch_file(
        srv.address[0], "site.map", out, port=srv.address[1], chunk_size=chunk, **client_options()
    )
    assert out.read_bytes() == data
    assert r["chunks_resumed"] > 0 and r["chunks_received"] + r["chunks_resumed"] == r["chunks"]
    assert sorted(os.listdir(tmp_path)) == ["robot", "site.map"]


# -- bit flips -------------------------------------------------------------------------------------


@pytest.mark.parametrize("direction", ["c2s", "s2c"])
def test_bit_flips_are_detected_and_repaired(
    tmp_path, robot_dir, make_server, proxy, direction
) -> None:
    chunk = 8192
    data = os.urandom(chunk * 12)
    src = tmp_path / "f.2d"
    src.write_bytes(data)
    srv = make_server()
    # flips after the handshake, in DATA payloads, headers and tags (c2s) or in ACKs (s2c)
    flips = tuple(range(2_000, 100_000, 7_919)) if direction == "c2s" else (1_300, 1_450, 1_600)
    p = proxy(srv.address, **{f"flip_{direction}": flips})
    r = send_file(src, *p.address, chunk_size=chunk, **client_options())
    assert (robot_dir / "f.2d").read_bytes() == data
    if direction == "c2s":
        assert r["chunks_resent"] > 0
    # and a pull with flips in the data direction
    p2 = proxy(srv.address, flip_s2c=tuple(range(3_000, 90_000, 6_007)))
    out = tmp_path / "back.2d"
    fetch_file(p2.address[0], "f.2d", out, port=p2.address[1], chunk_size=chunk, **client_options())
    assert out.read_bytes() == data


# -- speed paths --------------------------------------------------------------------------------


def test_tag_algorithm_is_negotiated_over_tcp(tmp_path, robot_dir, make_server) -> None:
    data = os.urandom(5 * (1 << 20) + 5)  # six frames of the default 1 MiB chunk, prepared ahead
    src = tmp_path / "a.2d"
    src.write_bytes(data)
    srv = make_server()
    r = send_file(src, *srv.address, **client_options())
    assert r["auth"] == "blake2b" and r["chunks"] == 6 and (robot_dir / "a.2d").read_bytes() == data
    old = make_server(auth_methods=("hmac-sha256",))
    r = send_file(src, *old.address, name="b.2d", **client_options())
    assert r["auth"] == "hmac-sha256" and (robot_dir / "b.2d").read_bytes() == data
    with pytest.raises(Rejected, match=r"auth_required: no common auth method") as e:
        send_file(src, *old.address, name="c.2d", **client_options(auth_methods=("blake2b",)))
    assert e.value.status == Status.AUTH_REQUIRED
    assert listing(robot_dir) == ["a.2d", "b.2d"]


def test_sender_reuses_digests_and_recovers_from_a_stale_one(
    tmp_path, robot_dir, make_server, monkeypatch
) -> None:
    import mapkit.transfer.client as client_mod

    monkeypatch.setattr(client_mod, "_DIGESTS", {})
    calls: list[int] = []
    real = client_mod.file_digests

    def counting(fd, size, *, md5=True):
        calls.append(size)
        return real(fd, size, md5=md5)

    monkeypatch.setattr(client_mod, "file_digests", counting)
    data = os.urandom(50_000)
    src = tmp_path / "c.2d"
    src.write_bytes(data)
    srv = make_server()
    send_file(src, *srv.address, **client_options())
    send_file(src, *srv.address, name="d.2d", **client_options())
    assert len(calls) == 1  # the second send knew the file's SHA-256
    src.write_bytes(data[::-1])  # a new file: new mtime and ctime, hashed again
    send_file(src, *srv.address, name="e.2d", **client_options())
    assert len(calls) == 2 and (robot_dir / "e.2d").read_bytes() == data[::-1]
    st = os.stat(src)
    key = (st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns, st.st_ctime_ns)
    assert key in client_mod._DIGESTS
    client_mod._DIGESTS[key] = ("0" * 64, None)  # a stale entry: the robot's check catches it
    r = send_file(src, *srv.address, name="f.2d", **client_options())
    assert len(calls) == 3 and r["sha256"] == sha(data[::-1])
    assert (robot_dir / "f.2d").read_bytes() == data[::-1]


# -- refusals --------------------------------------------------------------------------------------


def test_wrong_secret_and_no_secret_are_refused(tmp_path, robot_dir, make_server) -> None:
    src = tmp_path / "a.map"
    src.write_bytes(make_map(10))
    srv = make_server()
    with pytest.raises(
        Rejected, match=r"auth_failed: the client's proof does not match|wrong tag"
    ) as e:
        send_file(src, *srv.address, **client_options(secret=b"another-secret-0123456789"))
    assert e.value.status == Status.AUTH_FAILED
    with pytest.raises(Rejected, match=r"auth_required: this server requires authentication"):
        send_file(src, *srv.address, **client_options(secret=None, insecure=True))
    with pytest.raises(LocalTransferError, match=r"no shared secret"):
        send_file(src, *srv.address, **client_options(secret=None))
    assert listing(robot_dir) == []


def test_insecure_server_refuses_secret_clients_and_vice_versa(
    tmp_path, robot_dir, make_server
) -> None:
    src = tmp_path / "a.map"
    src.write_bytes(make_map(10))
    srv = make_server(secret=None, insecure=True)
    with pytest.raises(Rejected, match=r"this server has no shared secret"):
        send_file(src, *srv.address, **client_options())
    send_file(src, *srv.address, **client_options(secret=None, insecure=True))
    assert listing(robot_dir) == ["a.map"]


def test_replayed_session_is_refused(tmp_path, robot_dir, make_server, proxy) -> None:
    src = tmp_path / "a.map"
    src.write_bytes(make_map(10))
    srv = make_server()
    p = proxy(srv.address)
    send_file(src, *p.address, **client_options())
    recorded = bytes(p.record)
    os.unlink(robot_dir / "a.map")
    import socket

    with socket.create_connection(srv.address) as s:
        s.sendall(recorded)  # a captured session, replayed verbatim
        s.settimeout(5)
        answer = b""
        while chunk := s.recv(65536):
            answer += chunk
    assert b'"reason":"auth_failed"' in answer
    assert listing(robot_dir) == []


def test_replayed_frame_inside_a_session_is_refused(tmp_path, robot_dir, make_server) -> None:
    srv = make_server()
    c = Client(*srv.address, **client_options())
    # send a valid LIST frame twice: same bytes, same sequence number
    frame = c.link.channel.encode(Out(FrameType.LIST, b"{}", ref=1))
    c.link.sock.sendall(frame + frame)
    first = c.link.receive(5)
    assert first is not None and first.type == FrameType.LISTING
    second = c.link.receive(5)
    assert second is not None and second.type == FrameType.REJECT
    assert b"replayed frame: LIST seq" in second.payload and b'"reason":"replay"' in second.payload
    c.link.close()


@pytest.mark.parametrize(
    ("name", "match"),
    [
        ("../escape.map", "no folders allowed"),
        ("/etc/passwd.map", "no folders allowed"),
        ("a\\b.map", "no folders allowed"),
        ("..map", "'..' is not allowed"),
        (".hidden.map", "must not start with '.'"),
        ("bell\x07.map", "control characters"),
        ("x.exe", "only .map, .2d files"),
        ("active.map", "reserved for the active map"),
        ("nul.map", "a device name"),
    ],
)
def test_bad_names_are_refused(tmp_path, robot_dir, make_server, name, match) -> None:
    src = tmp_path / "ok.map"
    src.write_bytes(make_map(10))
    srv = make_server()
    from mapkit.transfer.protocol import Offer, Sender
    from mapkit.transfer.tcp import run

    data = src.read_bytes()
    offer = Offer.for_bytes(name, data)  # the client's own name check is bypassed here
    with pytest.raises(Rejected, match=match) as e, Client(*srv.address, **client_options()) as c:
        run(c.link, Sender(offer, lambda i: data, ref=9))
    assert e.value.status == Status.BAD_NAME
    assert listing(robot_dir) == []
    assert not (tmp_path.parent / "escape.map").exists()


def test_client_checks_names_too(tmp_path, make_server) -> None:
    srv = make_server()
    src = tmp_path / "a.map"
    src.write_bytes(make_map(5))
    with pytest.raises(TransferError, match=r"no folders allowed"):
        send_file(src, *srv.address, name="../../x.map", **client_options())


def test_oversized_offer_is_refused(tmp_path, robot_dir, make_server) -> None:
    src = tmp_path / "big.2d"
    src.write_bytes(os.urandom(50_000))
    srv = make_server(MapFolder(robot_dir, max_size=40_000))
    with pytest.raises(
        Rejected, match=r"too_large: big.2d has 50000 bytes, this robot accepts at most 40000"
    ):
        send_file(src, *srv.address, **client_options())
    assert listing(robot_dir) == []


def test_name_being_written_by_another_client_is_refused(tmp_path, robot_dir, make_server) -> None:
    src = tmp_path / "big.2d"
    src.write_bytes(os.urandom(64 * 1024))
    srv = make_server()
    from mapkit.transfer.protocol import Offer, Request

    with Client(*srv.address, **client_options()) as first:
        # the first client offers and stalls before sending data: the name is now being written
        offer = Offer.for_bytes("big.2d", src.read_bytes(), chunk_size=1024)
        first.link.send([Out(FrameType.OFFER, json.dumps(offer.json()).encode(), ref=77)])
        ack = first.link.receive(5)
        assert ack is not None and ack.type == FrameType.ACCEPT
        with pytest.raises(Rejected, match=r"busy: big.2d is being written by another client") as e:
            send_file(src, *srv.address, **client_options())
        assert e.value.status == Status.BUSY
        del Request
        first.link.close()  # vanish mid-transfer; the robot keeps the partial file for a resume
    assert not (robot_dir / "big.2d").exists()


def test_map_that_does_not_parse_is_refused_and_old_file_stays(
    tmp_path, robot_dir, make_server
) -> None:
    good = make_map(30)
    (robot_dir / "site.map").write_bytes(good)
    bad = tmp_path / "site.map"
    bad.write_bytes(b"2D-Map\nMinPos: 1 2 3\nDATA\n")
    srv = make_server()
    with pytest.raises(
        Rejected, match=r"parse_error: not a valid map: site.map:2: MinPos: expects exactly 2"
    ):
        send_file(bad, *srv.address, **client_options())
    assert (robot_dir / "site.map").read_bytes() == good
    assert listing(robot_dir) == ["site.map"]


def test_load_checks_md5_and_parse_and_keeps_the_active_map(
    tmp_path, robot_dir, make_server
) -> None:
    srv = make_server()
    host, port = srv.address
    (robot_dir / "good.map").write_bytes(make_map(20))
    (robot_dir / "broken.map").write_bytes(b"not a map\n")
    load_map(host, "good.map", port, **client_options())
    active = (robot_dir / "active.map").read_bytes()
    with pytest.raises(Rejected, match=r"md5_mismatch: good.map on the robot has MD5"):
        load_map(host, "good.map", port, md5="0" * 32, **client_options())
    with pytest.raises(
        Rejected, match=r"parse_error: not a valid map: broken.map: not an ARIA map"
    ):
        load_map(host, "broken.map", port, **client_options())
    with pytest.raises(Rejected, match=r"not_found: missing.map: no such map"):
        load_map(host, "missing.map", port, md5="0" * 32, **client_options())
    assert (robot_dir / "active.map").read_bytes() == active
    with pytest.raises(Rejected, match=r"no previous map to roll back to"):
        load_map(host, None, port, rollback=True, **client_options())


def test_fetch_missing_and_bad_names(tmp_path, make_server) -> None:
    srv = make_server()
    with pytest.raises(Rejected, match=r"not_found: nope.map: no such map on this robot"):
        fetch_file(
            srv.address[0], "nope.map", tmp_path / "x.map", port=srv.address[1], **client_options()
        )
    with pytest.raises(Rejected, match=r"bad_name"):
        fetch_file(
            srv.address[0],
            "../../etc/passwd.map",
            tmp_path / "x.map",
            port=srv.address[1],
            **client_options(),
        )
    assert not (tmp_path / "x.map").exists()


def test_receive_only_server_refuses_pull_list_and_load(tmp_path, robot_dir, make_server) -> None:
    srv = make_server(push_only=True)
    with pytest.raises(Rejected, match=r"unsupported: this peer only receives files"):
        list_maps(*srv.address, **client_options())


# -- full disk -------------------------------------------------------------------------------------


@pytest.fixture
def tiny_tmpfs(tmp_path):
    mnt = tmp_path / "tiny"
    mnt.mkdir()
    try:
        subprocess.run(
            ["mount", "-t", "tmpfs", "-o", "size=256k", "tmpfs", str(mnt)],
            check=True,
            capture_output=True,
            timeout=10,
        )
    except (OSError, subprocess.SubprocessError):
        pytest.skip("cannot mount a tmpfs here (needs root); the fault-injection test covers it")
    yield mnt
    subprocess.run(["umount", "-l", str(mnt)], check=False, timeout=10)


def test_full_disk_on_a_small_tmpfs(tmp_path, tiny_tmpfs, make_server) -> None:
    old = make_map(100)
    (tiny_tmpfs / "site.map").write_bytes(old)
    (tiny_tmpfs / "filler.2d").write_bytes(os.urandom(150 * 1024))
    big = tmp_path / "site.map"
    big.write_bytes(make_map(12_000))  # ~140 KB: does not fit beside the filler
    srv = make_server(MapFolder(tiny_tmpfs, reserve=0))
    with pytest.raises(Rejected, match=r"no_space: site.map: no space") as e:
        send_file(big, *srv.address, **client_options())
    assert e.value.status == Status.NO_SPACE
    assert (tiny_tmpfs / "site.map").read_bytes() == old
    assert sorted(os.listdir(tiny_tmpfs)) == ["filler.2d", "site.map"]


def test_disk_filling_up_during_the_transfer(tmp_path, robot_dir, make_server, monkeypatch) -> None:
    old = make_map(100)
    (robot_dir / "site.map").write_bytes(old)
    big = tmp_path / "site.map"
    big.write_bytes(make_map(20_000))
    budget = {"left": 100_000}
    real = os.pwrite

    def limited(fd, data, off):  # a folder that holds 100 KB more, then ENOSPC
        if budget["left"] < len(data):
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        budget["left"] -= len(data)
        return real(fd, data, off)

    monkeypatch.setattr(store_mod, "_pwrite", limited)
    srv = make_server()
    with pytest.raises(Rejected, match=r"no_space: writing site.map: no space left on the device"):
        send_file(big, *srv.address, chunk_size=16 * 1024, **client_options())
    wait_idle(srv)
    assert (robot_dir / "site.map").read_bytes() == old


# -- concurrency -----------------------------------------------------------------------------------


def test_twenty_clients_push_and_pull_at_once(tmp_path, robot_dir, make_server) -> None:
    shared = make_map(3000, 99)
    (robot_dir / "shared.map").write_bytes(shared)
    srv = make_server()
    host, port = srv.address

    def one(i: int) -> tuple[bytes, bytes, bytes]:
        data = make_map(500 + 37 * i, i)
        src = tmp_path / f"c{i}.map"
        src.write_bytes(data)
        send_file(src, host, port, chunk_size=2048, **client_options())
        out = tmp_path / f"pulled{i}.map"
        fetch_file(host, "shared.map", out, port=port, chunk_size=2048, **client_options())
        return data, (robot_dir / f"c{i}.map").read_bytes(), out.read_bytes()

    with ThreadPoolExecutor(20) as pool:
        results = list(pool.map(one, range(20)))
    for data, on_robot, pulled in results:
        assert on_robot == data and pulled == shared
    assert len(list_maps(host, port, **client_options())["maps"]) == 21


# -- TLS -------------------------------------------------------------------------------------------


def test_tls_push_and_pull(tmp_path, robot_dir, make_server, cert) -> None:
    crt, key = cert
    srv = make_server(tls=server_tls_context(str(crt), str(key)))
    src = tmp_path / "a.map"
    src.write_bytes(make_map(2000))
    send_file(
        src, *srv.address, tls=client_tls_context(str(crt)), chunk_size=4096, **client_options()
    )
    assert (robot_dir / "a.map").read_bytes() == src.read_bytes()
    big = tmp_path / "big.2d"  # 1 MiB frames: payloads read in place through TLS
    big.write_bytes(os.urandom(2_500_000))
    send_file(big, *srv.address, tls=client_tls_context(str(crt)), **client_options())
    assert (robot_dir / "big.2d").read_bytes() == big.read_bytes()
    with pytest.raises(LocalTransferError, match=r"TLS with 127.0.0.1:.* failed"):
        send_file(src, *srv.address, tls=client_tls_context(), **client_options())
    with pytest.raises(LocalTransferError, match=r"cannot load the TLS certificate"):
        server_tls_context(str(tmp_path / "missing.pem"))


def test_channel_is_bound_to_the_session(robot_dir, make_server) -> None:
    """A frame encoded for another session is refused (no cross-session replay)."""
    srv = make_server()
    c = Client(*srv.address, **client_options())
    other = Channel(initiator=True, session=(c.link.channel.session or 0) ^ 1)
    c.link.sock.sendall(other.encode(Out(FrameType.LIST, b"{}", ref=1)))
    ev = c.link.receive(5)
    assert ev is not None and ev.type == FrameType.REJECT and b"frame for session" in ev.payload
    c.link.close()


def test_concurrent_threads_do_not_share_sessions(robot_dir, make_server) -> None:
    srv = make_server()
    errors: list[BaseException] = []

    def worker() -> None:
        try:
            for _ in range(5):
                list_maps(*srv.address, **client_options())
        except BaseException as err:  # pragma: no cover - reported below
            errors.append(err)

    threads = [threading.Thread(target=worker) for _ in range(8)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not errors
    assert srv.sessions == 40


def test_a_pushed_map_is_parsed_once_even_when_loaded(
    tmp_path, robot_dir, make_server, monkeypatch
) -> None:
    import mapkit.transfer.folder as folder_mod  # MapFolder parses the maps

    calls: list[str] = []
    real = folder_mod.parse_map

    def counting(data, *, source="<string>"):
        calls.append(source)
        return real(data, source=source)

    monkeypatch.setattr(folder_mod, "parse_map", counting)
    srv = make_server()
    src = tmp_path / "a.map"
    src.write_bytes(make_map(100))
    send_file(src, *srv.address, load=True, **client_options())
    assert calls == ["a.map"]  # parsed on arrival; LOAD knew that content
    (robot_dir / "b.map").write_bytes(make_map(50, 7))  # put there by hand: parsed at LOAD
    load_map(*srv.address[:1], "b.map", srv.address[1], **client_options())
    assert calls == ["a.map", "b.map"]


def test_a_silent_writer_is_taken_over_and_its_partial_file_resumed(
    tmp_path, robot_dir, make_server
) -> None:
    """A terminal that lost its link and comes back need not wait for the stale session."""
    import time

    data = os.urandom(64 * 1024)
    src = tmp_path / "big.2d"
    src.write_bytes(data)
    srv = make_server(takeover_after=0.3)
    from mapkit.transfer.protocol import Offer

    stale = Client(*srv.address, **client_options())
    offer = Offer.for_bytes("big.2d", data, chunk_size=4096)
    stale.link.send([Out(FrameType.OFFER, json.dumps(offer.json()).encode(), ref=1)])
    assert stale.link.receive(5).type == FrameType.ACCEPT
    stale.link.send([Out(FrameType.DATA, data[i * 4096 : (i + 1) * 4096], ref=i) for i in range(5)])
    other = tmp_path / "other" / "big.2d"
    other.parent.mkdir()
    other.write_bytes(os.urandom(64 * 1024))
    with pytest.raises(Rejected, match=r"busy"):  # another file, the writer active: refused
        send_file(other, *srv.address, chunk_size=4096, **client_options())
    time.sleep(0.5)  # now silent for longer than takeover_after
    r = send_file(src, *srv.address, chunk_size=4096, **client_options())
    assert (robot_dir / "big.2d").read_bytes() == data
    assert r["chunks_skipped"] == 5  # what the stale session had written was kept
    stale.link.close()
