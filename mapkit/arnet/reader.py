"""Split the bytes a server sends into checked packets (sans-I/O, bounded memory).

:class:`PacketReader` takes whatever ``recv`` returned and yields whole :class:`Packet` values.
It never holds more than one incomplete packet (at most :data:`MAX_LENGTH` bytes) beyond the
bytes it was just given, and it refuses a frame as soon as its header shows it is bad: wrong
sync bytes, a length under 8 or over 32000, or (once complete) a wrong checksum. ARIA's own
receiver skips such frames and hunts for the next sync bytes; a client that downloads maps must
not guess, so here they end the connection with :class:`AriaProtocolError`.
"""

from __future__ import annotations

import struct

from mapkit.arnet.errors import AriaProtocolError
from mapkit.arnet.packet import MAX_LENGTH, MIN_LENGTH, SYNC, Packet, checksum

__all__ = ["PacketReader"]

_COMPACT_AT = 1 << 16


class PacketReader:
    """Incremental frame reader: :meth:`feed` bytes, iterate the complete packets.

    Args:
        max_length: The largest frame accepted (ARIA's limit, 32000, by default).

    Examples:
        >>> r = PacketReader()
        >>> [p.command for p in r.feed(bytes.fromhex("0f0c080008010009"))]
        [264]
    """

    def __init__(self, max_length: int = MAX_LENGTH) -> None:
        self.max_length = max_length
        self._buf = bytearray()
        self._pos = 0
        self.packets = 0
        self.bytes = 0

    @property
    def pending(self) -> int:
        """Bytes of an incomplete packet held back."""
        return len(self._buf) - self._pos

    def feed(self, data: bytes | bytearray | memoryview) -> list[Packet]:
        """Add received bytes and return every packet they complete, in order.

        Raises:
            AriaProtocolError: On bad sync bytes, a length out of range, or a wrong checksum.
        """
        self._buf += data
        self.bytes += len(data)
        buf = self._buf
        out: list[Packet] = []
        while True:
            avail = len(buf) - self._pos
            if avail < 4:
                break
            p = self._pos
            if buf[p] != SYNC[0] or buf[p + 1] != SYNC[1]:
                raise AriaProtocolError(
                    f"the server sent {bytes(buf[p : p + 2]).hex()} where a packet must start "
                    f"with 0f0c (byte {self.bytes - avail} of the connection)"
                )
            length = buf[p + 2] | (buf[p + 3] << 8)
            if length < MIN_LENGTH or length > self.max_length:
                raise AriaProtocolError(
                    f"the server announced a {length}-byte packet; ArNetworking packets are "
                    f"{MIN_LENGTH} to {self.max_length} bytes"
                )
            if avail < length:
                break
            frame = memoryview(buf)[p : p + length]
            try:
                want = checksum(frame, length)
                got = struct.unpack_from(">H", frame, length - 2)[0]
                command = struct.unpack_from("<H", frame, 4)[0]
                data = bytes(frame[6 : length - 2])
            finally:
                frame.release()
            if want != got:
                raise AriaProtocolError(
                    f"packet {self.packets + 1} from the server (command {command}, {length} "
                    f"bytes) has checksum {got:#06x}, expected {want:#06x}"
                )
            self._pos = p + length
            self.packets += 1
            out.append(Packet(command, data))
        if self._pos >= _COMPACT_AT or self._pos == len(buf):
            del buf[: self._pos]
            self._pos = 0
        return out
