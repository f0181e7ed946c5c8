"""The client side of an ArNetworking connection as a state machine, with no I/O (h11's shape).

Feed what the socket received to :meth:`ClientConnection.receive_data`; it returns
:mod:`~mapkit.arnet.events` and queues what must go back (the login answer), which
:meth:`ClientConnection.data_to_send` hands over. Requests are queued with :meth:`request`,
:meth:`start_request` and :meth:`stop_request`, by command *name*: ids are learned from the
server's LIST packets, since every server numbers its commands in the order it registered them.

The login (ARIA's ``ArClientBase``): the server introduces itself with a random password key;
the client answers with its user name and ``MD5(server_key + password_key + password)``, then
asks for TCP only (no UDP side channel, so it works through NAT and firewalls); the server
answers CONNECTED and its command lists, or REJECTED and closes.
"""

from __future__ import annotations

import enum
import hashlib
from typing import Any

from mapkit.arnet.errors import AriaPermissionError, AriaProtocolError
from mapkit.arnet.events import (
    Accepted,
    CommandInfo,
    Data,
    Event,
    Introduced,
    Ready,
    Rejected,
    ServerClosed,
)
from mapkit.arnet.packet import Packet, Payload, encode
from mapkit.arnet.reader import PacketReader

__all__ = ["ClientCommand", "ClientConnection", "ServerCommand", "State", "login_digest"]


class ClientCommand(enum.IntEnum):
    """Fixed ids of packets a client sends (``ArClientCommands.h``)."""

    SHUTDOWN = 1
    INTRODUCTION = 2
    UDP_INTRODUCTION = 3
    UDP_CONFIRMATION = 4
    TCP_ONLY = 5
    LIST = 128
    REQUEST = 129
    REQUESTSTOP = 130


class ServerCommand(enum.IntEnum):
    """Fixed ids of packets a server sends (``ArServerCommands.h``)."""

    SHUTDOWN = 1
    INTRODUCTION = 2
    UDP_INTRODUCTION = 3
    UDP_CONFIRMATION = 4
    CONNECTED = 5
    REJECTED = 6
    TCP_ONLY = 7
    LIST = 129
    LISTSINGLE = 130
    LISTARGRET = 131
    LISTARGRETSINGLE = 132
    LISTGROUPANDFLAGS = 133
    LISTGROUPANDFLAGSSINGLE = 134


#: Data command ids start here; lower ids are the fixed ones above.
FIRST_DATA_ID = 256


class State(enum.Enum):
    """Where a connection is."""

    AWAIT_INTRODUCTION = "waiting for the server's introduction"
    AWAIT_LOGIN = "waiting for the server to accept the login"
    AWAIT_LIST = "waiting for the server's command list"
    READY = "ready"
    REJECTED = "rejected"
    CLOSED = "closed"


def login_digest(
    password_key: bytes, password: str | bytes, server_key: str | bytes = b""
) -> bytes:
    """The 16-byte MD5 the client sends: ``MD5(server_key + password_key + password)``.

    Examples:
        >>> import hashlib
        >>> login_digest(b"abc", "secret1").hex() == hashlib.md5(b"abcsecret1").hexdigest()
        True
    """

    def b(v: str | bytes) -> bytes:
        return v if isinstance(v, bytes) else v.encode("utf-8")

    return hashlib.md5(b(server_key) + password_key + b(password)).digest()


