"""What a :class:`~mapkit.arnet.connection.ClientConnection` reports as server bytes arrive.

Every event is a frozen dataclass. The order on a good login is :class:`Introduced`,
:class:`Accepted`, then :class:`Ready` (the command list is complete); after that the server's
replies and broadcasts arrive as :class:`Data`. A refused login gives :class:`Rejected`, a
server that says goodbye :class:`ServerClosed`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from mapkit.arnet.packet import Fields

__all__ = [
    "Accepted",
    "CommandInfo",
    "Data",
    "Event",
    "Introduced",
    "Ready",
    "Rejected",
    "ServerClosed",
]


@dataclass(frozen=True)
class CommandInfo:
    """One data command the server announced in its lists (ids are per server, never fixed)."""

    id: int
    name: str
    description: str = ""
    arguments: str = ""
    returns: str = ""
    group: str = ""
    flags: tuple[str, ...] = ()


@dataclass(frozen=True)
class Introduced:
    """The server's INTRODUCTION: the login challenge (``password_key``) and its UDP port."""

    udp_port: int
    password_key: bytes
    protocol_version: str = ""


@dataclass(frozen=True)
class Accepted:
    """CONNECTED: the login was accepted."""


@dataclass(frozen=True)
class Ready:
    """The command lists are complete; requests may be sent."""

    commands: dict[str, CommandInfo] = field(default_factory=dict)


@dataclass(frozen=True)
class Rejected:
    """REJECTED: the server refused this client (``code`` 1 is a bad user or password)."""

    code: int
    text: str


@dataclass(frozen=True)
class ServerClosed:
    """The server sent SHUTDOWN."""


@dataclass(frozen=True)
class Data:
    """A packet of a data command: a reply to a request, or a broadcast the client asked for.

    ``data`` empty is the end marker of ``RETURN_UNTIL_EMPTY`` replies and the whole of
    ``mapUpdated``-style broadcasts.
    """

    name: str
    command: int
    data: bytes

    def fields(self) -> Fields:
        """A typed reader over the data (errors name the command)."""
        return Fields(self.data, f"{self.name} reply")


Event = Introduced | Accepted | Ready | Rejected | ServerClosed | Data
