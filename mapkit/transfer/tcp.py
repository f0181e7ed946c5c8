"""MKT/1 over TCP: blocking sockets with timeouts, optional TLS, and the loop that drives a machine.

A :class:`FrameLink` joins a socket and a :class:`~mapkit.transfer.protocol.Channel`: ``send``
writes :class:`~mapkit.transfer.protocol.Out` frames with one gather write each (no copy of
chunk data on plain TCP), ``receive`` reads with ``recv_into`` through
:meth:`~mapkit.transfer.protocol.Channel.receive_into` (a large payload lands in its own buffer,
copied once by the kernel) and returns the next frame.
:func:`run` drives any protocol machine over a link until it finishes.
"""

from __future__ import annotations

import contextlib
import socket
import ssl
import time
from collections.abc import Callable, Iterable
from typing import Any

from mapkit.errors import LocalTransferError
from mapkit.transfer.protocol import DEFAULT_PORT, Channel, Event, Out

__all__ = [
    "FrameLink",
    "client_tls_context",
    "connect",
    "listen",
    "parse_address",
    "run",
    "server_tls_context",
    "tune_socket",
]

RECV_BUFFER = 64 * 1024  # largest read outside a large payload
IOV_MAX = 512


def parse_address(
    text: str, default_port: int = DEFAULT_PORT, *, default_host: str = ""
) -> tuple[str, int]:
    """Split ``HOST[:PORT]`` (``[v6]:PORT`` for IPv6) into host and port.

    Raises:
        LocalTransferError: When the port is not a number in 0..65535.

    Examples:
        >>> parse_address("robot")
        ('robot', 7373)
        >>> parse_address("10.0.0.5:9000")
        ('10.0.0.5', 9000)
        >>> parse_address("[::1]:80")
        ('::1', 80)
        >>> parse_address(":7400", default_host="0.0.0.0")
        ('0.0.0.0', 7400)
    """
    host, port_text = text, ""
    if text.startswith("["):
        end = text.find("]")
        if end < 0:
            raise LocalTransferError(f"bad address {text!r}: missing ']'")
        host, rest = text[1:end], text[end + 1 :]
        if rest.startswith(":"):
            port_text = rest[1:]
    elif text.count(":") == 1:
        host, port_text = text.split(":")
    if not port_text:
        port = default_port
    else:
        try:
            port = int(port_text)
        except ValueError:
            port = -1
        if not 0 <= port <= 65535:
            raise LocalTransferError(f"bad address {text!r}: port must be a number 0..65535")
    return host or default_host, port


def client_tls_context(cafile: str | None = None, *, verify: bool = True) -> ssl.SSLContext:
    """A TLS client context: trusts ``cafile`` (a CA or the server's own certificate) or the
    system CAs.

    Args:
        cafile: PEM file to trust.
        verify: False to skip certificate checks (then only the shared secret authenticates).
    """
    ctx = ssl.create_default_context(cafile=cafile)
    ctx.minimum_version = ssl.TLSVersion.TLSv1_2
    if not verify:
        ctx.check_hostname = False
        ctx.verify_mode = ssl.CERT_NONE
    return ctx


def server_tls_context(certfile: str, keyfile: str | None = None) -> ssl.SSLContext:
    """A TLS server context with a certificate chain and key.

    Raises:
        LocalTransferError: When the certificate or key cannot be loaded.
    """
    ctx = ssl.SSLContext(ssl.PROTOCOL_TLS_SERVER)
    ctx.minimum_version = ssl.TLSVersion.TLSv1_2
    try:
        ctx.load_cert_chain(certfile, keyfile)
    except (OSError, ssl.SSLError) as err:
        raise LocalTransferError(f"{certfile}: cannot load the TLS certificate/key: {err}") from err
    return ctx


#: TCP keepalive: probe a connection silent for this many seconds, every KEEPALIVE_INTERVAL,
#: and drop it after KEEPALIVE_COUNT unanswered probes (a peer whose Wi-Fi dropped sends no FIN).
KEEPALIVE_IDLE = 10
KEEPALIVE_INTERVAL = 5
KEEPALIVE_COUNT = 3
#: Drop a connection whose sent data stays unacknowledged this long (ms; TCP_USER_TIMEOUT), so a
#: writer blocked on a dead peer does not wait for TCP's 15-minute retransmission limit.
USER_TIMEOUT_MS = 30_000


def tune_socket(sock: socket.socket, *, keepalive: bool = True) -> None:
    """``TCP_NODELAY``, and keepalive probes plus a send timeout so dead peers are found.

    Options the platform lacks are skipped.
    """
    sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    if not keepalive:
        return
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_KEEPALIVE, 1)
    for name, value in (
        ("TCP_KEEPIDLE", KEEPALIVE_IDLE),
        ("TCP_KEEPINTVL", KEEPALIVE_INTERVAL),
        ("TCP_KEEPCNT", KEEPALIVE_COUNT),
        ("TCP_USER_TIMEOUT", USER_TIMEOUT_MS),
    ):
        opt = getattr(socket, name, None)
        if opt is not None:
            with contextlib.suppress(OSError):
                sock.setsockopt(socket.IPPROTO_TCP, opt, value)


_tune = tune_socket


