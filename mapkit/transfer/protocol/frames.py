"""Writing frames: control payloads as bounded JSON, per-frame tags, and the frame encoder."""

from __future__ import annotations

import hashlib
import hmac
import json
import struct
import zlib
from collections.abc import Callable, Mapping
from typing import Any

from mapkit.transfer.protocol.constants import (
    MAGIC,
    MAX_CONTROL_PAYLOAD,
    MAX_HANDSHAKE_PAYLOAD,
    MAX_REFUSAL_PAYLOAD,
    TAG_SIZE,
    VERSION,
    Flag,
    FrameType,
)
from mapkit.transfer.protocol.errors import ProtocolError
from mapkit.transfer.wirejson import WireJSONError, check_fields, decode_object

__all__ = ["Prepared", "dump_json", "encode_frame", "parse_json", "prepare_payload"]


# payloads that a peer can send before it proved anything are small: decoding them costs little
_SMALL_PAYLOADS: dict[int, int] = {
    FrameType.HELLO: MAX_HANDSHAKE_PAYLOAD,
    FrameType.HELLO_ACK: MAX_HANDSHAKE_PAYLOAD,
    FrameType.AUTH: MAX_HANDSHAKE_PAYLOAD,
    FrameType.AUTH_OK: MAX_HANDSHAKE_PAYLOAD,
    FrameType.REJECT: MAX_REFUSAL_PAYLOAD,
    FrameType.CANCEL: MAX_REFUSAL_PAYLOAD,
}


def _type_name(t: int) -> str:
    try:
        return FrameType(t).name
    except ValueError:
        return f"type {t}"


def dump_json(obj: dict[str, Any]) -> bytes:
    """Compact UTF-8 JSON for a control payload."""
    return json.dumps(obj, separators=(",", ":"), ensure_ascii=False).encode("utf-8")


def parse_json(
    payload: bytes | bytearray,
    what: str = "frame",
    schema: Mapping[str, Any] | None = None,
    *,
    max_size: int = MAX_CONTROL_PAYLOAD,
) -> dict[str, Any]:
    """Parse a control payload with the bounded decoder (:mod:`mapkit.transfer.wirejson`):
    at most ``max_size`` bytes, 16 levels deep, 20-digit integers, finite numbers, valid
    Unicode, and the field types of ``schema`` (see :data:`~mapkit.transfer.wirejson.SCHEMAS`).

    Raises:
        ProtocolError: When it is not a JSON object within those limits.

    Examples:
        >>> parse_json(b'{"name":"a.map"}', "GET")
        {'name': 'a.map'}
        >>> try:
        ...     parse_json(b'[' * 100000, "HELLO")
        ... except ProtocolError as err:
        ...     print(err)
        HELLO payload refused: nested deeper than 16 levels
    """
    try:
        obj = decode_object(payload, max_size=max_size)
        if schema is not None:
            check_fields(obj, schema, what)
    except WireJSONError as err:
        raise ProtocolError(f"{what} payload refused: {err}") from err
    return obj


_Bytes = bytes | bytearray | memoryview


def _tag_hmac_sha256(key: bytes, head: bytes | memoryview, payload: _Bytes) -> bytes:
    mac = hmac.new(key, head, hashlib.sha256)
    mac.update(payload)
    return mac.digest()[:TAG_SIZE]


def _tag_blake2b(key: bytes, head: bytes | memoryview, payload: _Bytes) -> bytes:
    # payload first: its part can be computed before the header (sequence number) is known
    mac = hashlib.blake2b(digest_size=TAG_SIZE, key=key)
    mac.update(payload)  # hashlib releases the GIL on large buffers
    mac.update(head)
    return mac.digest()


