"""The thin socket driver: a blocking TCP client around :class:`ClientConnection`.

:class:`AriaClient` opens the connection, logs in (TCP only), and then runs one request at a
time: :meth:`~AriaClient.call` for a single reply, :meth:`~AriaClient.call_until_empty` for
``RETURN_UNTIL_EMPTY`` replies, :meth:`~AriaClient.subscribe` for broadcasts (which queue up
until :meth:`~AriaClient.next_broadcast` takes them).

Every wait is bounded: when no complete packet arrives for ``timeout`` seconds (a stalled server,
or one that drips bytes), :class:`AriaTimeoutError` ends it. Memory is bounded too: the frame
reader holds at most one incomplete packet, unclaimed broadcasts are capped, and callers stream
large replies. Any error closes the connection.
"""

from __future__ import annotations

import contextlib
import logging
import socket
import time
from collections import deque
from collections.abc import Iterator
from types import TracebackType

from mapkit.arnet.connection import ClientConnection, State
from mapkit.arnet.errors import (
    AriaConnectionError,
    AriaError,
    AriaLoginError,
    AriaProtocolError,
    AriaTimeoutError,
)
from mapkit.arnet.events import CommandInfo, Data, Ready, Rejected, ServerClosed

__all__ = ["DEFAULT_PORT", "AriaClient", "parse_host"]

log = logging.getLogger(__name__)

#: ArNetworking's port on ARNL and ARAM robots.
DEFAULT_PORT = 7272
#: Broadcasts kept for :meth:`AriaClient.next_broadcast` (older ones are dropped).
MAX_QUEUED_BROADCASTS = 256
_RECV = 1 << 18

REJECT_REASONS = {
    1: "wrong user name or password",
    2: "the robot is managed by a central server",
    4: "protocol version mismatch",
    6: "the robot type (real or simulated) does not match",
}


def parse_host(address: str, default_port: int = DEFAULT_PORT) -> tuple[str, int]:
    """``host[:port]`` (``[v6]:port`` too) as (host, port).

    Examples:
        >>> parse_host("robot"), parse_host("10.0.0.5:7273"), parse_host("[::1]:1")
        (('robot', 7272), ('10.0.0.5', 7273), ('::1', 1))
    """
    a = address.strip()
    if not a:
        raise ValueError("empty robot address")
    if a.startswith("["):
        host, _, rest = a[1:].partition("]")
        port_text = rest[1:] if rest.startswith(":") else ""
    elif a.count(":") == 1:
        host, port_text = a.split(":")
        if not port_text:
            raise ValueError(f"no port after ':' in robot address '{address}'")
    else:
        host, port_text = a, ""
    if not host:
        raise ValueError(f"no host in robot address '{address}'")
    if not port_text:
        return host, default_port
    if not port_text.isdigit() or not 0 < int(port_text) < 65536:
        raise ValueError(f"bad port in robot address '{address}'")
    return host, int(port_text)


