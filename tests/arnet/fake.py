"""A hostile ArNetworking server: real TCP on 127.0.0.1, a good login, then scripted packets.

Each :class:`FakeServer` accepts connections in a thread, introduces itself, accepts any login,
announces a few commands, and answers each request with whatever its ``reply`` function returns
(raw bytes, so they can break every rule: checksums, lengths, layouts, or never come).
"""

from __future__ import annotations

import contextlib
import socket
import struct
import threading
from collections.abc import Callable
from typing import Any

from mapkit.arnet.packet import Payload, encode
from mapkit.arnet.reader import PacketReader

#: The commands the fake server announces, with their ids.
IDS = {
    "getMapName": 300,
    "getMapId": 301,
    "getFile": 302,
    "getMap": 303,
    "mapUpdated": 304,
    "getDirListingMultiplePackets": 305,
    "putFile": 306,
}
NAMES = {v: k for k, v in IDS.items()}

Reply = Callable[[str, bytes], Any]


def frame(command: int | str, data: bytes = b"") -> bytes:
    """A correct packet (ids by name from :data:`IDS`)."""
    return encode(IDS[command] if isinstance(command, str) else command, data)


def raw_frame(
    command: int, data: bytes, length: int | None = None, check: int | None = None
) -> bytes:
    """A packet with any length field and checksum (defaults: the correct ones)."""
    good = encode(command, data)
    n = len(good) if length is None else length
    c = struct.unpack(">H", good[-2:])[0] if check is None else check
    return b"\x0f\x0c" + struct.pack("<HH", n, command) + data + struct.pack(">H", c)


def file_packet(data: bytes, name: str = "x.map", count: int | None = None) -> bytes:
    """A getFile reply packet carrying ``data`` (``count`` may lie about its size)."""
    n = len(data) if count is None else count
    return frame("getFile", Payload().ubyte2(0).string(name).ubyte4(n).raw(data).bytes())


def login_packets() -> bytes:
    """CONNECTED and the three command lists."""
    lst, argret, groups = (
        Payload().ubyte2(len(IDS)),
        Payload().ubyte2(len(IDS)),
        Payload().ubyte2(len(IDS)),
    )
    for name, cid in IDS.items():
        lst.ubyte2(cid).string(name).string("fake")
        argret.ubyte2(cid).string("").string("")
        groups.ubyte2(cid).string("Map").string("RETURN_SINGLE")
    return (
        encode(5)
        + encode(129, lst.bytes())
        + encode(131, argret.bytes())
        + encode(133, groups.bytes())
    )


def intro_packet() -> bytes:
    return encode(
        2, Payload().string("alpha").ubyte2(0).ubyte4(1).ubyte4(2).string("key").string("").bytes()
    )


class FakeServer:
    """Serve ``reply(name, args)`` for every request; ``reply`` returns bytes to send, a float
    (seconds to stall before closing), a function of the socket, or None (send nothing).

    Args:
        reply: The script.
        after_login: Bytes sent right after the login (before any request).
        intro: Bytes sent instead of the introduction.
        login: Bytes sent instead of CONNECTED and the command lists.
    """

    def __init__(
        self,
        reply: Reply | None = None,
        *,
        after_login: bytes = b"",
        intro: bytes | None = None,
        login: bytes | None = None,
    ) -> None:
        self.login = login_packets() if login is None else login
        self.reply = reply or (lambda name, args: None)
        self.after_login = after_login
        self.intro = intro_packet() if intro is None else intro
        self.sock = socket.create_server(("127.0.0.1", 0))
        self.port = int(self.sock.getsockname()[1])
        self.requests: list[tuple[str, bytes]] = []
        self.stop = threading.Event()
        self.errors: list[BaseException] = []
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    @property
    def address(self) -> str:
        return f"127.0.0.1:{self.port}"

    def _run(self) -> None:
        self.sock.settimeout(0.2)
        while not self.stop.is_set():
            try:
                conn, _ = self.sock.accept()
            except (TimeoutError, OSError):
                continue
            with conn:
                try:
                    self._session(conn)
                except OSError:
                    pass
                except Exception as e:  # pragma: no cover - shows in the test that uses it
                    self.errors.append(e)

    def _session(self, conn: socket.socket) -> None:
        conn.settimeout(0.2)
        conn.sendall(self.intro)
        reader = PacketReader()
        logged_in = False
        while not self.stop.is_set():
            try:
                data = conn.recv(65536)
            except TimeoutError:
                continue
            if not data:
                return
            for p in reader.feed(data):
                if p.command == 2 and not logged_in:
                    logged_in = True
                    conn.sendall(self.login + self.after_login)
                elif p.command in NAMES:
                    name = NAMES[p.command]
                    self.requests.append((name, p.data))
                    out = self.reply(name, p.data)
                    if isinstance(out, float):
                        self.stop.wait(out)
                        return
                    if isinstance(out, bytes | bytearray):
                        conn.sendall(out)
                    elif callable(out):
                        out(conn)

    def close(self) -> None:
        self.stop.set()
        with contextlib.suppress(OSError):
            self.sock.close()
        self.thread.join(5)


def drip(data: bytes, every: float, stop: threading.Event) -> Callable[[socket.socket], None]:
    """Send ``data`` one byte every ``every`` seconds (a server that keeps the line barely
    alive)."""

    def go(conn: socket.socket) -> None:
        for b in data:
            if stop.wait(every):
                return
            conn.sendall(bytes([b]))

    return go
