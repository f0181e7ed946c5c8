"""ArNetworking packets: the frame, ARIA's checksum, and the typed fields inside the data.

A packet on the wire (``ArNetPacket`` in ARIA)::

    0f 0c | u16 LE total length L | u16 LE command | data (L - 8 bytes) | u16 BE checksum

``L`` counts everything (6 header bytes, the data and the 2 checksum bytes); ARIA accepts
``8 <= L <= 32000``. The checksum is ARIA's robot-packet sum: big-endian byte pairs added modulo
2**16 from offset 3 (the high byte of the length) while more than three bytes of the ``L - 4``
counted ones remain, then the next byte XORed in. So byte 2 is never covered, nor is the last
data byte of an odd-length packet.

Inside the data, integers are little-endian (``byte``, ``byte2``, ``byte4`` signed or not),
strings are NUL-terminated with no length prefix, and doubles travel as ``%g`` strings.
This module does no I/O.
"""

from __future__ import annotations

import struct
import sys
from array import array
from dataclasses import dataclass

from mapkit.arnet.errors import AriaProtocolError, AriaValueError

__all__ = [
    "HEADER_LENGTH",
    "MAX_DATA",
    "MAX_LENGTH",
    "MIN_LENGTH",
    "SYNC",
    "Fields",
    "Packet",
    "Payload",
    "checksum",
    "encode",
]

SYNC = b"\x0f\x0c"
HEADER_LENGTH = 6
MIN_LENGTH = 8
MAX_LENGTH = 32000  # ArNetPacket::MAX_LENGTH
MAX_DATA = MAX_LENGTH - MIN_LENGTH

_LITTLE = sys.byteorder == "little"
_NUMPY_FROM = 256  # byte pairs; longer frames are summed with numpy


def checksum(frame: bytes | bytearray | memoryview, length: int | None = None) -> int:
    """ARIA's checksum of a frame of total length ``length`` (default ``len(frame)``).

    Only the first ``length - 2`` bytes are read (the checksum bytes themselves are not).

    Examples:
        >>> hex(checksum(bytes.fromhex("0f0c08000801") + b"\\0\\0"))
        '0x9'
        >>> hex(checksum(bytes.fromhex("0f0c09000c01") + b"\\0" + b"\\0\\0"))
        '0xd'
    """
    total = len(frame) if length is None else length
    n = total - 4
    if n < 4:
        raise ValueError(f"a packet is at least {MIN_LENGTH} bytes, not {total}")
    pairs = (n - 2) // 2
    end = 3 + 2 * pairs
    if pairs > _NUMPY_FROM:
        import numpy as np

        total = int(np.frombuffer(frame, dtype=">u2", count=pairs, offset=3).sum(dtype=np.uint64))
        return (total & 0xFFFF) ^ frame[end]
    words = array("H")
    words.frombytes(bytes(frame[3:end]))
    if _LITTLE:
        words.byteswap()
    return (sum(words) & 0xFFFF) ^ frame[end]


def encode(command: int, data: bytes = b"") -> bytes:
    """One framed packet with ``command`` and ``data`` (at most :data:`MAX_DATA` bytes).

    Examples:
        >>> encode(264).hex()
        '0f0c080008010009'
    """
    if not 0 <= command <= 0xFFFF:
        raise ValueError(f"command id {command} is not a 16-bit number")
    if len(data) > MAX_DATA:
        raise ValueError(f"{len(data)} data bytes do not fit one packet (at most {MAX_DATA})")
    length = MIN_LENGTH + len(data)
    head = SYNC + struct.pack("<HH", length, command) + data
    return head + struct.pack(">H", checksum(head + b"\0\0"))


@dataclass(frozen=True)
class Packet:
    """One packet as received: its command id and its data (checksum already verified)."""

    command: int
    data: bytes

    def fields(self, what: str = "") -> Fields:
        """A reader over the data; ``what`` names the packet in error messages."""
        return Fields(self.data, what or f"packet {self.command}")


