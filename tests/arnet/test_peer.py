"""mapkit's ArNetworking client against ARIA 2.9.1's own server, checked with ARIA's own client.

One ``run-mapserver`` serves the module: every real sample map, logins from a user file
(``admin`` may do everything, ``mapper`` has only the map service).
"""

from __future__ import annotations

import hashlib
import os
import signal
from pathlib import Path

import pytest

import mapkit
from mapkit import aria
from tests.arnet.peer import ADMIN, MAPPER, Peer, leftovers, start_peer

pytestmark = pytest.mark.network

#: Maps ARIA 2.9.1 cannot load (it reads 2D-Map up to 2D-Map-Ex3).
NOT_LOADABLE = {"omron-ld-showroom-ex4.map"}


def robot(peer: Peer, login: tuple[str, str] = ADMIN, **kw: object) -> aria.Robot:
    return aria.connect(peer.address, user=login[0], password=login[1], **kw)  # type: ignore[arg-type]


def loadable(maps: list[Path]) -> list[Path]:
    return [m for m in maps if m.name not in NOT_LOADABLE]


def test_login_learns_the_command_list(peer: Peer) -> None:
    with robot(peer) as r:
        cmds = r.client.commands
        listed = peer.probe("list").stdout
        assert len(cmds) == listed.count(" group=") == 40
        for name, info in cmds.items():
            assert f"{info.id} {name} group={info.group}" in listed
        assert (
            cmds["getFile"].group == "FileAccess" and "RETURN_UNTIL_EMPTY" in cmds["getFile"].flags
        )
        assert r.map_name == peer.mapname()


def test_every_loadable_real_map_fetched_equal(peer: Peer, real_maps: list[Path]) -> None:
    """Each real map the robot loads: the file service gives its exact bytes (checked against
    the robot's map id), the map service a map that parses equal to the file served."""
    with robot(peer) as r:
        previous = r.map_name
        try:
            for path in loadable(real_maps):
                r.load_map(path.name)
                assert peer.mapname() == path.name
                exact = r.fetch(via="file")
                assert exact.data == path.read_bytes(), path.name
                assert exact.verified and exact.robot_md5 == exact.md5
                expected = mapkit.load(path)
                assert exact.map == expected
                rebuilt = r.fetch(via="map")
                assert rebuilt.source == "map service" and rebuilt.map == expected, path.name
        finally:
            r.load_map(previous)


def test_fetch_a_named_file_that_is_not_active(peer: Peer, real_maps: list[Path]) -> None:
    ex4 = next(m for m in real_maps if m.name in NOT_LOADABLE)
    with robot(peer) as r:
        got = r.fetch(ex4.name)
        assert got.data == ex4.read_bytes() and got.source == "file"
        assert got.map == mapkit.load(ex4) and got.map.category == "2D-Map-Ex4"
        with pytest.raises(aria.AriaRemoteError, match="only the active map"):
            r.fetch(ex4.name, via="map")


def test_uploads_are_byte_exact_for_arias_client(
    peer: Peer, tmp_path: Path, real_maps: list[Path]
) -> None:
    blob = os.urandom(95_000) + b"\0\r\n\xff" * 10  # several packets, a short last one
    with robot(peer) as r:
        r.put_file(blob, "blob.bin")
        r.put_file(b"", "empty.bin")
        r.put_file(real_maps[0].read_bytes(), "sub-copy.map")
        names = {e.name: e.size for e in r.files()}
        assert names["blob.bin"] == len(blob) and names["empty.bin"] == 0
        assert r.read_file("blob.bin") == blob
        r.delete_file("sub-copy.map")
        assert "sub-copy.map" not in {e.name for e in r.files()}
        with pytest.raises(aria.AriaRemoteError, match="does not exist"):
            r.delete_file("sub-copy.map")
    assert peer.probe_get("blob.bin", tmp_path / "b") == blob
    assert peer.probe_get("empty.bin", tmp_path / "e") == b""
    assert (peer.root / "blob.bin").read_bytes() == blob


