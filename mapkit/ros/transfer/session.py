"""What both sides share: the package's logger and one session's channel over the bus."""

from __future__ import annotations

import logging
from collections.abc import Iterable

from mapkit.ros.transport import RosLink
from mapkit.transfer.protocol import (
    MAGIC,
    AuthenticationError,
    Channel,
    Damaged,
    Frame,
    Out,
    ProtocolError,
)

log = logging.getLogger("mapkit.ros.transfer")  # one logger for the whole package


def _session_id(data: bytes) -> int | None:
    if len(data) >= 16 and data[:4] == MAGIC:
        return int.from_bytes(data[8:16], "big")
    return None


class _Conn:
    """One session's channel and the node at the other end of it."""

    def __init__(self, link: RosLink, peer: str, channel: Channel) -> None:
        self.link = link
        self.peer = peer
        self.channel = channel

    def send(self, outs: Iterable[Out]) -> None:
        for o in outs:
            self.link.send(self.peer, self.channel.encode(o))

    def events(self, data: bytes) -> list[Frame | Damaged]:
        self.channel.receive_message(data)
        out: list[Frame | Damaged] = []
        while True:
            try:
                ev = self.channel.next_event()
            except AuthenticationError:
                raise  # a handshake frame made with another secret: the session ends
            except ProtocolError as err:  # a frame this side cannot take: drop the message
                log.warning("%s: dropped a frame: %s", self.peer, err)
                return out
            if ev is None:
                return out
            out.append(ev)
