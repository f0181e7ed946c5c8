"""MKT/1 constants: magic, version, sizes and limits, frame types, flags and status codes."""

from __future__ import annotations

import enum
import struct

__all__ = [
    "AUTH_METHODS",
    "DEFAULT_CHUNK_SIZE",
    "DEFAULT_MAX_PAYLOAD",
    "DEFAULT_PORT",
    "HEADER",
    "HEADER_SIZE",
    "MAC_HEADER",
    "MAGIC",
    "MAX_CHUNKS",
    "MAX_CHUNK_SIZE",
    "MAX_CONTROL_PAYLOAD",
    "MAX_HANDSHAKE_PAYLOAD",
    "MAX_REFUSAL_PAYLOAD",
    "MIN_SECRET",
    "NONCE_SIZE",
    "SOFTWARE",
    "TAG_SIZE",
    "VERSION",
    "Flag",
    "FrameType",
    "Status",
]


MAGIC = b"MKT1"
VERSION = 1
DEFAULT_PORT = 7373
HEADER = struct.Struct(">4sBBHQIIIII")
HEADER_SIZE = HEADER.size  # 36
MAC_HEADER = 28  # the header bytes the tag covers: everything before the two CRCs
TAG_SIZE = 16
DEFAULT_CHUNK_SIZE = 256 * 1024
MAX_CHUNK_SIZE = 4 * 1024 * 1024
MAX_CONTROL_PAYLOAD = 1024 * 1024
MAX_HANDSHAKE_PAYLOAD = 16 * 1024  # HELLO ... AUTH_OK: a few hundred bytes; read before any proof
MAX_REFUSAL_PAYLOAD = 64 * 1024  # REJECT / CANCEL: may arrive untagged
DEFAULT_MAX_PAYLOAD = MAX_CHUNK_SIZE
MAX_CHUNKS = 1 << 24
NONCE_SIZE = 32
MIN_SECRET = 16
SOFTWARE = "mapkit"
#: Per-frame tag algorithms, in this side's order of preference (section 4 of the spec):
#: keyed BLAKE2b with a 16-byte output, 1.4-2x faster than HMAC-SHA256 on CPUs without SHA
#: instructions, and HMAC-SHA256 truncated to 16 bytes.
AUTH_METHODS = ("blake2b", "hmac-sha256")


class FrameType(enum.IntEnum):
    """Frame types (byte 5 of the header). Numbers are part of the wire format."""

    HELLO = 1
    HELLO_ACK = 2
    AUTH = 3
    AUTH_OK = 4
    REJECT = 5
    CANCEL = 6
    PING = 7
    PONG = 8
    BYE = 9
    OFFER = 16
    ACCEPT = 17
    DATA = 18
    ACK = 19
    DONE = 20
    VERIFIED = 21
    GET = 32
    NOT_MODIFIED = 33
    LIST = 34
    LISTING = 35
    LOAD = 36
    LOADED = 37
    ANNOUNCE = 38


class Flag(enum.IntFlag):
    """Header flag bits (bytes 6-7)."""

    AUTH = 0x0001  #: a 16-byte tag follows the payload
    RETX = 0x0002  #: this DATA frame is a resend (informational)
    ACKREQ = 0x0004  #: the sender's window is full (or this is its last chunk): acknowledge now


class Status(enum.IntEnum):
    """Why a request was refused or a transfer cancelled (``code`` in REJECT / CANCEL)."""

    OK = 0
    BAD_VERSION = 1
    AUTH_REQUIRED = 2
    AUTH_FAILED = 3
    BAD_NAME = 4
    TOO_LARGE = 6
    NO_SPACE = 7
    BUSY = 8
    HASH_MISMATCH = 10
    NOT_FOUND = 11
    PARSE_ERROR = 12
    TIMEOUT = 13
    CANCELLED = 14
    INTERNAL = 15
    MD5_MISMATCH = 16
    REPLAY = 17
    PROTOCOL = 18
    UNSUPPORTED = 19
    IO_ERROR = 20

    @property
    def reason(self) -> str:
        """The lower-case name used as ``reason`` on the wire, e.g. ``"bad_name"``."""
        return self.name.lower()
