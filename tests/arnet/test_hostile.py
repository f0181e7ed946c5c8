"""A server that breaks the protocol (real TCP, a Python fake): one clear error, in time, and
nothing left behind: no output file, no temp file.

Every case runs ``mapkit aria fetch`` (and ``get``) in-process with ``--timeout 1``.
"""

from __future__ import annotations

import hashlib
import re
import socket
import threading
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest
from click.testing import CliRunner

from mapkit import aria
from mapkit.arnet.packet import Payload, encode
from mapkit.cli.main import cli
from tests.arnet.fake import IDS, FakeServer, drip, file_packet, frame, raw_frame
from tests.arnet.peer import leftovers

pytestmark = pytest.mark.network

NAME = frame("getMapName", b"x.map\0")
MAP_ID = frame("getMapId", b"\0x.map\0" + (16).to_bytes(4, "little") + bytes(range(16)) + b"\0" * 8)
TEXT = b"2D-Map\nDATA\n1 1\n"


def map_server(on_file: Callable[[], Any]) -> Callable[[str, bytes], Any]:
    """Answer getMapName/getMapId well and getFile with ``on_file()``."""

    def reply(name: str, _args: bytes) -> Any:
        if name == "getMapName":
            return NAME
        if name == "getMapId":
            return MAP_ID
        return on_file()

    return reply


@pytest.fixture
def fake() -> Iterator[Callable[..., FakeServer]]:
    made: list[FakeServer] = []

    def make(*a: Any, **kw: Any) -> FakeServer:
        s = FakeServer(*a, **kw)
        made.append(s)
        return s

    yield make
    for s in made:
        s.close()


def run_fetch(server: FakeServer, out: Path, *extra: str) -> tuple[int, str]:
    res = CliRunner().invoke(
        cli, ["aria", "fetch", server.address, "-o", str(out / "x.map"), "--timeout", "1", *extra]
    )
    return res.exit_code, res.output


STOP = threading.Event()
CASES: dict[str, tuple[Callable[[], Any], str]] = {
    "bad checksum": (
        lambda: raw_frame(IDS["getFile"], b"\0\0x\0\0\0\0\0", check=0x1234),
        r"checksum 0x1234, expected",
    ),
    "announced length longer than sent, then silence": (
        lambda: raw_frame(IDS["getFile"], b"\0\0x\0", length=2000),
        r"sent nothing for 1 s",
    ),
    "oversize packet": (
        lambda: raw_frame(IDS["getFile"], b"\0" * 10, length=40000),
        r"announced a 40000-byte packet; ArNetworking packets are 8 to 32000",
    ),
    "length under the header": (
        lambda: raw_frame(IDS["getFile"], b"", length=5),
        r"announced a 5-byte packet",
    ),
    "chunk count larger than the chunk": (
        lambda: file_packet(TEXT, count=30000),
        r"says it carries 30000 bytes .* holds 16",
    ),
    "chunk count smaller than the chunk": (
        lambda: file_packet(TEXT, count=3),
        r"says it carries 3 bytes .* holds 16",
    ),
    "string without its NUL": (lambda: frame("getFile", b"\0\0no-nul"), r"has no terminating NUL"),
    "packet cut inside a field": (lambda: frame("getFile", b"\0"), r"ends inside a ubyte2 field"),
    "garbage instead of a packet": (
        lambda: b"HTTP/1.1 400 Bad Request\r\n\r\n",
        r"sent 4854 where a packet must start with 0f0c",
    ),
    "an unannounced command id": (lambda: frame(999, b"x"), r"command 999, which is not in"),
    "stall": (lambda: None, r"sent nothing for 1 s while receiving the reply to getFile"),
    "byte by byte, never a whole packet": (
        lambda: drip(file_packet(TEXT), 0.4, STOP),
        r"sent nothing for 1 s",
    ),
    "closed in the middle of the reply": (lambda: file_packet(TEXT)[:12] + b"", r"."),
    "the file never ends": (lambda: file_packet(TEXT), r"sent nothing for 1 s"),
    "an error code": (lambda: frame("getFile", b"\x02\0x.map\0"), r"'x.map' does not exist"),
    "a file that is not a map": (
        lambda: file_packet(b"hello\n") + file_packet(b"") + frame("getFile"),
        r"127.0.0.1:\d+/other.map: not an ARIA map",
    ),
    "bytes that do not match the map id": (
        lambda: file_packet(TEXT) + file_packet(b"") + frame("getFile"),
        r"\(MD5 3015614a8823cf9f80bee3b51908d442\) is not the map the robot has loaded "
        r"\(MD5 000102030405060708090a0b0c0d0e0f\)",
    ),
}


