"""What the core hands its driver: decoded frames, damaged frames, frames to send, and a
receiver's chunks and completion."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from mapkit.transfer.protocol.constants import MAX_CONTROL_PAYLOAD, FrameType
from mapkit.transfer.protocol.frames import _SMALL_PAYLOADS, Prepared, _type_name, parse_json
from mapkit.transfer.protocol.offer import Offer
from mapkit.transfer.wirejson import SCHEMAS

__all__ = ["ChunkReceived", "Damaged", "Event", "Frame", "Out", "TransferComplete"]


# -- frames -------------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class Frame:
    """A decoded, checked frame.

    Attributes:
        type: The frame type (a :class:`FrameType`, or an int for unknown types).
        seq: The sender's sequence number (1, 2, ... per direction).
        ref: Chunk index for DATA; the request number for control frames.
        payload: The payload bytes (a ``bytearray`` when a large payload was received in place,
            see :meth:`Channel.receive_into`).
        flags: Header flags.
        session: The session id.
        authentic: True when the frame carried a valid tag.
        crc: CRC-32 of the payload alone (computed while checking the frame).
    """

    type: int
    seq: int
    ref: int
    payload: bytes | bytearray
    flags: int = 0
    session: int = 0
    authentic: bool = False
    crc: int = 0

    def json(self) -> dict[str, Any]:
        """The payload as a JSON object.

        Raises:
            ProtocolError: When the payload is not a UTF-8 JSON object.
        """
        return parse_json(
            self.payload,
            _type_name(self.type),
            SCHEMAS.get(self.type),
            max_size=_SMALL_PAYLOADS.get(self.type, MAX_CONTROL_PAYLOAD),
        )


@dataclass(frozen=True, slots=True)
class Damaged:
    """A frame whose header was intact but whose body failed its CRC (it was dropped).

    The receiver of a transfer uses it to ask for the chunk again at once.
    """

    type: int
    seq: int
    ref: int


@dataclass(frozen=True, slots=True)
class Out:
    """A frame to send: the machines return these, :meth:`Channel.encode` numbers and tags them.

    Attributes:
        type: Frame type.
        payload: Payload bytes (JSON for control frames, chunk bytes for DATA, which may come
            as a :class:`Prepared` payload).
        ref: Chunk index or request number.
        flags: Extra flags (e.g. :attr:`Flag.RETX`).
        plain: Send without a tag even when keys are installed (REJECTs during the handshake,
            which the peer may not be able to check).
    """

    type: FrameType
    payload: bytes | bytearray | memoryview | Prepared = b""
    ref: int = 0
    flags: int = 0
    plain: bool = False


Event = Frame | Damaged

# -- a receiver's events ---------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class ChunkReceived:
    """A new chunk for the application to store at ``offset``."""

    index: int
    offset: int
    data: bytes | bytearray
    crc: int | None = None  #: CRC-32 of ``data`` when the transport computed it


@dataclass(frozen=True, slots=True)
class TransferComplete:
    """Every chunk is held: the application checks the file, then calls
    :meth:`Receiver.verified` or :meth:`Receiver.fail`."""

    offer: Offer
