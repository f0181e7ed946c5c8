"""Helpers for the transfer tests: client options, a fault-injecting TCP proxy, maps."""

from __future__ import annotations

import os
import socket
import threading
import time
from pathlib import Path
from typing import Any

from mapkit.transfer import MapServer

SECRET = b"test-secret-0123456789abcdef"


def client_options(**kw: Any) -> dict[str, Any]:
    """Client options for tests: the secret, short timeouts."""
    return {"secret": SECRET, "timeout": 5.0, "rto": 0.2, **kw}


def wait_idle(server: MapServer, timeout: float = 5.0) -> None:
    """Wait until the server has no session threads (a cut session has saved its journal)."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        with server._lock:
            if not server._threads:
                return
        time.sleep(0.01)
    raise AssertionError("server sessions did not end")


class Proxy:
    """A TCP proxy on 127.0.0.1 that can cut a connection or flip bits at given stream offsets.

    Args:
        target: ``(host, port)`` to forward to.
        cut_c2s / cut_s2c: Close both ends after forwarding this many bytes in that direction.
        flip_c2s / flip_s2c: Byte offsets (in that direction's stream) whose lowest bit is flipped.
        inject_c2s: ``(offset, bytes)``: insert these bytes into the client's stream at offset.

    Attributes:
        c2s / s2c: Bytes forwarded, over all connections.
        record: Bytes the client sent on the last connection.
    """

    def __init__(self, target: tuple[str, int], *, cut_c2s: int | None = None,
                 cut_s2c: int | None = None, flip_c2s: tuple[int, ...] = (),
                 flip_s2c: tuple[int, ...] = (), inject_c2s: tuple[int, bytes] | None = None) -> None:
        self.target = target
        self.cut = {"c2s": cut_c2s, "s2c": cut_s2c}
        self.flips = {"c2s": set(flip_c2s), "s2c": set(flip_s2c)}
        self.inject = inject_c2s
        self.c2s = 0
        self.s2c = 0
        self.record = bytearray()
        self.sock = socket.create_server(("127.0.0.1", 0))
        self.address = self.sock.getsockname()
        self._stop = False
        self._thread = threading.Thread(target=self._accept, daemon=True)
        self._thread.start()

    def _accept(self) -> None:
        while not self._stop:
            try:
                a, _ = self.sock.accept()
            except OSError:
                return
            b = socket.create_connection(self.target)
            self.record = bytearray()
            state = {"c2s": 0, "s2c": 0, "closed": False}
            for src, dst, d in ((a, b, "c2s"), (b, a, "s2c")):
                threading.Thread(target=self._pump, args=(src, dst, d, state, a, b), daemon=True).start()

    def _pump(self, src: socket.socket, dst: socket.socket, d: str, state: dict[str, Any],
              a: socket.socket, b: socket.socket) -> None:
        try:
            while True:
                data = bytearray(src.recv(65536))
                if not data:
                    break
                pos = state[d]
                for off in self.flips[d]:
                    if pos <= off < pos + len(data):
                        data[off - pos] ^= 0x01
                if d == "c2s" and self.inject and pos <= self.inject[0] < pos + len(data):
                    k = self.inject[0] - pos
                    data[k:k] = self.inject[1]
                cut = self.cut[d]
                if cut is not None and pos + len(data) >= cut:
                    data = data[: max(0, cut - pos)]
                    dst.sendall(data)
                    self._count(d, len(data))
                    break
                dst.sendall(data)
                state[d] += len(data)
                self._count(d, len(data))
                if d == "c2s":
                    self.record += data
        except OSError:
            pass
        for s in (a, b):
            try:
                s.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass
            s.close()

    def _count(self, d: str, n: int) -> None:
        if d == "c2s":
            self.c2s += n
        else:
            self.s2c += n

    def close(self) -> None:
        self._stop = True
        self.sock.close()


def make_map(points: int, seed: int = 0) -> bytes:
    """A valid ARIA map with ``points`` points (about 12 bytes each)."""
    import random

    rng = random.Random(seed)
    rows = "".join(f"{rng.randrange(-50000, 50000)} {rng.randrange(-50000, 50000)}\n" for _ in range(points))
    return ("2D-Map\nCairn: Goal 1000 2000 0 \"\" ICON \"Desk\"\nDATA\n" + rows).encode()


def listing(folder: Path) -> list[str]:
    """Every entry of a folder, hidden ones included, sorted."""
    return sorted(os.listdir(folder))