class Fields:
    """Read typed fields from a packet's data, in order; a short or malformed packet raises.

    Raises:
        AriaProtocolError: When a field runs past the end of the data (naming the packet).
    """

    __slots__ = ("_data", "_pos", "what")

    def __init__(self, data: bytes, what: str = "packet") -> None:
        self._data = data
        self._pos = 0
        self.what = what

    @property
    def remaining(self) -> int:
        """Bytes not read yet."""
        return len(self._data) - self._pos

    def _take(self, n: int, kind: str) -> bytes:
        if n < 0 or self._pos + n > len(self._data):
            raise AriaProtocolError(
                f"{self.what}: the server's packet ends inside a {kind} field "
                f"(offset {self._pos}, {self.remaining} bytes left, {n} needed)"
            )
        out = self._data[self._pos : self._pos + n]
        self._pos += n
        return out

    def _unpack(self, fmt: str, kind: str) -> int:
        value: int = struct.unpack(fmt, self._take(struct.calcsize(fmt), kind))[0]
        return value

    def byte(self) -> int:
        """A signed byte."""
        return self._unpack("<b", "byte")

    def ubyte(self) -> int:
        """An unsigned byte."""
        return self._unpack("<B", "ubyte")

    def byte2(self) -> int:
        """A signed 16-bit integer."""
        return self._unpack("<h", "byte2")

    def ubyte2(self) -> int:
        """An unsigned 16-bit integer."""
        return self._unpack("<H", "ubyte2")

    def byte4(self) -> int:
        """A signed 32-bit integer."""
        return self._unpack("<i", "byte4")

    def ubyte4(self) -> int:
        """An unsigned 32-bit integer."""
        return self._unpack("<I", "ubyte4")

    def raw(self, n: int) -> bytes:
        """``n`` raw bytes."""
        return self._take(n, f"{n}-byte data")

    def rest(self) -> bytes:
        """Everything not read yet."""
        return self._take(self.remaining, "data")

    def str_bytes(self) -> bytes:
        """A NUL-terminated string, as bytes (without the NUL)."""
        end = self._data.find(b"\0", self._pos)
        if end < 0:
            raise AriaProtocolError(
                f"{self.what}: a string at offset {self._pos} has no terminating NUL"
            )
        out = self._data[self._pos : end]
        self._pos = end + 1
        return out

    def string(self) -> str:
        """A NUL-terminated string (UTF-8, undecodable bytes kept as surrogates)."""
        return self.str_bytes().decode("utf-8", "surrogateescape")


class Payload:
    """Build a packet's data field by field (the writer side of :class:`Fields`).

    Examples:
        >>> Payload().ubyte2(0).string("maps/a.map").bytes().hex()
        '00006d6170732f612e6d617000'
    """

    __slots__ = ("_parts",)

    def __init__(self) -> None:
        self._parts: list[bytes] = []

    def byte(self, v: int) -> Payload:
        self._parts.append(struct.pack("<b", v))
        return self

    def ubyte(self, v: int) -> Payload:
        self._parts.append(struct.pack("<B", v))
        return self

    def byte2(self, v: int) -> Payload:
        self._parts.append(struct.pack("<h", v))
        return self

    def ubyte2(self, v: int) -> Payload:
        self._parts.append(struct.pack("<H", v))
        return self

    def byte4(self, v: int) -> Payload:
        self._parts.append(struct.pack("<i", v))
        return self

    def ubyte4(self, v: int) -> Payload:
        self._parts.append(struct.pack("<I", v))
        return self

    def raw(self, data: bytes) -> Payload:
        self._parts.append(bytes(data))
        return self

    def string(self, s: str | bytes) -> Payload:
        try:
            b = s if isinstance(s, bytes) else s.encode("utf-8", "surrogateescape")
        except UnicodeEncodeError:
            raise AriaValueError(f"{s!r} cannot be sent to the robot: it is not text") from None
        if b"\0" in b:
            raise AriaValueError(f"{s!r} cannot be sent to the robot: it holds a NUL byte")
        self._parts.append(b + b"\0")
        return self

    def bytes(self) -> bytes:
        """The data built so far."""
        return b"".join(self._parts)