class AriaClient:
    """A logged-in ArNetworking connection (use as a context manager).

    Args:
        host: The robot's host name or address.
        port: Its ArNetworking port (7272 on robots).
        user: The user name; "" when the robot needs no login.
        password: The password (sent only as MD5 with the server's one-time key).
        timeout: Seconds without a complete packet from the server before giving up.

    Raises:
        AriaConnectionError: When nothing answers at the address.
        AriaLoginError: When the robot refuses the login.
        AriaTimeoutError: When the robot does not finish the login in time.
        AriaProtocolError: When it sends something that is not ArNetworking.
    """

    def __init__(
        self,
        host: str,
        port: int = DEFAULT_PORT,
        *,
        user: str = "",
        password: str | bytes = "",
        timeout: float = 15.0,
    ) -> None:
        self.host, self.port, self.user, self.timeout = host, port, user, timeout
        self._password = password
        self._sock: socket.socket | None = None
        self._conn = ClientConnection(user, password)
        self._replies: deque[Data] = deque()
        self._broadcasts: deque[Data] = deque(maxlen=MAX_QUEUED_BROADCASTS)
        self._awaiting = ""
        self._skip: dict[str, int] = {}
        self._unfinished = ""
        self._last = time.monotonic()
        self._buf = bytearray(_RECV)
        self.bytes_received = 0

    @property
    def address(self) -> str:
        """``host:port``."""
        return f"{self.host}:{self.port}"

    @property
    def commands(self) -> dict[str, CommandInfo]:
        """The commands the server offers this user, by name."""
        return self._conn.commands

    def offers(self, name: str) -> bool:
        """True when the server lists command ``name`` for this user."""
        return self._conn.offers(name)

    def command_check(self, name: str) -> CommandInfo:
        """The command ``name``; raises :class:`AriaPermissionError` when not offered."""
        try:
            return self._conn.command(name)
        except AriaError as e:
            raise type(e)(f"{self.address}: {e}") from None

    # -- life cycle -----------------------------------------------------------------------------

    def open(self) -> AriaClient:
        """Connect and log in; returns ``self``."""
        try:
            sock = socket.create_connection((self.host, self.port), timeout=self.timeout)
        except OSError as e:
            raise AriaConnectionError(
                f"cannot connect to the robot at {self.address}: {e.strerror or e}"
            ) from e
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self._sock = sock
        self._last = time.monotonic()
        try:
            while self._conn.state is not State.READY:
                self._pump("logging in")
        except BaseException:
            self._drop()
            raise
        self._password = ""
        return self

    def close(self) -> None:
        """Say goodbye (SHUTDOWN) and close the socket."""
        if self._sock is None:
            return
        with contextlib.suppress(OSError, AriaError):
            self._conn.close()
            self._sock.settimeout(1.0)
            self._sock.sendall(self._conn.data_to_send())
        self._drop()

    def _drop(self) -> None:
        if self._sock is not None:
            with contextlib.suppress(OSError):
                self._sock.close()
        self._sock = None

    def __enter__(self) -> AriaClient:
        if self._sock is None:
            self.open()
        return self

    def __exit__(
        self, et: type[BaseException] | None, ev: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()

    # -- the pump -------------------------------------------------------------------------------

    def _flush(self) -> None:
        out = self._conn.data_to_send()
        if not out:
            return
        if self._sock is None:
            raise AriaConnectionError(f"the connection to {self.address} is closed")
        try:
            self._sock.settimeout(self.timeout)
            self._sock.sendall(out)
        except TimeoutError as e:
            self._drop()
            raise AriaTimeoutError(
                f"the robot at {self.address} accepted no data for {self.timeout:g} s"
            ) from e
        except OSError as e:
            self._drop()
            raise AriaConnectionError(
                f"the connection to {self.address} broke while sending: {e.strerror or e}"
            ) from e

    def _pump(self, what: str, deadline: float | None = None) -> bool:
        """Receive once (bounded by the timeout) and route the events; False on ``deadline``."""
        self._flush()
        if self._sock is None:
            raise AriaConnectionError(f"the connection to {self.address} is closed")
        now = time.monotonic()
        limit = self._last + self.timeout
        if deadline is not None and deadline < limit:
            if deadline <= now:
                return False
            limit = deadline
        if limit <= now:
            self._drop()
            raise AriaTimeoutError(
                f"the robot at {self.address} sent nothing for {self.timeout:g} s while {what}"
            )
        try:
            self._sock.settimeout(limit - now)
            n = self._sock.recv_into(self._buf)
        except TimeoutError:
            if deadline is not None and deadline <= limit:
                return False
            self._drop()
            raise AriaTimeoutError(
                f"the robot at {self.address} sent nothing for {self.timeout:g} s while {what}"
            ) from None
        except OSError as e:
            self._drop()
            raise AriaConnectionError(
                f"the connection to {self.address} broke while {what}: {e.strerror or e}"
            ) from e
        if n == 0:
            self._drop()
            raise AriaConnectionError(
                f"the robot at {self.address} closed the connection while {what}"
            )
        self.bytes_received += n
        try:
            events = self._conn.receive_data(memoryview(self._buf)[:n])
        except AriaProtocolError as e:
            self._drop()
            raise AriaProtocolError(f"{self.address}: {e} (while {what})") from e
        if events:
            self._last = time.monotonic()
        for ev in events:
            if isinstance(ev, Data):
                if self._skip.get(ev.name):
                    if not ev.data:  # the end of a reply its reader gave up on
                        self._skip[ev.name] -= 1
                elif ev.name == self._awaiting:
                    self._replies.append(ev)
                elif ev.name in self._conn.standing:
                    self._broadcasts.append(ev)
                else:
                    log.debug("ignored %s packet (%d bytes)", ev.name, len(ev.data))
            elif isinstance(ev, Rejected):
                self._drop()
                reason = REJECT_REASONS.get(ev.code, f"code {ev.code}")
                who = f" for user '{self.user}'" if self.user else " (no user name given)"
                text = f": {ev.text}" if ev.text else ""
                raise AriaLoginError(
                    f"the robot at {self.address} refused the login{who}: {reason}{text}", ev.code
                )
            elif isinstance(ev, ServerClosed):
                self._drop()
                raise AriaConnectionError(
                    f"the robot at {self.address} shut the connection down while {what}"
                )
            elif isinstance(ev, Ready):
                log.debug("%s offers %d commands", self.address, len(ev.commands))
        return True

    # -- requests -------------------------------------------------------------------------------

    def send(self, name: str, data: bytes = b"") -> None:
        """Send a request without waiting for its reply."""
        if self._unfinished:
            # the last RETURN_UNTIL_EMPTY reply was abandoned (an error code): skip its rest
            late = self._unfinished
            if not any(r.name == late and not r.data for r in self._replies):
                self._skip[late] = self._skip.get(late, 0) + 1
            self._unfinished = ""
        self._replies.clear()
        self._conn.request(name, data)
        self._flush()

    def _wait(self, name: str, what: str) -> Data:
        self._awaiting = name
        while not self._replies:
            self._pump(what)
        return self._replies.popleft()

    def expect(self, name: str, what: str = "") -> Data:
        """Wait for the next packet of command ``name`` (after :meth:`send`)."""
        return self._wait(name, what or f"waiting for the reply to {name}")

    def call(self, name: str, data: bytes = b"") -> Data:
        """Send a request and return its first reply packet."""
        self._awaiting = name
        self.send(name, data)
        return self._wait(name, f"waiting for the reply to {name}")

    def call_until_empty(self, name: str, data: bytes = b"") -> Iterator[Data]:
        """Send a request and yield its reply packets up to (not including) the empty one."""
        self._awaiting = name
        self.send(name, data)
        self._unfinished = name
        while True:
            reply = self._wait(name, f"receiving the reply to {name}")
            if not reply.data:
                self._unfinished = ""
                return
            yield reply

    def subscribe(self, name: str) -> None:
        """Ask for the broadcasts of command ``name`` (REQUEST with interval -1)."""
        self._conn.start_request(name, -1)
        self._flush()

    def unsubscribe(self, name: str) -> None:
        """Stop the broadcasts of ``name``."""
        self._conn.stop_request(name)
        self._flush()

    def next_broadcast(self, timeout: float | None = None) -> Data | None:
        """The next queued broadcast, waiting up to ``timeout`` s (None: no wait limit but the
        connection's own timeout); None when none came."""
        deadline = None if timeout is None else time.monotonic() + timeout
        self._awaiting = ""
        while not self._broadcasts:
            if deadline is None:
                self._pump("waiting for a broadcast")
            elif not self._pump("waiting for a broadcast", deadline):
                return None
        return self._broadcasts.popleft()

    def drain_broadcasts(self, name: str) -> int:
        """Forget queued broadcasts of ``name``; how many there were."""
        keep = [b for b in self._broadcasts if b.name != name]
        n = len(self._broadcasts) - len(keep)
        self._broadcasts.clear()
        self._broadcasts.extend(keep)
        return n

    def keepalive(self) -> None:
        """Mark the connection as active now (for idle waits between requests)."""
        self._last = time.monotonic()