def connect(
    host: str, port: int = DEFAULT_PORT, *, timeout: float = 10.0, tls: ssl.SSLContext | None = None
) -> socket.socket:
    """Open a TCP connection (and the TLS handshake when ``tls`` is given).

    Raises:
        LocalTransferError: When the host cannot be reached or TLS fails.
    """
    try:
        sock = socket.create_connection((host, port), timeout=timeout)
    except OSError as err:
        raise LocalTransferError(f"cannot connect to {host}:{port}: {err.strerror or err}") from err
    _tune(sock)
    if tls is not None:
        try:
            sock = tls.wrap_socket(sock, server_hostname=host)
        except (OSError, ssl.SSLError) as err:
            sock.close()
            raise LocalTransferError(f"TLS with {host}:{port} failed: {err}") from err
    return sock


def listen(host: str, port: int, *, backlog: int = 64) -> socket.socket:
    """A listening TCP socket (``SO_REUSEADDR``; port 0 picks a free port).

    Raises:
        LocalTransferError: When the address cannot be bound.
    """
    try:
        infos = socket.getaddrinfo(
            host or None, port, type=socket.SOCK_STREAM, flags=socket.AI_PASSIVE
        )
        family, _, _, _, addr = infos[0]
        sock = socket.socket(family, socket.SOCK_STREAM)
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        sock.bind(addr)
        sock.listen(backlog)
    except OSError as err:
        raise LocalTransferError(
            f"cannot listen on {host or '*'}:{port}: {err.strerror or err}"
        ) from err
    return sock


class FrameLink:
    """A socket carrying MKT frames for one :class:`~mapkit.transfer.protocol.Channel`.

    Args:
        sock: A connected socket (plain or TLS).
        channel: The session's channel (ordered).
        peer: Name of the peer for messages.

    Attributes:
        bytes_in: Bytes read from the socket.
        bytes_out: Bytes written.
    """

    def __init__(self, sock: socket.socket, channel: Channel, *, peer: str = "peer") -> None:
        self.sock = sock
        self.channel = channel
        self.peer = peer
        self.tls = isinstance(sock, ssl.SSLSocket)
        self.bytes_in = 0
        self.bytes_out = 0
        self.closed = False

    def send(self, outs: Iterable[Out]) -> None:
        """Encode and write frames, in order.

        Raises:
            LocalTransferError: When the connection is broken.
        """
        parts: list[Any] = []
        for o in outs:
            parts.extend(p for p in self.channel.encode_parts(o) if len(p))
        if not parts:
            return
        try:
            if self.tls or not hasattr(self.sock, "sendmsg"):
                data = b"".join(parts)
                self.sock.sendall(data)
                self.bytes_out += len(data)
                return
            while parts:
                batch = parts[:IOV_MAX]
                n = self.sock.sendmsg(batch)
                self.bytes_out += n
                # drop what was written; keep the rest of a partly written part
                k = 0
                while k < len(batch) and n >= len(batch[k]):
                    n -= len(batch[k])
                    k += 1
                parts = parts[k:]
                if n:
                    parts[0] = memoryview(parts[0])[n:]
        except (OSError, ssl.SSLError) as err:
            self.closed = True
            raise LocalTransferError(
                f"connection to {self.peer} broken while sending: "
                f"{getattr(err, 'strerror', None) or err}"
            ) from err

    def receive(self, timeout: float | None) -> Event | None:
        """The next frame (or damaged-frame notice), or None when ``timeout`` seconds pass first.

        Raises:
            LocalTransferError: When the peer closed the connection or it broke.
            ProtocolError: When the peer broke the protocol (see :meth:`Channel.next_event`).
        """
        deadline = None if timeout is None else time.monotonic() + timeout
        while True:
            ev = self.channel.next_event()
            if ev is not None:
                return ev
            if self.closed:
                raise LocalTransferError(f"connection closed by {self.peer}")
            left = None if deadline is None else deadline - time.monotonic()
            if left is not None and left <= 0:
                return None
            try:
                self.sock.settimeout(left)
                n = self.channel.receive_into(self.sock.recv_into, RECV_BUFFER)
            except TimeoutError:
                return None
            except (OSError, ssl.SSLError) as err:
                self.closed = True
                raise LocalTransferError(
                    f"connection to {self.peer} broken: {getattr(err, 'strerror', None) or err}"
                ) from err
            if n == 0:
                self.closed = True
                raise LocalTransferError(f"connection closed by {self.peer}")
            self.bytes_in += n

    def close(self) -> None:
        """Close the socket (idempotent)."""
        self.closed = True
        with contextlib.suppress(OSError):
            self.sock.shutdown(socket.SHUT_RDWR)
        self.sock.close()


def run(
    link: FrameLink,
    machine: Any,
    *,
    start: bool = True,
    on_events: Callable[[], list[Out]] | None = None,
    tick: Callable[[], None] | None = None,
    clock: Callable[[], float] = time.monotonic,
) -> None:
    """Drive ``machine`` (handshake, request, sender, receiver) over ``link`` until it finishes.

    Args:
        link: The link.
        machine: A protocol machine (``start``/``handle``/``poll``/``deadline``).
        start: Send what ``machine.start`` returns first.
        on_events: Called after each frame; handles the machine's events (store chunks...) and
            returns more frames to send.
        tick: Called after each frame (progress display).
        clock: Monotonic clock.

    Raises:
        TransferError: The machine's error once it finished with one, or a link error.
    """
    if start:
        link.send(machine.start(clock()))
    while not machine.finished:
        now = clock()
        out = machine.poll(now)
        if out:
            link.send(out)
        if machine.finished:
            break
        dl = machine.deadline()
        ev = link.receive(None if dl is None else max(0.0, dl - clock()))
        if ev is None:
            continue
        out = machine.handle(ev, clock())
        if on_events is not None:
            out = out + on_events()
        if out:
            link.send(out)
        if tick is not None:
            tick()
    if machine.error is not None:
        raise machine.error