def test_paths_outside_the_shared_folder_are_refused(peer: Peer, tmp_path: Path) -> None:
    with robot(peer) as r:
        with pytest.raises(aria.AriaRemoteError, match=r"outside|does not exist"):
            r.read_file("../users.txt")
        with pytest.raises(aria.AriaRemoteError, match=r"outside|does not exist"):
            r.read_file("root/../aria-office.map")
        with pytest.raises(aria.AriaRemoteError, match="not a folder"):
            r.files("no-such-dir")
        with pytest.raises(aria.AriaRemoteError, match="does not exist"):
            r.get_file("missing.map", tmp_path / "missing.map")
        assert r.read_file("aria-office.map") == (peer.root / "aria-office.map").read_bytes()
        with pytest.raises(aria.AriaRemoteError, match=r"outside|folder that does not exist"):
            r.put_file(b"x", "../escaped.txt")
    assert not (peer.root.parent / "escaped.txt").exists()
    assert leftovers(tmp_path) == []


def test_send_load_switches_and_ex4_is_rolled_back(peer: Peer, real_maps: list[Path]) -> None:
    office = next(m for m in real_maps if m.name == "aria-office.map")
    tri = next(m for m in real_maps if m.name == "aria-triangle.map")
    ex4 = next(m for m in real_maps if m.name in NOT_LOADABLE)
    with robot(peer) as r:
        r.load_map(office.name)
        res = r.send_map(tri, "sent-tri.map", load=True)
        assert res["loaded"] and res["previous"] == office.name and res["broadcast"]
        assert peer.mapname() == "sent-tri.map"
        assert res["robot_md5"] == res["md5"] == hashlib.md5(tri.read_bytes()).hexdigest()
        assert (peer.root / "sent-tri.map").read_bytes() == tri.read_bytes()
        # a map the robot cannot load, sent under a new name: refused, removed, old map active
        with pytest.raises(aria.AriaRemoteError, match=r"could not load 'new-ex4.map'.*removed"):
            r.send_map(ex4, "new-ex4.map", load=True)
        assert peer.mapname() == "sent-tri.map" and r.map_name == "sent-tri.map"
        assert not (peer.root / "new-ex4.map").exists()
        # ... sent over the active map's own file: the old file comes back
        with pytest.raises(aria.AriaRemoteError, match=r"restored robot file 'sent-tri.map'"):
            r.send_map(ex4, "sent-tri.map", load=True)
        assert (peer.root / "sent-tri.map").read_bytes() == tri.read_bytes()
        assert peer.mapname() == "sent-tri.map"
        # a changed version of the active map, under its own name: reloaded, confirmed by MD5
        changed = mapkit.load(tri)
        changed = changed.replace(
            objects=(*changed.objects, mapkit.MapObject("Goal", 10, 20, 0, name="New"))
        )
        res = r.send_map(changed, "sent-tri.map", load=True)
        assert res["robot_md5"] == res["md5"] == hashlib.md5(mapkit.dumpb(changed)).hexdigest()
        assert res["broadcast"] and res["previous"] == "sent-tri.map"
        assert "New" in peer.probe("goals").stdout
        r.load_map(office.name)


def test_maps_with_errors_are_refused_before_sending(peer: Peer, tmp_path: Path) -> None:
    bad = tmp_path / "bad.map"
    for text, code in (
        ("2D-Map\nResolution: 20 mm\nDATA\n1 1\n", "bad.map:2: error MK110"),
        ("2D-Map\nDATA\n1 99999999999\n", "MK304"),
        ('2D-Map\nCairn: Goal nan 0 0 "" ICON "g"\nDATA\n', "bad.map:2.*MK107"),
    ):
        bad.write_text(text)
        with robot(peer) as r, pytest.raises(aria.AriaMapRefusedError, match=f"not sent.*{code}"):
            r.send_map(bad, load=True)
    not_a_map = tmp_path / "notes.map"
    not_a_map.write_text("hello\n")
    with (
        robot(peer) as r,
        pytest.raises(mapkit.MapFormatError, match=r"notes.map: not an ARIA map"),
    ):
        r.send_map(not_a_map)
    assert not (peer.root / "bad.map").exists() and not (peer.root / "notes.map").exists()