@pytest.mark.parametrize("case", list(CASES))
def test_broken_server_gives_one_line_and_leaves_nothing(
    case: str, fake: Any, tmp_path: Path
) -> None:
    on_file, expected = CASES[case]
    server = fake(map_server(on_file))
    if case == "closed in the middle of the reply":
        server.reply = map_server(lambda: file_packet(TEXT)[:12])
        server.reply = _then_close(server.reply)
    extra = ["--name", "other.map"] if case == "a file that is not a map" else []
    code, out = run_fetch(server, tmp_path, "--via", "file", *extra)
    assert code == 1, out
    lines = out.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("Error: "), out
    assert re.search(expected, lines[0]), lines[0]
    assert leftovers(tmp_path) == [], case


def _then_close(reply: Callable[[str, bytes], Any]) -> Callable[[str, bytes], Any]:
    def go(name: str, args: bytes) -> Any:
        out = reply(name, args)
        if name != "getFile":
            return out

        def send_and_close(conn: Any) -> None:
            conn.sendall(out)
            conn.shutdown(2)

        return send_and_close

    return go


def test_endless_file_hits_the_size_limit_and_writes_nothing(fake: Any, tmp_path: Path) -> None:
    chunk = file_packet(b"x" * 30000)
    server = fake(map_server(lambda: chunk * 40))
    with (
        aria.connect(server.address, timeout=2) as r,
        pytest.raises(aria.AriaProtocolError, match="larger than 500000 bytes"),
    ):
        r.get_file("x.map", tmp_path / "x.map", max_size=500_000)
    assert leftovers(tmp_path) == []


def test_bad_login_exchanges(fake: Any, tmp_path: Path) -> None:
    cases = {
        b"": "sent nothing for 1 s while logging in",
        frame(2, b"alpha\0"): "ends inside a ubyte2 field",
        raw_frame(5, b"") + b"": "sent CONNECTED while waiting for the server's introduction",
        frame(6, b"\x01\x00\0"): "refused the login.*wrong user name or password",
    }
    for intro, expected in cases.items():
        server = fake(intro=intro)
        res = CliRunner().invoke(cli, ["aria", "info", server.address, "--timeout", "1"])
        assert res.exit_code == 1, res.output
        assert len(res.output.strip().splitlines()) == 1
        assert re.search(expected, res.output), res.output
    assert leftovers(tmp_path) == []


def test_list_with_a_lying_count(fake: Any) -> None:
    lying = encode(5) + encode(
        129, Payload().ubyte2(3).ubyte2(300).string("getMapName").string("").bytes()
    )
    server = fake(login=lying)
    with pytest.raises(aria.AriaProtocolError, match="LIST: the server's packet ends inside"):
        aria.connect(server.address, timeout=1)


def test_nothing_listening() -> None:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    with pytest.raises(
        aria.AriaConnectionError, match=f"cannot connect to the robot at 127.0.0.1:{port}"
    ):
        aria.connect(f"127.0.0.1:{port}", timeout=1)


def test_watch_ends_when_the_robot_goes_away(fake: Any) -> None:
    served = {"getFile": 0}

    def reply(name: str, args: bytes) -> Any:
        if name == "getFile":
            served["getFile"] += 1
            body = file_packet(TEXT) + file_packet(b"") + frame("getFile")

            def send_then_close(conn: socket.socket) -> None:
                conn.sendall(body)
                STOP.wait(0.3)
                conn.shutdown(socket.SHUT_RDWR)

            return send_then_close
        if name == "getMapId":
            digest = hashlib.md5(TEXT).digest()
            return frame("getMapId", b"\0x.map\0" + (16).to_bytes(4, "little") + digest + b"\0" * 8)
        return map_server(lambda: None)(name, args)

    server = fake(reply)
    server.reply = reply
    with aria.connect(server.address, timeout=2) as r:
        changes = r.watch()
        first = next(changes)
        assert first.initial and first.name == "x.map" and first.map.points.tolist() == [[1, 1]]
        assert first.source == "file"
        with pytest.raises(aria.AriaConnectionError, match="closed the connection while waiting"):
            next(changes)
    assert served["getFile"] == 1