class Prepared:
    """A DATA payload whose per-byte work was done ahead, e.g. in another thread while the file
    was being hashed: its CRC-32 and, for ``blake2b`` tags, the keyed BLAKE2b state after the
    payload. :func:`encode_frame` then only adds the header (microseconds per frame).

    Make them with :meth:`Channel.preparer`; pass one as an :class:`Out`'s payload (a
    :class:`Sender`'s ``read_chunk`` may return it). A frame encoded with another key or tag
    algorithm ignores the state and computes the tag afresh.

    Attributes:
        data: The payload bytes.
        crc: CRC-32 of ``data``.
    """

    __slots__ = ("_key", "_state", "crc", "data")

    def __init__(self, data: _Bytes, crc: int, state: Any = None, key: bytes | None = None) -> None:
        self.data = data
        self.crc = crc
        self._state = state
        self._key = key

    def __len__(self) -> int:
        return len(self.data)

    def with_data(self, data: _Bytes, crc: int) -> Prepared | None:
        """The same preparation for ``data``, read again later, if its CRC-32 ``crc`` is still
        this one's (None: the bytes changed since, so the preparation does not apply)."""
        return Prepared(data, crc, self._state, self._key) if crc == self.crc else None

    def tag(self, key: bytes, auth: str, head: bytes) -> bytes:
        """The frame's tag with ``key`` and ``auth`` for header bytes ``head`` (0..27)."""
        mine = self._key or b""
        if auth == "blake2b" and self._state is not None and hmac.compare_digest(key, mine):
            mac = self._state.copy()
            mac.update(head)
            return bytes(mac.digest())
        return _TAGGERS[auth](key, head, self.data)


def prepare_payload(data: _Bytes, key: bytes | None = None, auth: str = "none") -> Prepared:
    """Do a payload's CRC-32 (and with ``auth`` ``"blake2b"`` and a ``key``, its share of the
    tag) now; see :class:`Prepared`.

    Examples:
        >>> p = prepare_payload(b"chunk", b"k" * 32, "blake2b")
        >>> k = b"k" * 32
        >>> h = encode_frame(FrameType.DATA, p, session=1, seq=5, key=k, auth="blake2b")
        >>> h == encode_frame(FrameType.DATA, b"chunk", session=1, seq=5, key=k, auth="blake2b")
        True
    """
    state = None
    if auth == "blake2b" and key is not None:
        state = hashlib.blake2b(digest_size=TAG_SIZE, key=key)
        state.update(data)
    return Prepared(data, zlib.crc32(data), state, key)


_TAGGERS: dict[str, Callable[[bytes, bytes | memoryview, _Bytes], bytes]] = {
    "blake2b": _tag_blake2b,
    "hmac-sha256": _tag_hmac_sha256,
}
_tag = _tag_hmac_sha256  # the MKT/1 default, kept for callers of the old name


def encode_frame(
    type: int,
    payload: bytes | bytearray | memoryview | Prepared = b"",
    *,
    session: int,
    seq: int,
    ref: int = 0,
    flags: int = 0,
    key: bytes | None = None,
    auth: str = "hmac-sha256",
) -> tuple[bytes, bytes | bytearray | memoryview, bytes]:
    """Encode one frame as ``(header, payload, tag)`` (join them to get the wire bytes).

    Args:
        type: Frame type.
        payload: Payload bytes, or a :class:`Prepared` payload (its data is sent).
        session: 64-bit session id.
        seq: Sequence number (32-bit).
        ref: Chunk index or request number (32-bit).
        flags: Header flags; :attr:`Flag.AUTH` is set here when ``key`` is given.
        key: The sending direction's 32-byte key, or None for an untagged frame.
        auth: The tag algorithm (one of :data:`AUTH_METHODS`) when ``key`` is given.

    Returns:
        Three byte strings to send back to back (the tag is empty without a key).

    Examples:
        >>> head, body, tag = encode_frame(FrameType.PING, b"{}", session=1, seq=1)
        >>> len(head), head[:4], tag
        (36, b'MKT1', b'')
    """
    n = len(payload)
    if key is not None:
        flags |= Flag.AUTH
    else:
        flags &= ~Flag.AUTH
    head = struct.pack(">4sBBHQIII", MAGIC, VERSION, type, flags, session, seq, ref, n)
    if isinstance(payload, Prepared):
        tag = payload.tag(key, auth, head) if key is not None else b""
        crc, payload = payload.crc, payload.data
    else:
        tag = _TAGGERS[auth](key, head, payload) if key is not None else b""
        crc = zlib.crc32(payload)
    body_crc = zlib.crc32(tag, crc)
    head += struct.pack(">I", body_crc)
    head += struct.pack(">I", zlib.crc32(head))
    return head, payload, tag