def test_watch_sees_each_change_and_keeps_versions(peer: Peer, tmp_path: Path) -> None:
    with robot(peer) as r:
        r.load_map("aria-office.map")
        seen = []
        for ch in r.watch(save_dir=tmp_path / "versions"):
            seen.append(ch)
            if ch.initial:
                res = peer.probe("setmap", "aria-triangle.map", "5")
                assert "save succeeded" in res.stdout, res.stdout
            else:
                break
        r.load_map("aria-office.map")
    assert [c.name for c in seen] == ["aria-office.map", "aria-triangle.map"]
    assert seen[0].initial and not seen[1].initial
    kept = sorted((tmp_path / "versions").iterdir())
    assert len(kept) == 2
    assert {p.read_bytes() for p in kept} == {(peer.root / c.name).read_bytes() for c in seen}


def test_wrong_password_and_unknown_user(peer: Peer) -> None:
    for login in (("admin", "wrong"), ("nobody", "secret1"), ("", "")):
        with pytest.raises(
            aria.AriaLoginError, match=r"refused the login.*wrong user name or password"
        ) as e:
            robot(peer, login)
        assert e.value.code == 1 and "\n" not in str(e.value)


def test_user_without_file_rights(peer: Peer, tmp_path: Path) -> None:
    with robot(peer, MAPPER) as r:
        assert not r.client.offers("getFile") and r.client.offers("getMap")
        info = r.info()
        assert info["can"]["fetch_map"] and not info["can"]["fetch_exact"]
        assert not info["can"]["upload"] and not info["can"]["load_map"]
        got = r.fetch()  # falls back to the map service
        assert got.source == "map service" and got.map == mapkit.load(peer.root / got.name)
        for call in (
            lambda: r.get_file("aria-office.map", tmp_path / "x.map"),
            lambda: r.put_file(b"x", "x.map"),
            lambda: r.files(),
            lambda: r.delete_file("aria-office.map"),
            lambda: r.load_map("x.map"),
        ):
            with pytest.raises(
                aria.AriaPermissionError, match=r"does not offer '\w+' to user 'mapper'"
            ):
                call()
    assert leftovers(tmp_path) == []


def test_server_killed_mid_transfer_leaves_nothing(tmp_path: Path) -> None:
    big = tmp_path / "big.bin"
    big.write_bytes(os.urandom(3_000_000))
    p = start_peer(tmp_path / "srv", [big], login=None)
    out = tmp_path / "out"
    out.mkdir()
    try:
        with aria.connect(p.address, timeout=5) as r:

            def kill(done: int, _total: int) -> None:
                if p.proc.poll() is None:
                    os.kill(p.proc.pid, signal.SIGKILL)
                    p.proc.wait()

            with pytest.raises(aria.AriaConnectionError, match=r"closed the connection|broke") as e:
                r.get_file("big.bin", out / "big.bin", progress=kill)
            assert "\n" not in str(e.value)
    finally:
        p.stop()
    assert leftovers(out) == []


def test_server_killed_mid_upload_leaves_no_half_file(tmp_path: Path) -> None:
    p = start_peer(tmp_path / "srv", [], login=None)
    try:
        with aria.connect(p.address, timeout=5) as r:

            def kill(done: int, _total: int) -> None:
                if done > 200_000 and p.proc.poll() is None:
                    os.kill(p.proc.pid, signal.SIGKILL)
                    p.proc.wait()

            with pytest.raises(aria.AriaConnectionError):
                r.put_file(os.urandom(3_000_000), "up.bin", progress=kill)
    finally:
        p.stop()
    assert leftovers(p.root) == []  # ARIA stages uploads elsewhere and renames when complete