class ClientConnection:
    """One client connection's protocol state (no sockets; see :mod:`mapkit.arnet.client`).

    Args:
        user: The user name ("" when the server needs no login).
        password: The password (only its MD5 with the server's key is sent).
        server_key: The server key (``-serverInfoFile``), "" on nearly every robot.
        max_length: The largest packet accepted from the server.
    """

    def __init__(
        self,
        user: str = "",
        password: str | bytes = "",
        *,
        server_key: str = "",
        max_length: int | None = None,
    ) -> None:
        self.user = user
        self._password = password
        self._server_key = server_key
        self.state = State.AWAIT_INTRODUCTION
        self._reader = PacketReader() if max_length is None else PacketReader(max_length)
        self._out: list[bytes] = []
        self.commands: dict[str, CommandInfo] = {}
        self._by_id: dict[int, CommandInfo] = {}
        self._extra: dict[int, dict[str, Any]] = {}
        self.standing: set[str] = set()
        self.introduction: Introduced | None = None

    # -- outgoing --------------------------------------------------------------------------------

    def data_to_send(self) -> bytes:
        """Bytes queued for the server (emptied by this call)."""
        out = b"".join(self._out)
        self._out.clear()
        return out

    def command(self, name: str) -> CommandInfo:
        """The server's command ``name``.

        Raises:
            AriaPermissionError: When the server did not list it for this user.
        """
        self._need_ready(name)
        try:
            return self.commands[name]
        except KeyError:
            who = f"user '{self.user}'" if self.user else "this client"
            raise AriaPermissionError(
                f"the server does not offer '{name}' to {who} (it is not in the server's "
                "command list: the server lacks it or the user's groups do not include it)"
            ) from None

    def offers(self, name: str) -> bool:
        """True when the server listed command ``name`` for this user."""
        return name in self.commands

    def request(self, name: str, data: bytes = b"") -> None:
        """Queue a one-off request: the command's packet with ``data`` as its arguments."""
        self._out.append(encode(self.command(name).id, data))

    def start_request(self, name: str, interval_ms: int = -1, data: bytes = b"") -> None:
        """Queue a standing request (REQUEST): every ``interval_ms``, or -1 for broadcasts only."""
        cmd = self.command(name)
        self._out.append(
            encode(
                ClientCommand.REQUEST, Payload().ubyte2(cmd.id).byte4(interval_ms).bytes() + data
            )
        )
        self.standing.add(name)

    def stop_request(self, name: str) -> None:
        """Queue REQUESTSTOP for a standing request."""
        self._out.append(
            encode(ClientCommand.REQUESTSTOP, Payload().ubyte2(self.command(name).id).bytes())
        )
        self.standing.discard(name)

    def close(self) -> None:
        """Queue SHUTDOWN (what ARIA's client sends before it disconnects)."""
        if self.state is not State.CLOSED:
            self._out.append(encode(ClientCommand.SHUTDOWN))
        self.state = State.CLOSED

    # -- incoming --------------------------------------------------------------------------------

    def receive_data(self, data: bytes | bytearray | memoryview) -> list[Event]:
        """Process bytes from the server; the events they complete, in order.

        Raises:
            AriaProtocolError: On broken framing or a packet that does not fit the protocol.
        """
        events: list[Event] = []
        for packet in self._reader.feed(data):
            event = self._handle(packet)
            if event is not None:
                events.append(event)
        return events

    @property
    def buffered(self) -> int:
        """Bytes of an incomplete packet held back."""
        return self._reader.pending

    def _need_ready(self, name: str) -> None:
        if self.state is not State.READY:
            raise AriaProtocolError(f"cannot send '{name}': the connection is {self.state.value}")

    def _handle(self, p: Packet) -> Event | None:
        if p.command >= FIRST_DATA_ID:
            if self.state is not State.READY:
                raise AriaProtocolError(
                    f"the server sent data (command {p.command}) while {self.state.value}"
                )
            info = self._by_id.get(p.command)
            if info is None:
                raise AriaProtocolError(
                    f"the server sent command {p.command}, which is not in its command list"
                )
            return Data(info.name, p.command, p.data)
        if p.command == ServerCommand.INTRODUCTION:
            return self._on_introduction(p)
        if p.command == ServerCommand.CONNECTED:
            self._expect(State.AWAIT_LOGIN, "CONNECTED")
            self.state = State.AWAIT_LIST
            return Accepted()
        if p.command == ServerCommand.REJECTED:
            f = p.fields("REJECTED")
            code = f.byte2()
            text = f.string() if f.remaining else ""
            self.state = State.REJECTED
            return Rejected(code, text)
        if p.command in (ServerCommand.LIST, ServerCommand.LISTSINGLE):
            self._on_list(p, "LIST", ("name", "description"))
            return None
        if p.command in (ServerCommand.LISTARGRET, ServerCommand.LISTARGRETSINGLE):
            self._on_list(p, "LISTARGRET", ("arguments", "returns"))
            return None
        if p.command in (ServerCommand.LISTGROUPANDFLAGS, ServerCommand.LISTGROUPANDFLAGSSINGLE):
            self._on_list(p, "LISTGROUPANDFLAGS", ("group", "flags"))
            if p.command == ServerCommand.LISTGROUPANDFLAGS and self.state is State.AWAIT_LIST:
                self.state = State.READY
                return Ready(dict(self.commands))
            return None
        if p.command == ServerCommand.SHUTDOWN:
            self.state = State.CLOSED
            return ServerClosed()
        # UDP_INTRODUCTION / UDP_CONFIRMATION / TCP_ONLY: nothing to do for a TCP-only client.
        return None

    def _expect(self, state: State, what: str) -> None:
        if self.state is not state:
            raise AriaProtocolError(f"the server sent {what} while {self.state.value}")

    def _on_introduction(self, p: Packet) -> Introduced:
        self._expect(State.AWAIT_INTRODUCTION, "INTRODUCTION")
        f = p.fields("the server's INTRODUCTION")
        f.str_bytes()  # "alpha"
        udp_port = f.ubyte2()
        f.ubyte4()  # auth key (UDP only)
        f.ubyte4()  # intro key (UDP only)
        password_key = f.str_bytes()
        version = f.string() if f.remaining else ""
        intro = Introduced(udp_port, password_key, version)
        self.introduction = intro
        answer = (
            Payload()
            .ubyte2(0)
            .string(self.user)
            .raw(login_digest(password_key, self._password, self._server_key))
            .string("")
            .byte(0)
            .bytes()
        )
        self._out.append(encode(ClientCommand.INTRODUCTION, answer))
        self._out.append(encode(ClientCommand.TCP_ONLY))
        self._password = ""
        self.state = State.AWAIT_LOGIN
        return intro

    def _on_list(self, p: Packet, what: str, keys: tuple[str, ...]) -> None:
        if self.state not in (State.AWAIT_LIST, State.READY):
            raise AriaProtocolError(f"the server sent {what} while {self.state.value}")
        f = p.fields(f"the server's {what}")
        count = f.ubyte2()
        for _ in range(count):
            cid = f.ubyte2()
            values = [f.string() for _ in keys]
            if what == "LIST":
                if cid < FIRST_DATA_ID:
                    raise AriaProtocolError(
                        f"the server's LIST gives data command id {cid} (below {FIRST_DATA_ID})"
                    )
                info = CommandInfo(cid, values[0])
                self._extra.setdefault(cid, {})["description"] = values[1]
                old = self._by_id.get(cid)
                if old is not None and old.name != info.name:
                    self.commands.pop(old.name, None)
                self._by_id[cid] = info
                self.commands[info.name] = info
            else:
                self._extra.setdefault(cid, {}).update(zip(keys, values, strict=True))
        if f.remaining:
            raise AriaProtocolError(
                f"the server's {what} has {f.remaining} bytes after its {count} entries"
            )
        self._merge()

    def _merge(self) -> None:
        for cid, info in list(self._by_id.items()):
            extra = self._extra.get(cid, {})
            flags = tuple(x for x in str(extra.get("flags", "")).split("|") if x)
            new = CommandInfo(
                cid,
                info.name,
                str(extra.get("description", info.description)),
                str(extra.get("arguments", "")),
                str(extra.get("returns", "")),
                str(extra.get("group", "")),
                flags,
            )
            self._by_id[cid] = new
            self.commands[new.name] = new
