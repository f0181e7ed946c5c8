"""Helpers for the transfer tests: client options, a fault-injecting TCP proxy, maps."""

from __future__ import annotations

import contextlib
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

    def __init__(
        self,
        target: tuple[str, int],
        *,
        cut_c2s: int | None = None,
        cut_s2c: int | None = None,
        flip_c2s: tuple[int, ...] = (),
        flip_s2c: tuple[int, ...] = (),
        inject_c2s: tuple[int, bytes] | None = None,
    ) -> None:
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
                threading.Thread(
                    target=self._pump, args=(src, dst, d, state, a, b), daemon=True
                ).start()

    def _pump(
        self,
        src: socket.socket,
        dst: socket.socket,
        d: str,
        state: dict[str, Any],
        a: socket.socket,
        b: socket.socket,
    ) -> None:
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
            with contextlib.suppress(OSError):
                s.shutdown(socket.SHUT_RDWR)
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
    rows = "".join(
        f"{rng.randrange(-50000, 50000)} {rng.randrange(-50000, 50000)}\n" for _ in range(points)
    )
    return ('2D-Map\nCairn: Goal 1000 2000 0 "" ICON "Desk"\nDATA\n' + rows).encode()


def listing(folder: Path) -> list[str]:
    """Every entry of a folder, hidden ones included, sorted."""
    return sorted(os.listdir(folder))


# -- a real `mapkit serve` process, raw peers, a proxy that freezes ----------------------------


class ServeProcess:
    """``python -m mapkit serve FOLDER --listen 127.0.0.1:0`` in the background, its log in a file.

    Attributes:
        port: The port it listens on.
        log_path: Its stderr.
    """

    def __init__(self, folder: Path, secret_file: Path, *args: str, log_path: Path) -> None:
        import re
        import subprocess
        import sys

        env = {**os.environ, "PYTHONUNBUFFERED": "1"}
        env.pop("MAPKIT_SECRET", None)
        self.log_path = log_path
        self._log = open(log_path, "wb")  # noqa: SIM115 - closed in stop()
        self.proc = subprocess.Popen(
            [
                sys.executable,
                "-m",
                "mapkit",
                "serve",
                str(folder),
                "--listen",
                "127.0.0.1:0",
                "--secret-file",
                str(secret_file),
                *args,
            ],
            stderr=self._log,
            stdout=subprocess.DEVNULL,
            env=env,
        )
        end = time.monotonic() + 60
        while True:
            m = re.search(r"on 127\.0\.0\.1:(\d+) \(", self.log())
            if m:
                self.port = int(m.group(1))
                break
            if self.proc.poll() is not None or time.monotonic() > end:
                raise AssertionError(f"mapkit serve did not start:\n{self.log()}")
            time.sleep(0.05)

    @property
    def address(self) -> tuple[str, int]:
        return "127.0.0.1", self.port

    def log(self) -> str:
        return self.log_path.read_text(errors="replace")

    def alive(self) -> bool:
        return self.proc.poll() is None

    def stop(self) -> int:
        import signal
        import subprocess

        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
            try:
                self.proc.wait(20)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(10)
        self._log.close()
        return int(self.proc.returncode)


def silent_connection(address: tuple[str, int], source: str = "127.0.0.1") -> socket.socket:
    """A TCP connection that never sends a byte (from ``source``, any 127.x.y.z on Linux)."""
    s = socket.socket()
    s.bind((source, 0))
    s.connect(address)
    return s


def closed_by_peer(sock: socket.socket, timeout: float) -> bool:
    """True when the peer closes (or resets) ``sock`` within ``timeout`` s (reads are dropped)."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        sock.settimeout(max(0.01, end - time.monotonic()))
        try:
            if not sock.recv(65536):
                return True
        except TimeoutError:
            return False
        except OSError:
            return True
    return False


def raw_session(
    address: tuple[str, int], secret: bytes | None = SECRET, *, timeout: float = 5.0
) -> Any:
    """An authenticated MKT session over a plain socket: ``(FrameLink, next_ref)``; send any frame
    (numbered and tagged by the session's channel) with ``link.send([Out(...)])``."""
    import secrets as _secrets

    from mapkit.transfer.protocol import Channel, ClientHandshake
    from mapkit.transfer.tcp import FrameLink, connect, run

    sock = connect(*address, timeout=timeout)
    channel = Channel(initiator=True, session=_secrets.randbits(64) or 1)
    link = FrameLink(sock, channel, peer="robot")
    run(link, ClientHandshake(link.channel, secret, peer="raw", idle_timeout=timeout))
    return link


class FreezeProxy:
    """A TCP proxy that forwards until ``freeze_after`` bytes went client→server, then forwards
    nothing more in either direction and keeps both connections open: a Wi-Fi cut, as the robot
    sees it (no FIN, no RST, just silence).

    Attributes:
        frozen: Set when the cut happened.
    """

    def __init__(self, target: tuple[str, int], freeze_after: int) -> None:
        self.target = target
        self.freeze_after = freeze_after
        self.frozen = threading.Event()
        self.sock = socket.create_server(("127.0.0.1", 0))
        self.address = self.sock.getsockname()
        self._held: list[socket.socket] = []
        self._c2s = 0
        threading.Thread(target=self._accept, daemon=True).start()

    def _accept(self) -> None:
        try:
            a, _ = self.sock.accept()
        except OSError:
            return
        b = socket.create_connection(self.target)
        self._held += [a, b]
        threading.Thread(target=self._pump, args=(a, b, True), daemon=True).start()
        threading.Thread(target=self._pump, args=(b, a, False), daemon=True).start()

    def _pump(self, src: socket.socket, dst: socket.socket, c2s: bool) -> None:
        try:
            while not self.frozen.is_set():
                data = src.recv(65536)
                if not data or self.frozen.is_set():
                    return
                if c2s:
                    room = self.freeze_after - self._c2s
                    if len(data) >= room:
                        dst.sendall(data[: max(0, room)])
                        self._c2s += max(0, room)
                        self.frozen.set()
                        return
                    self._c2s += len(data)
                dst.sendall(data)
        except OSError:
            return

    def close(self) -> None:
        self.sock.close()
        for s in self._held:
            s.close()  # closing a closed socket is harmless


def fails_once(real: Any, error: BaseException) -> Any:
    """``real`` wrapped so that its first call raises ``error`` (a bug met once), then works."""
    calls = {"n": 0}

    def wrapper(*args: Any, **kw: Any) -> Any:
        calls["n"] += 1
        if calls["n"] == 1:
            raise error
        return real(*args, **kw)

    return wrapper
