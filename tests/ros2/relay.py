"""Reach a TCP server on the host from inside the test network namespace, through a Unix socket
(filesystem sockets are not per network namespace).

Inside the namespace: ``python -m tests.ros2.relay UNIX_PATH`` listens on a loopback TCP port,
prints it, and forwards each connection to ``UNIX_PATH``. On the host, :func:`serve_unix` forwards
each connection on ``UNIX_PATH`` to a TCP port.
"""

from __future__ import annotations

import contextlib
import socket
import sys
import threading


def _pump(src: socket.socket, dst: socket.socket) -> None:
    try:
        while data := src.recv(65536):
            dst.sendall(data)
    except OSError:
        pass
    finally:
        for s in (src, dst):
            with contextlib.suppress(OSError):
                s.shutdown(socket.SHUT_RDWR)


def _join(a: socket.socket, b: socket.socket) -> None:
    threading.Thread(target=_pump, args=(a, b), daemon=True).start()
    threading.Thread(target=_pump, args=(b, a), daemon=True).start()


def serve_unix(path: str, port: int) -> socket.socket:
    """Forward connections on the Unix socket ``path`` to 127.0.0.1:``port`` (daemon thread)."""
    srv = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    srv.bind(path)
    srv.listen(8)

    def loop() -> None:
        while True:
            try:
                conn, _ = srv.accept()
            except OSError:
                return
            _join(conn, socket.create_connection(("127.0.0.1", port)))

    threading.Thread(target=loop, daemon=True).start()
    return srv


def main() -> None:
    srv = socket.socket()
    srv.bind(("127.0.0.1", 0))
    srv.listen(8)
    print(srv.getsockname()[1], flush=True)
    while True:
        conn, _ = srv.accept()
        up = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        up.connect(sys.argv[1])
        _join(conn, up)


if __name__ == "__main__":
    main()
