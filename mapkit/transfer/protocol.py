"""MKT/1, the mapkit transfer protocol, without any I/O ("sans-I/O").

This module knows frames, keys and state machines, and nothing about sockets, files or threads,
so the same core drives TCP (:mod:`mapkit.transfer.tcp`) and message transports such as ROS
topics. The wire format is specified in ``docs/transfer-protocol.md``; this docstring is the map
of the code.

Layers, bottom up:

* :func:`encode_frame` / :class:`Channel`: frames (magic ``MKT1``, version, type, flags,
  session, sequence, ref, length, CRC-32 of the body, CRC-32 of the header, payload, optional
  16-byte tag: keyed BLAKE2b or HMAC-SHA256, see :data:`AUTH_METHODS`). A :class:`Channel`
  numbers outgoing frames, tags them once keys are installed, and turns incoming bytes (a
  stream via :meth:`Channel.receive_data` or, without copies, :meth:`Channel.receive_into`;
  or one message per frame via :meth:`Channel.receive_message`) into :class:`Frame` and
  :class:`Damaged` events, checking CRCs, tags, the session id and replays.
* :class:`ClientHandshake` / :class:`ServerHandshake`: version and auth negotiation and mutual
  challenge-response from a pre-shared secret; they install the per-direction session keys in
  the channel.
* :class:`Request`: a control request that is resent until its answer comes.
* :class:`Sender` / :class:`Receiver`: one file in chunks, windowed, acknowledged with a
  cumulative index plus selective ranges, damaged or lost chunks resent, resume from a bitmap of
  chunks the receiver already holds, whole-file SHA-256 checked by the receiver's application.

Every machine has the same shape: ``start(now)`` and ``handle(frame, now)`` and ``poll(now)``
return the :class:`Out` frames to send (encode them with :meth:`Channel.encode`, in order);
``deadline()`` says when ``poll`` wants to run next; ``finished`` and ``error`` say how it ended.
Time is whatever monotonic clock the driver passes in (seconds), so tests can simulate it.

Writing a binding for another transport (what :mod:`mapkit.transfer.tcp` does for TCP):

1. Make a :class:`Channel` per session: ``Channel(initiator=True, session=random 64 bits)`` on
   the side that starts, ``Channel(initiator=False)`` on the other; ``ordered=False`` when the
   transport may lose, duplicate or reorder (ROS topics), and then feed each received message
   with :meth:`Channel.receive_message` (one frame per message) instead of ``receive_data``.
2. Run :class:`ClientHandshake` / :class:`ServerHandshake`, then :class:`Request` machines for
   GET/LIST/LOAD/BYE and :class:`Sender` / :class:`Receiver` for files: loop ``poll`` → send →
   wait for a message until ``deadline()`` → ``handle`` → send, until ``finished``.
3. For a receiver, store chunks and finish the file with
   :meth:`mapkit.transfer.store.PartialFile.take` (resume journal, SHA-256, atomic rename); on the
   robot side :class:`mapkit.transfer.server.MapFolder` does names, listings and LOAD.
4. Send :class:`Damaged` events to the machine too (``handle`` accepts them): the receiver asks
   for a damaged chunk again at once.

Examples:
    A whole push over an in-memory link, insecure, with 4-byte chunks:

    >>> import hashlib
    >>> data = b"2D-Map\\nDATA\\n1 2\\n"
    >>> offer = Offer.for_bytes("a.map", data, chunk_size=4)
    >>> tx = Sender(offer, lambda i: data[i * 4:(i + 1) * 4], ref=1)
    >>> rx_channel, tx_channel = Channel(initiator=False), Channel(initiator=True, session=7)
    >>> wire = [tx_channel.encode(o) for o in tx.start(0.0)]
    >>> rx_channel.receive_data(b"".join(wire))
    >>> frame = rx_channel.next_event()
    >>> rx = Receiver(Offer.from_json(frame.json()), ref=frame.ref)
    >>> got = bytearray(offer.size)
    >>> out = rx.accept(0.0)
    >>> while not tx.finished:
    ...     tx_channel.receive_data(b"".join(rx_channel.encode(o) for o in out))
    ...     out = []
    ...     while (ev := tx_channel.next_event()) is not None:
    ...         for o in tx.handle(ev, 0.0):
    ...             rx_channel.receive_data(tx_channel.encode(o))
    ...     while (ev := rx_channel.next_event()) is not None:
    ...         out += rx.handle(ev, 0.0)
    ...         for e in rx.pop_events():
    ...             if isinstance(e, ChunkReceived):
    ...                 got[e.offset:e.offset + len(e.data)] = e.data
    ...             elif isinstance(e, TransferComplete):
    ...                 out += rx.verified({"sha256": hashlib.sha256(got).hexdigest()}, 0.0)
    ...     out += tx.poll(0.0)
    >>> bytes(got) == data, tx.chunks_sent
    (True, 4)
"""

from __future__ import annotations

import base64
import binascii
import enum
import hashlib
import hmac
import json
import os
import struct
import sys
import zlib
from collections import deque
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Union

from mapkit.errors import ChecksumError, LocalTransferError, RemoteTransferError, TransferError
from mapkit.transfer.wirejson import SCHEMAS, WireJSONError, check_fields, decode_object

__all__ = [
    "AUTH_METHODS",
    "DEFAULT_CHUNK_SIZE",
    "DEFAULT_PORT",
    "HEADER_SIZE",
    "MAGIC",
    "MAX_CHUNK_SIZE",
    "TAG_SIZE",
    "VERSION",
    "AuthenticationError",
    "BufferPool",
    "Channel",
    "ChunkReceived",
    "ClientHandshake",
    "Damaged",
    "Flag",
    "Frame",
    "FrameType",
    "Offer",
    "Out",
    "Prepared",
    "ProtocolError",
    "Receiver",
    "Rejected",
    "ReplayError",
    "Request",
    "Sender",
    "ServerHandshake",
    "Status",
    "TransferComplete",
    "bitmap_from_ranges",
    "decode_bitmap",
    "derive_keys",
    "encode_bitmap",
    "encode_frame",
    "load_secret",
    "prepare_payload",
    "ranges_from_bitmap",
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


# -- errors -----------------------------------------------------------------------------------


class ProtocolError(LocalTransferError):
    """The peer broke the protocol (bad frame, unexpected type, limit exceeded).

    Attributes:
        status: The :class:`Status` to report to the peer before giving up.
    """

    def __init__(self, message: str, status: Status = Status.PROTOCOL) -> None:
        super().__init__(message)
        self.status = status


class AuthenticationError(ProtocolError):
    """A frame or proof failed authentication (wrong secret, forged or altered frame)."""

    def __init__(self, message: str, status: Status = Status.AUTH_FAILED) -> None:
        super().__init__(message, status)


class ReplayError(ProtocolError):
    """A frame's sequence number was already used in this session."""

    def __init__(self, message: str) -> None:
        super().__init__(message, Status.REPLAY)


class Rejected(RemoteTransferError):
    """The peer refused a request or cancelled a transfer (REJECT or CANCEL frame).

    Attributes:
        status: The peer's :class:`Status` (or the raw int when unknown).
        reason: The peer's reason word, e.g. ``"bad_name"``.
        detail: The peer's human-readable message.
    """

    def __init__(self, status: int, reason: str, detail: str, *, peer: str = "peer") -> None:
        self.status: Status | int
        try:
            self.status = Status(status)
        except ValueError:
            self.status = status
        self.reason = reason
        self.detail = detail
        super().__init__(f"{peer} refused: {reason}: {detail}" if detail else f"{peer} refused: {reason}")


class TimeoutTransferError(LocalTransferError):
    """No answer from the peer in time (after the allowed resends)."""

    status = Status.TIMEOUT


def status_of(err: BaseException) -> Status:
    """The :class:`Status` that best describes ``err`` for a REJECT or CANCEL frame."""
    st = getattr(err, "status", None)
    if isinstance(st, Status):
        return st
    if isinstance(err, ChecksumError):
        return Status.HASH_MISMATCH
    return Status.INTERNAL


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
        return parse_json(self.payload, _type_name(self.type), SCHEMAS.get(self.type),
                          max_size=_SMALL_PAYLOADS.get(self.type, MAX_CONTROL_PAYLOAD))


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


Event = Union[Frame, Damaged]

# payloads that a peer can send before it proved anything are small: decoding them costs little
_SMALL_PAYLOADS: dict[int, int] = {
    FrameType.HELLO: MAX_HANDSHAKE_PAYLOAD, FrameType.HELLO_ACK: MAX_HANDSHAKE_PAYLOAD,
    FrameType.AUTH: MAX_HANDSHAKE_PAYLOAD, FrameType.AUTH_OK: MAX_HANDSHAKE_PAYLOAD,
    FrameType.REJECT: MAX_REFUSAL_PAYLOAD, FrameType.CANCEL: MAX_REFUSAL_PAYLOAD,
}


def _type_name(t: int) -> str:
    try:
        return FrameType(t).name
    except ValueError:
        return f"type {t}"


def dump_json(obj: dict[str, Any]) -> bytes:
    """Compact UTF-8 JSON for a control payload."""
    return json.dumps(obj, separators=(",", ":"), ensure_ascii=False).encode("utf-8")


def parse_json(payload: bytes | bytearray, what: str = "frame",
               schema: Mapping[str, Any] | None = None, *,
               max_size: int = MAX_CONTROL_PAYLOAD) -> dict[str, Any]:
    """Parse a control payload with the bounded decoder (:mod:`mapkit.transfer.wirejson`):
    at most ``max_size`` bytes, 16 levels deep, 20-digit integers, finite numbers, valid
    Unicode, and the field types of ``schema`` (see :data:`~mapkit.transfer.wirejson.SCHEMAS`).

    Raises:
        ProtocolError: When it is not a JSON object within those limits.

    Examples:
        >>> parse_json(b'{"name":"a.map"}', "GET")
        {'name': 'a.map'}
        >>> parse_json(b'[' * 100000, "HELLO")
        Traceback (most recent call last):
        ...
        mapkit.transfer.protocol.ProtocolError: HELLO payload refused: nested deeper than 16 levels
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


class BufferPool:
    """Reusable large buffers, so that a stream of 1 MiB chunks does not map fresh memory (and
    take a page fault per 4 KiB) for every chunk.

    :meth:`get` hands out a pooled ``bytearray`` only when nothing else refers to it any more
    (CPython reference counts): a buffer still held by a frame, a queue or a memoryview is never
    reused, so callers need not give buffers back.

    Args:
        limit: Buffers kept at most.

    Examples:
        >>> pool = BufferPool()
        >>> a = pool.get(4)
        >>> pool.get(4) is a  # still referenced by `a`: a new one
        False
        >>> del a
        >>> len(pool.get(4))
        4
    """

    def __init__(self, limit: int = 16) -> None:
        self.limit = limit
        self._bufs: list[bytearray] = []

    def get(self, size: int) -> bytearray:
        """A buffer of exactly ``size`` bytes (contents undefined)."""
        for buf in self._bufs:
            if len(buf) == size and sys.getrefcount(buf) <= 3:  # the list, `buf`, the call
                return buf
        buf = bytearray(size)
        if len(self._bufs) < self.limit:
            self._bufs.append(buf)
        return buf


class Channel:
    """Framing, tagging and replay protection for one session, in one endpoint.

    Args:
        initiator: True for the side that opened the session (its frames use the c2s key).
        session: The session id; a responder leaves it None and adopts the first frame's id.
        ordered: True on stream transports (TCP): a replayed, reordered or foreign frame is an
            error. False on message transports that may lose, duplicate or reorder: such frames
            are dropped and counted.
        max_payload: Largest payload accepted (bigger is a protocol error).
        replay_window: How many sequence numbers back a late frame may still arrive (unordered).
        direct_threshold: On a stream, the payload of a frame at least this large is received
            into a buffer of its own (see :meth:`receive_into`) and delivered as that
            ``bytearray``, without further copies.

    Attributes:
        auth: The tag algorithm once keys are installed (one of :data:`AUTH_METHODS`).
        stats: Counters: ``frames_in``, ``frames_out``, ``damaged``, ``garbage`` (bytes skipped),
            ``duplicates``, ``foreign`` (other sessions), ``forged`` (bad tags dropped).
    """

    def __init__(
        self,
        *,
        initiator: bool,
        session: int | None = None,
        ordered: bool = True,
        max_payload: int = DEFAULT_MAX_PAYLOAD,
        replay_window: int = 4096,
        direct_threshold: int = 64 * 1024,
    ) -> None:
        self.initiator = initiator
        self.session = session
        self.ordered = ordered
        self.max_payload = max_payload
        self.replay_window = replay_window
        self.direct_threshold = direct_threshold
        self.auth = "hmac-sha256"
        self._tagger = _TAGGERS[self.auth]
        self._seq = 0
        self._send_key: bytes | None = None
        self._recv_key: bytes | None = None
        self._buf = bytearray()
        self._pos = 0
        self._messages = False  # receive_message was used: never receive a payload in place
        self._scratch: bytearray | None = None
        # a large frame whose header was checked and whose payload is being received in place
        self._body: bytearray | None = None
        self._body_fill = 0
        self._body_head: tuple[bytes, int, int, int, int, int, int, bool] | None = None
        self._pool = BufferPool()
        self._highest = 0
        self._seen = 0  # bit k set: seq (highest - k) was seen
        self.stats = {"frames_in": 0, "frames_out": 0, "damaged": 0, "garbage": 0,
                      "duplicates": 0, "foreign": 0, "forged": 0}

    # keys -------------------------------------------------------------------------------------
    def install_keys(self, c2s: bytes, s2c: bytes, auth: str = "hmac-sha256") -> None:
        """Tag every later frame and require tags on incoming ones (except the handshake).

        Args:
            c2s: The initiator's sending key.
            s2c: The responder's sending key.
            auth: The tag algorithm negotiated in the handshake (one of :data:`AUTH_METHODS`).

        Raises:
            ValueError: For an unknown ``auth``.
        """
        if auth not in _TAGGERS:
            raise ValueError(f"unknown tag algorithm {auth!r}")
        self.auth = auth
        self._tagger = _TAGGERS[auth]
        self._send_key, self._recv_key = (c2s, s2c) if self.initiator else (s2c, c2s)

    @property
    def keyed(self) -> bool:
        """True once session keys are installed."""
        return self._send_key is not None

    # sending ----------------------------------------------------------------------------------
    def encode_parts(self, out: Out) -> tuple[bytes, bytes | bytearray | memoryview, bytes]:
        """Number (and tag) ``out``; return ``(header, payload, tag)`` for a gather write."""
        if self.session is None:
            raise LocalTransferError("no session id yet: the channel has not seen the peer's HELLO")
        self._seq += 1
        if self._seq > 0xFFFFFFFF:
            raise LocalTransferError("sequence numbers exhausted: start a new session")
        plain = out.plain or out.type in (FrameType.HELLO, FrameType.HELLO_ACK)
        key = None if plain else self._send_key
        self.stats["frames_out"] += 1
        return encode_frame(out.type, out.payload, session=self.session, seq=self._seq,
                            ref=out.ref, flags=out.flags, key=key, auth=self.auth)

    def preparer(self) -> Callable[[_Bytes], Prepared]:
        """A function that does a payload's per-byte work for this channel's sending key and tag
        algorithm ahead of time (:class:`Prepared`); call it from any thread."""
        key, auth = self._send_key, self.auth

        def prepare(data: _Bytes) -> Prepared:
            return prepare_payload(data, key, auth if key is not None else "none")

        return prepare

    def encode(self, out: Out) -> bytes:
        """Number (and tag) ``out``; return its wire bytes."""
        head, payload, tag = self.encode_parts(out)
        return b"".join((head, payload, tag))

    # receiving --------------------------------------------------------------------------------
    def receive_data(self, data: bytes | bytearray | memoryview) -> None:
        """Add bytes from a stream transport; frames come out of :meth:`next_event`."""
        body = self._body
        if body is not None and self._body_fill < len(body):
            k = min(len(data), len(body) - self._body_fill)
            body[self._body_fill:self._body_fill + k] = data[:k]
            self._body_fill += k
            if k == len(data):
                return
            data = data[k:]
        if self._pos and self._pos >= len(self._buf) // 2:
            del self._buf[: self._pos]
            self._pos = 0
        self._buf += data

    def receive_into(self, recv: Callable[[memoryview], int], size: int = 64 * 1024) -> int:
        """Read from a stream with ``recv`` (e.g. ``socket.recv_into``) straight into this channel.

        While the payload of a large frame (``direct_threshold``) is arriving, ``recv`` writes
        into that payload's own buffer, which later becomes :attr:`Frame.payload`: the bytes are
        copied once, by the kernel. Otherwise at most ``size`` bytes are read and buffered.

        Args:
            recv: Fills a prefix of the given buffer and returns how many bytes it wrote
                (0: end of stream). Its exceptions propagate.
            size: Largest read outside a large payload.

        Returns:
            What ``recv`` returned.
        """
        body = self._body
        if body is not None and self._body_fill < len(body):
            with memoryview(body) as view:
                n = recv(view[self._body_fill:])
            self._body_fill += n
            return n
        if self._scratch is None or len(self._scratch) != size:
            self._scratch = bytearray(size)
        with memoryview(self._scratch) as view:
            n = recv(view)
            if n:
                self.receive_data(view[:n])
        return n

    def receive_message(self, data: bytes | bytearray | memoryview) -> None:
        """Add one message of a message transport, which holds exactly one frame.

        Anything left over of a previous message (a truncated frame) is dropped as garbage.
        """
        self._messages = True
        self.stats["garbage"] += self.buffered
        self._body, self._body_head, self._body_fill = None, None, 0
        self._buf = bytearray(data)
        self._pos = 0

    @property
    def buffered(self) -> int:
        """Bytes received but not yet decoded."""
        return len(self._buf) - self._pos + (self._body_fill if self._body is not None else 0)

    def next_event(self) -> Event | None:
        """The next decoded :class:`Frame` or :class:`Damaged`, or None when more bytes are needed.

        Raises:
            ProtocolError: On an ordered transport: a frame from another session, an oversized or
                unknown-version frame.
            AuthenticationError: A frame with a valid CRC but a missing or wrong tag, on an ordered
                transport or during the handshake.
            ReplayError: A sequence number seen before, on an ordered transport.
        """
        while True:
            ev = self._decode_one()
            if ev is not _AGAIN:
                return ev  # type: ignore[return-value]

    def _resync(self, start: int) -> None:
        buf = self._buf
        nxt = buf.find(MAGIC, start)
        if nxt < 0:
            nxt = max(start, len(buf) - len(MAGIC) + 1)
        self.stats["garbage"] += nxt - self._pos
        self._pos = nxt

    def _decode_one(self) -> Event | object | None:
        if self._body is not None:
            return self._finish_body()
        buf, pos = self._buf, self._pos
        if len(buf) - pos < HEADER_SIZE:
            if len(buf) - pos >= 4 and buf[pos:pos + 4] != MAGIC:
                self._resync(pos + 1)
                return _AGAIN
            return None
        if buf[pos:pos + 4] != MAGIC:
            self._resync(pos + 1)
            return _AGAIN
        (_, version, ftype, flags, session, seq, ref, length, body_crc, head_crc) = HEADER.unpack_from(buf, pos)
        with memoryview(buf) as view:
            head_ok = zlib.crc32(view[pos:pos + 32]) == head_crc
        if not head_ok:
            self._resync(pos + 1)
            return _AGAIN
        if version != VERSION:
            raise ProtocolError(f"peer speaks MKT version {version}, this side only {VERSION}",
                                Status.BAD_VERSION)
        limit = self.max_payload if ftype == FrameType.DATA else MAX_CONTROL_PAYLOAD
        if length > max(limit, MAX_CONTROL_PAYLOAD):
            raise ProtocolError(f"{_type_name(ftype)} frame of {length} bytes exceeds the limit of "
                                f"{limit} bytes", Status.TOO_LARGE)
        tagged = bool(flags & Flag.AUTH)
        total = HEADER_SIZE + length + (TAG_SIZE if tagged else 0)
        start = pos + HEADER_SIZE
        head = bytes(buf[pos:start])
        if len(buf) - pos < total:
            if length < self.direct_threshold or self._messages:
                return None
            # a large payload: give it a buffer of its own and receive the rest straight into it
            body = self._pool.get(length)
            k = min(len(buf) - start, length)
            with memoryview(buf) as view:
                body[:k] = view[start:start + k]
            self._body, self._body_fill = body, k
            self._body_head = (head, ftype, flags, session, seq, ref, body_crc, tagged)
            self._pos = start + k
            return self._finish_body()
        with memoryview(buf) as view:
            payload = bytes(view[start:start + length])
            tag = bytes(view[start + length:pos + total])
        self._pos = pos + total
        return self._check(head, ftype, flags, session, seq, ref, body_crc, tagged, payload, tag)

    def _finish_body(self) -> Event | object | None:
        body, meta = self._body, self._body_head
        assert body is not None and meta is not None
        head, ftype, flags, session, seq, ref, body_crc, tagged = meta
        if self._body_fill < len(body):
            return None
        n = TAG_SIZE if tagged else 0
        if len(self._buf) - self._pos < n:
            return None
        tag = bytes(self._buf[self._pos:self._pos + n])
        self._pos += n
        self._body, self._body_head, self._body_fill = None, None, 0
        return self._check(head, ftype, flags, session, seq, ref, body_crc, tagged, body, tag)

    def _check(self, head: bytes, ftype: int, flags: int, session: int, seq: int, ref: int,
               body_crc: int, tagged: bool, payload: bytes | bytearray,
               tag: bytes) -> Event | object:
        """CRC, session, tag and replay checks of a whole frame already taken off the buffer."""
        handshake = ftype in (FrameType.HELLO, FrameType.HELLO_ACK)
        key = None if handshake else self._recv_key
        tag_ok = False
        if key is not None and tagged and len(payload) >= _TAG_FIRST:
            # a valid tag proves the body intact: the CRC pass is skipped, and the payload's own
            # CRC (for the resume journal) follows from the header's CRC of payload ‖ tag
            mine = self._tagger(key, head[:MAC_HEADER], payload)
            tag_ok = hmac.compare_digest(mine, tag)
        if tag_ok:
            crc = crc32_strip(body_crc, tag)
        else:
            crc = zlib.crc32(payload)
            if zlib.crc32(tag, crc) != body_crc:
                self.stats["damaged"] += 1
                return Damaged(ftype, seq, ref)
        # session
        if self.session is None:
            self.session = session
        elif session != self.session:
            if self.ordered:
                raise ProtocolError(f"frame for session {session:016x} on session {self.session:016x}")
            self.stats["foreign"] += 1
            return _AGAIN
        # authentication
        authentic = False
        if key is not None:
            if tag_ok or (tagged and len(payload) < _TAG_FIRST and hmac.compare_digest(
                    self._tagger(key, head[:MAC_HEADER], payload), tag)):
                authentic = True
            elif ftype == FrameType.REJECT and not tagged:
                authentic = False  # an untagged refusal: delivered, marked as not authentic
            else:
                what = "has no tag" if not tagged else "has a wrong tag"
                if self.ordered or ftype in (FrameType.AUTH, FrameType.AUTH_OK):
                    raise AuthenticationError(f"{_type_name(ftype)} frame (seq {seq}) {what}: "
                                              "altered, forged, or sent with another secret")
                self.stats["forged"] += 1
                return _AGAIN
        # replay
        if not self._replay_ok(seq):
            if self.ordered:
                raise ReplayError(f"replayed frame: {_type_name(ftype)} seq {seq} after seq "
                                  f"{self._highest}")
            self.stats["duplicates"] += 1
            return _AGAIN
        self.stats["frames_in"] += 1
        return Frame(ftype, seq, ref, payload, flags, session, authentic, crc)

    def _replay_ok(self, seq: int) -> bool:
        if seq == 0:
            return False
        if seq > self._highest:
            shift = seq - self._highest
            self._seen = ((self._seen << shift) | 1) & ((1 << self.replay_window) - 1)
            self._highest = seq
            return True
        if self.ordered:
            return False
        back = self._highest - seq
        if back >= self.replay_window or (self._seen >> back) & 1:
            return False
        self._seen |= 1 << back
        return True


_AGAIN = object()
_TAG_FIRST = 4096  # payloads from this size: check the tag first, the CRC only if the tag fails


def _crc_table() -> tuple[list[int], dict[int, int]]:
    table = []
    for i in range(256):
        c = i
        for _ in range(8):
            c = (c >> 1) ^ 0xEDB88320 if c & 1 else c >> 1
        table.append(c)
    return table, {t >> 24: i for i, t in enumerate(table)}


_CRC_TABLE, _CRC_TOP = _crc_table()


def crc32_strip(crc: int, tail: bytes) -> int:
    """The CRC-32 of ``data`` from the CRC-32 of ``data ‖ tail`` (zlib's CRC run backwards).

    Examples:
        >>> crc32_strip(zlib.crc32(b"payload" + b"tag"), b"tag") == zlib.crc32(b"payload")
        True
    """
    s = crc ^ 0xFFFFFFFF
    for b in reversed(tail):
        i = _CRC_TOP[s >> 24]
        s = (((s ^ _CRC_TABLE[i]) << 8) & 0xFFFFFFFF) | (i ^ b)
    return s ^ 0xFFFFFFFF


# -- keys and secrets ----------------------------------------------------------------------------


def load_secret(*, path: str | os.PathLike[str] | None = None,
                env: Mapping[str, str] | None = None) -> bytes | None:
    """Read the pre-shared secret from a file, or else the ``MAPKIT_SECRET`` environment variable.

    Surrounding whitespace (the trailing newline of a file) is removed. The secret is never taken
    from the command line, where other users can read it.

    Args:
        path: A file holding the secret, or None.
        env: The environment to read (default ``os.environ``); ``MAPKIT_SECRET_FILE`` names a
            file when ``path`` is None.

    Returns:
        The secret, or None when none is configured.

    Raises:
        LocalTransferError: When the file cannot be read or the secret is shorter than 16 bytes.

    Examples:
        >>> load_secret(env={"MAPKIT_SECRET": "correct horse battery staple"})
        b'correct horse battery staple'
        >>> load_secret(env={}) is None
        True
    """
    environ: Mapping[str, str] = os.environ if env is None else env
    where = ""
    if path is None and environ.get("MAPKIT_SECRET_FILE"):
        path = environ["MAPKIT_SECRET_FILE"]
    if path is not None:
        where = os.fspath(path)
        try:
            with open(path, "rb") as fh:
                secret = fh.read(65536).strip()
        except OSError as err:
            raise LocalTransferError(f"{where}: cannot read the secret: {err.strerror}") from err
    elif environ.get("MAPKIT_SECRET"):
        where = "MAPKIT_SECRET"
        secret = environ["MAPKIT_SECRET"].strip().encode("utf-8")
    else:
        return None
    if len(secret) < MIN_SECRET:
        raise LocalTransferError(f"{where}: the secret has {len(secret)} bytes; use at least "
                                 f"{MIN_SECRET} (e.g. `head -c 32 /dev/urandom | base64`)")
    return secret


def _hkdf(secret: bytes, salt: bytes, info: bytes, length: int) -> bytes:
    prk = hmac.new(salt, secret, hashlib.sha256).digest()
    out, block, i = b"", b"", 1
    while len(out) < length:
        block = hmac.new(prk, block + info + bytes([i]), hashlib.sha256).digest()
        out += block
        i += 1
    return out[:length]


def derive_keys(secret: bytes, session: int, nonce_c: bytes, nonce_s: bytes,
                transcript: bytes) -> tuple[bytes, bytes]:
    """The two session keys ``(c2s, s2c)``: HKDF-SHA256 of the secret, salted with both nonces.

    Args:
        secret: The pre-shared secret.
        session: The session id.
        nonce_c: The client's 32-byte nonce (HELLO).
        nonce_s: The server's 32-byte nonce (HELLO_ACK).
        transcript: SHA-256 of the HELLO payload followed by the HELLO_ACK payload.

    Returns:
        Two 32-byte keys.
    """
    okm = _hkdf(secret, nonce_c + nonce_s, b"MKT1 keys" + session.to_bytes(8, "big") + transcript, 64)
    return okm[:32], okm[32:]


def _proof(key: bytes, label: bytes, transcript: bytes) -> str:
    return hmac.new(key, label + transcript, hashlib.sha256).hexdigest()


def _unhex(value: Any, size: int, what: str) -> bytes:
    try:
        raw = binascii.unhexlify(value) if isinstance(value, str) else b""
    except (binascii.Error, ValueError):
        raw = b""
    if len(raw) != size:
        raise ProtocolError(f"{what} must be {size} bytes in hex")
    return raw


# -- bitmaps and ranges ---------------------------------------------------------------------------


def ranges_from_bitmap(have: bytes | bytearray, start: int = 0, limit: int | None = None) -> list[list[int]]:
    """Half-open ``[a, b)`` ranges of set entries (value 1) in a byte-per-chunk bitmap.

    Examples:
        >>> ranges_from_bitmap(bytearray([1, 1, 0, 1, 0, 0, 1]))
        [[0, 2], [3, 4], [6, 7]]
        >>> ranges_from_bitmap(bytearray([1, 1, 0, 1, 0, 0, 1]), start=1, limit=1)
        [[1, 2]]
    """
    out: list[list[int]] = []
    n = len(have)
    i = start
    while i < n and (limit is None or len(out) < limit):
        a = have.find(1, i)
        if a < 0:
            break
        b = have.find(0, a)
        if b < 0:
            b = n
        out.append([a, b])
        i = b
    return out


def bitmap_from_ranges(n: int, ranges: Iterable[Any]) -> bytearray:
    """A byte-per-chunk bitmap of ``n`` entries with the given ``[a, b)`` ranges set.

    Raises:
        ProtocolError: When a range is malformed or out of bounds.
    """
    have = bytearray(n)
    for r in ranges:
        if not (isinstance(r, list) and len(r) == 2 and all(isinstance(v, int) for v in r)
                and 0 <= r[0] <= r[1] <= n):
            raise ProtocolError(f"bad chunk range {r!r} for {n} chunks")
        have[r[0]:r[1]] = b"\x01" * (r[1] - r[0])
    return have


_TO_01 = bytes.maketrans(b"\x00\x01", b"01")
_FROM_01 = bytes.maketrans(b"01", b"\x00\x01")


def encode_bitmap(have: bytes | bytearray) -> str:
    """Pack a byte-per-chunk bitmap into base64 bits, most significant bit first.

    Examples:
        >>> encode_bitmap(bytearray([1, 0, 1, 1, 0, 0, 0, 0, 1]))
        'sIA='
    """
    n = len(have)
    if n == 0 or not any(have):
        return ""
    pad = (-n) % 8
    bits = bytes(have).translate(_TO_01) + b"0" * pad
    return base64.b64encode(int(bits, 2).to_bytes((n + pad) // 8, "big")).decode("ascii")


def decode_bitmap(text: Any, n: int) -> bytearray:
    """Unpack :func:`encode_bitmap` output into a byte-per-chunk bitmap of ``n`` entries.

    Raises:
        ProtocolError: When the text is not base64 of the right length.

    Examples:
        >>> list(decode_bitmap('sIA=', 9))
        [1, 0, 1, 1, 0, 0, 0, 0, 1]
    """
    if text in ("", None):
        return bytearray(n)
    try:
        raw = base64.b64decode(text, validate=True)
    except (binascii.Error, ValueError, TypeError) as err:
        raise ProtocolError(f"bad chunk bitmap: {err}") from err
    if len(raw) != (n + 7) // 8:
        raise ProtocolError(f"chunk bitmap has {len(raw)} bytes, expected {(n + 7) // 8}")
    bits = format(int.from_bytes(raw, "big"), f"0{len(raw) * 8}b").encode("ascii")
    out = bytearray(bits[:n].translate(_FROM_01))
    if any(bits[n:].translate(_FROM_01)):
        raise ProtocolError("chunk bitmap has bits set past the last chunk")
    return out


# -- offer ------------------------------------------------------------------------------------------


def kind_of(name: str) -> str:
    """``"map"`` for ``.map`` names, ``"2d"`` for ``.2d`` laser logs, else ``"file"``."""
    low = name.lower()
    return "map" if low.endswith(".map") else "2d" if low.endswith(".2d") else "file"


@dataclass(frozen=True, slots=True)
class Offer:
    """What a sender proposes to send: the file's identity and how it is cut into chunks.

    Attributes:
        name: Plain file name (checked by the receiver's application, not here).
        size: Bytes.
        sha256: Hex SHA-256 of the whole file: the file's identity and the final check.
        chunk_size: Bytes per chunk (the last chunk may be shorter).
        md5: Hex MD5 of the file for maps (ARIA's map id), else None.
        kind: ``"map"``, ``"2d"`` or ``"file"``.
        mtime: Modification time (UNIX seconds) or None.
    """

    name: str
    size: int
    sha256: str
    chunk_size: int = DEFAULT_CHUNK_SIZE
    md5: str | None = None
    kind: str = "file"
    mtime: float | None = None

    @property
    def chunks(self) -> int:
        """Number of chunks (0 for an empty file)."""
        return -(-self.size // self.chunk_size)

    def chunk_len(self, index: int) -> int:
        """Length of chunk ``index``."""
        return min(self.chunk_size, self.size - index * self.chunk_size)

    def json(self) -> dict[str, Any]:
        """The OFFER payload."""
        d: dict[str, Any] = {"name": self.name, "size": self.size, "sha256": self.sha256,
                             "chunk_size": self.chunk_size, "chunks": self.chunks, "kind": self.kind}
        if self.md5 is not None:
            d["md5"] = self.md5
        if self.mtime is not None:
            d["mtime"] = self.mtime
        return d

    @classmethod
    def from_json(cls, d: dict[str, Any], *, max_chunk: int = MAX_CHUNK_SIZE) -> Offer:
        """Check and read an OFFER payload.

        Raises:
            ProtocolError: When a field is missing, of the wrong type or inconsistent.
        """
        name, size, sha, cs = d.get("name"), d.get("size"), d.get("sha256"), d.get("chunk_size")
        if not isinstance(name, str):
            raise ProtocolError("OFFER has no name", Status.BAD_NAME)
        if not isinstance(size, int) or isinstance(size, bool) or size < 0:
            raise ProtocolError(f"OFFER size {size!r} is not a byte count")
        if not isinstance(cs, int) or isinstance(cs, bool) or not 1 <= cs <= max_chunk:
            raise ProtocolError(f"OFFER chunk size {cs!r} is outside 1..{max_chunk}", Status.TOO_LARGE)
        _unhex(sha, 32, "OFFER sha256")
        kind = d.get("kind", kind_of(name))
        if kind != kind_of(name):
            raise ProtocolError(f"OFFER kind {kind!r} does not match the name {name!r} "
                                f"(a {kind_of(name)!r} by its suffix)")
        md5 = d.get("md5")
        if md5 is not None:
            _unhex(md5, 16, "OFFER md5")
        elif kind == "map":
            raise ProtocolError(f"OFFER of the map {name!r} has no md5 (required for maps: "
                                "ARIA's map id)")
        mtime = d.get("mtime")
        offer = cls(name, size, str(sha).lower(), cs, str(md5).lower() if md5 else None, kind,
                    mtime if isinstance(mtime, (int, float)) else None)
        if d.get("chunks", offer.chunks) != offer.chunks:
            raise ProtocolError(f"OFFER says {d.get('chunks')} chunks, size/chunk_size gives {offer.chunks}")
        if offer.chunks > MAX_CHUNKS:
            raise ProtocolError(f"OFFER has {offer.chunks} chunks, more than {MAX_CHUNKS}", Status.TOO_LARGE)
        return offer

    @classmethod
    def for_bytes(cls, name: str, data: bytes, *, chunk_size: int = DEFAULT_CHUNK_SIZE,
                  mtime: float | None = None) -> Offer:
        """An offer for bytes in memory (MD5 included for maps).

        Examples:
            >>> Offer.for_bytes("a.map", b"2D-Map\\n").chunks
            1
        """
        kind = kind_of(name)
        md5 = hashlib.md5(data).hexdigest() if kind == "map" else None
        return cls(name, len(data), hashlib.sha256(data).hexdigest(), chunk_size, md5, kind, mtime)


# -- machine plumbing -----------------------------------------------------------------------------


def _reject(code: Status, message: str, ref: int = 0, *, plain: bool = False,
            ftype: FrameType = FrameType.REJECT) -> Out:
    return Out(ftype, dump_json({"code": int(code), "reason": code.reason, "message": message}),
               ref=ref, plain=plain)


def rejected_from(frame: Frame, peer: str = "peer") -> Rejected:
    """A :class:`Rejected` error from a REJECT or CANCEL frame."""
    try:
        d = frame.json()
    except ProtocolError:
        d = {}
    code = d.get("code", int(Status.INTERNAL))
    code = code if isinstance(code, int) else int(Status.INTERNAL)
    try:
        default_reason = Status(code).reason
    except ValueError:
        default_reason = f"code {code}"
    reason = str(d["reason"]) if isinstance(d.get("reason"), str) else default_reason
    message = str(d["message"]) if isinstance(d.get("message"), str) else ""
    return Rejected(code, reason, message, peer=peer)


def reject_out(err: BaseException, ref: int = 0, *, plain: bool = False, cancel: bool = False) -> Out:
    """The REJECT (or CANCEL) frame that reports ``err`` to the peer."""
    return _reject(status_of(err), str(err), ref, plain=plain,
                   ftype=FrameType.CANCEL if cancel else FrameType.REJECT)


class _Machine:
    """Shared state: finished/error, a resend timer and an idle timer."""

    def __init__(self, *, rto: float, max_tries: int, idle_timeout: float) -> None:
        self.rto = rto
        self.max_tries = max_tries
        self.idle_timeout = idle_timeout
        self.finished = False
        self.error: TransferError | None = None
        self._timer: float | None = None
        self._tries = 0
        self._last_heard = 0.0
        self._events: list[Any] = []

    @property
    def last_heard(self) -> float:
        """When (on the driver's clock) the last frame from the peer arrived."""
        return self._last_heard

    def pop_events(self) -> list[Any]:
        """Events for the application since the last call."""
        ev, self._events = self._events, []
        return ev

    def _fail(self, err: TransferError) -> None:
        if not self.finished:
            self.finished = True
            self.error = err
            self._timer = None

    def _finish(self) -> None:
        self.finished = True
        self._timer = None

    def _arm(self, now: float) -> None:
        self._timer = now + self.rto * min(2 ** max(self._tries - 1, 0), 8)

    def _heard(self, now: float) -> None:
        self._last_heard = now

    def deadline(self) -> float | None:
        """When :meth:`poll` should run next (None: only on a frame)."""
        if self.finished:
            return None
        idle = self._last_heard + self.idle_timeout
        return idle if self._timer is None else min(self._timer, idle)

    def _idle(self, now: float, what: str) -> bool:
        if not self.finished and now >= self._last_heard + self.idle_timeout:
            self._fail(TimeoutTransferError(f"no frame from the peer for {self.idle_timeout:g} s "
                                            f"while {what}"))
            return True
        return False

    ref = 0

    def _handle(self, f: Frame, now: float) -> list[Out]:  # pragma: no cover - overridden
        return []

    def _guarded(self, f: Frame, now: float, peer: str) -> list[Out]:
        """A REJECT/CANCEL of this exchange ends it; a local error is answered with CANCEL."""
        if f.type in (FrameType.REJECT, FrameType.CANCEL):
            if f.ref == self.ref:
                self._fail(rejected_from(f, peer))
            return []
        try:
            return self._handle(f, now)
        except TransferError as err:
            return self.fail(err, self.ref)

    def _resend(self, now: float, out: Out | None) -> list[Out]:
        """``[out]`` again when the resend timer expired; fail after ``max_tries`` sends."""
        if self._timer is None or now < self._timer or out is None:
            return []
        if self._tries >= self.max_tries:
            self._fail(TimeoutTransferError(f"no answer to {out.type.name} after {self._tries} tries"))
            return []
        self._tries += 1
        self._arm(now)
        return [out]

    def fail(self, err: TransferError, ref: int = 0) -> list[Out]:
        """Give up with ``err`` (e.g. the application's disk is full); returns the CANCEL to send."""
        if self.finished:
            return []
        self._fail(err)
        return [reject_out(err, ref, cancel=True)]


# -- handshake --------------------------------------------------------------------------------------


class ClientHandshake(_Machine):
    """The initiator's side of HELLO / HELLO_ACK / AUTH / AUTH_OK.

    Args:
        channel: The session's channel (its session id set); keys are installed into it.
        secret: The pre-shared secret, or None for an insecure session (``--insecure``).
        peer: A name for this endpoint (host name), shown in the peer's logs.
        nonce: Fixed nonce for tests; random otherwise.
        rto: First resend timeout (seconds), doubled on each resend.
        max_tries: Sends of one frame before giving up.
        idle_timeout: Give up after this long without any frame.
        auth_methods: Tag algorithms to offer, preferred first (with a secret).

    Attributes:
        server: The HELLO_ACK payload (version, peer name, limits, features).
        auth: ``"none"``, or the tag algorithm the server chose once the handshake is done.
    """

    def __init__(self, channel: Channel, secret: bytes | None, *, peer: str = "",
                 nonce: bytes | None = None, rto: float = 1.0, max_tries: int = 5,
                 idle_timeout: float = 30.0, auth_methods: Sequence[str] = AUTH_METHODS) -> None:
        super().__init__(rto=rto, max_tries=max_tries, idle_timeout=idle_timeout)
        self.channel = channel
        self.secret = secret
        methods = [m for m in auth_methods if m in _TAGGERS]
        if secret is not None and not methods:
            raise ValueError(f"no known tag algorithm in {list(auth_methods)!r}")
        self.offered: list[str] | str = methods if secret is not None else "none"
        self.auth = methods[0] if secret is not None else "none"
        self.nonce = nonce or os.urandom(NONCE_SIZE)
        self.server: dict[str, Any] = {}
        self._hello = dump_json({"versions": [VERSION], "nonce": self.nonce.hex(),
                                 "auth": self.offered, "peer": peer, "software": SOFTWARE})
        self._pending: Out | None = None
        self._th = b""
        self._expect_proof = ""

    def start(self, now: float) -> list[Out]:
        """The HELLO frame."""
        self._heard(now)
        self._pending = Out(FrameType.HELLO, self._hello)
        self._tries = 1
        self._arm(now)
        return [self._pending]

    def poll(self, now: float) -> list[Out]:
        """Resend HELLO or AUTH when its answer is late."""
        if self.finished or self._idle(now, "waiting for the handshake"):
            return []
        return self._resend(now, self._pending)

    def handle(self, ev: Event, now: float) -> list[Out]:
        """Take a frame from the server."""
        if self.finished or isinstance(ev, Damaged):
            return []
        self._heard(now)
        try:
            return self._handle(ev, now)
        except TransferError as err:
            self._fail(err)
            return []

    def _handle(self, f: Frame, now: float) -> list[Out]:
        if f.type in (FrameType.REJECT, FrameType.CANCEL):
            raise rejected_from(f, "server")
        if f.type == FrameType.HELLO_ACK and self._pending is not None \
                and self._pending.type == FrameType.HELLO:
            d = f.json()
            if d.get("version") != VERSION:
                raise ProtocolError(f"server chose MKT version {d.get('version')!r}", Status.BAD_VERSION)
            chosen = d.get("auth")
            if chosen != self.offered and not (isinstance(self.offered, list)
                                               and chosen in self.offered):
                raise AuthenticationError(f"asked for auth {self.offered!r}, server answered "
                                          f"{chosen!r}")
            self.auth = str(chosen)
            self.server = d
            self._th = hashlib.sha256(self._hello + f.payload).digest()
            proof = ""
            if self.secret is not None:
                nonce_s = _unhex(d.get("nonce"), NONCE_SIZE, "HELLO_ACK nonce")
                assert self.channel.session is not None
                c2s, s2c = derive_keys(self.secret, self.channel.session, self.nonce, nonce_s, self._th)
                self.channel.install_keys(c2s, s2c, self.auth)
                proof = _proof(c2s, b"MKT1 client proof", self._th)
                self._expect_proof = _proof(s2c, b"MKT1 server proof", self._th)
            self._pending = Out(FrameType.AUTH, dump_json({"proof": proof}))
            self._tries = 1
            self._arm(now)
            return [self._pending]
        if f.type == FrameType.AUTH_OK and self._pending is not None \
                and self._pending.type == FrameType.AUTH:
            if self.secret is not None:
                got = f.json().get("proof")
                if not (f.authentic and isinstance(got, str)
                        and hmac.compare_digest(got, self._expect_proof)):
                    raise AuthenticationError("the server could not prove it knows the shared secret")
            self._pending = None
            self._finish()
            return []
        return []  # a late duplicate answer


class ServerHandshake(_Machine):
    """The responder's side of the handshake.

    Args:
        channel: A fresh responder channel.
        secret: The pre-shared secret, or None.
        insecure: Accept clients without authentication.
        peer: This server's name.
        info: Extra HELLO_ACK fields (limits, features).
        idle_timeout: Give up after this long without a frame.
        auth_methods: Tag algorithms this server accepts; it picks the client's most preferred
            one among them.
        timeout: Give up when the handshake is not done this many seconds after :meth:`start`,
            however often the client sends (a peer that trickles frames or repeats HELLO
            cannot hold the session open); None for no limit but ``idle_timeout``.

    Attributes:
        client: The client's HELLO payload.
        auth: ``"none"``, or the tag algorithm chosen (once the HELLO arrived).
    """

    def __init__(self, channel: Channel, secret: bytes | None, *, insecure: bool = False,
                 peer: str = "", info: dict[str, Any] | None = None, nonce: bytes | None = None,
                 idle_timeout: float = 30.0, auth_methods: Sequence[str] = AUTH_METHODS,
                 timeout: float | None = None) -> None:
        super().__init__(rto=1.0, max_tries=1, idle_timeout=idle_timeout)
        self.timeout = timeout
        self._until: float | None = None
        self.channel = channel
        self.secret = secret
        self.insecure = insecure
        self.auth_methods = tuple(m for m in auth_methods if m in _TAGGERS)
        self.auth = "none"
        self.peer = peer
        self.info = dict(info or {})
        self.nonce = nonce or os.urandom(NONCE_SIZE)
        self.client: dict[str, Any] = {}
        self._hello = b""
        self._ack: Out | None = None
        self._ok: Out | None = None
        self._th = b""
        self._expect = ""

    def start(self, now: float) -> list[Out]:
        """Nothing: the client speaks first (the handshake deadline starts now)."""
        self._heard(now)
        if self.timeout is not None:
            self._until = now + self.timeout
        return []

    def deadline(self) -> float | None:
        """The idle deadline, or the handshake's own deadline when that comes first."""
        dl = super().deadline()
        if dl is None or self._until is None:
            return dl
        return min(dl, self._until)

    def poll(self, now: float) -> list[Out]:
        """Check the idle timeout and the handshake deadline."""
        if self._idle(now, "waiting for the client's handshake"):
            return []
        if not self.finished and self._until is not None and now >= self._until:
            self._fail(TimeoutTransferError(f"handshake not completed within {self.timeout:g} s"))
        return []

    def handle(self, ev: Event, now: float) -> list[Out]:
        """Take a frame from the client; a failure returns the REJECT to send."""
        if isinstance(ev, Damaged):
            return []
        self._heard(now)
        try:
            return self._hello_or_auth(ev)
        except TransferError as err:
            self._fail(err)
            return [reject_out(err, ev.ref, plain=True)]

    def _hello_or_auth(self, f: Frame) -> list[Out]:
        if f.type == FrameType.HELLO:
            if self._ack is not None:
                if f.payload == self._hello:
                    return [self._ack]  # the client did not get our answer
                raise ProtocolError("a second, different HELLO in one session")
            d = f.json()
            versions = d.get("versions")
            if not isinstance(versions, list) or VERSION not in versions:
                raise ProtocolError(f"client offers MKT versions {versions!r}, this server speaks "
                                    f"{VERSION}", Status.BAD_VERSION)
            auth = self._choose(d.get("auth"))
            nonce_c = _unhex(d.get("nonce"), NONCE_SIZE, "HELLO nonce")
            self.client = d
            self._hello = bytes(f.payload)
            ack = {"version": VERSION, "nonce": self.nonce.hex(), "auth": auth, "peer": self.peer,
                   "software": SOFTWARE, **self.info}
            ack_payload = dump_json(ack)
            self._ack = Out(FrameType.HELLO_ACK, ack_payload, ref=f.ref)
            self._th = hashlib.sha256(self._hello + ack_payload).digest()
            proof = ""
            self.auth = auth
            if auth != "none":
                assert self.secret is not None and self.channel.session is not None
                c2s, s2c = derive_keys(self.secret, self.channel.session, nonce_c, self.nonce, self._th)
                self.channel.install_keys(c2s, s2c, auth)
                self._expect = _proof(c2s, b"MKT1 client proof", self._th)
                proof = _proof(s2c, b"MKT1 server proof", self._th)
            self._ok = Out(FrameType.AUTH_OK, dump_json({"proof": proof}))
            return [self._ack]
        if f.type == FrameType.AUTH and self._ack is not None:
            if self._expect:
                got = f.json().get("proof")
                if not (f.authentic and isinstance(got, str) and hmac.compare_digest(got, self._expect)):
                    raise AuthenticationError("the client's proof does not match: it uses another "
                                              "shared secret")
            assert self._ok is not None
            self._finish()
            return [self._ok]
        if f.type in (FrameType.REJECT, FrameType.CANCEL, FrameType.BYE):
            raise rejected_from(f, "client")
        raise ProtocolError(f"expected HELLO or AUTH, got {_type_name(f.type)}")

    def _choose(self, offered: Any) -> str:
        """The tag algorithm for a HELLO's ``auth`` (a list in preference order, or one string)."""
        if offered == "none":
            if not self.insecure:
                raise AuthenticationError(
                    "this server requires authentication: give the shared secret "
                    "(--secret-file or MAPKIT_SECRET)", Status.AUTH_REQUIRED)
            return "none"
        methods = [offered] if isinstance(offered, str) else offered
        if not (isinstance(methods, list) and methods and all(isinstance(m, str) for m in methods)):
            raise AuthenticationError(f"unknown auth method {offered!r}", Status.AUTH_REQUIRED)
        if self.secret is None:
            raise AuthenticationError("this server has no shared secret (it runs with "
                                      "--insecure): connect with --insecure", Status.AUTH_REQUIRED)
        for m in methods:
            if m in self.auth_methods:
                return str(m)
        raise AuthenticationError(f"no common auth method: the client offers {methods!r}, this "
                                  f"server accepts {list(self.auth_methods)!r}",
                                  Status.AUTH_REQUIRED)

    def resend(self, f: Frame) -> list[Out]:
        """After the handshake: answer a repeated AUTH (the client missed AUTH_OK)."""
        if f.type == FrameType.AUTH and self._ok is not None:
            return [self._ok]
        return []


# -- requests -----------------------------------------------------------------------------------------


class Request(_Machine):
    """A control request (GET, LIST, LOAD, PING, BYE) resent until its answer arrives.

    Args:
        type: The request's frame type.
        payload: JSON object to send.
        ref: The request number (answers carry it).
        answers: Frame types that answer it (REJECT always ends it with :class:`Rejected`).

    Attributes:
        response: The answering frame once :attr:`finished` without error.
    """

    def __init__(self, type: FrameType, payload: dict[str, Any], *, ref: int,
                 answers: Iterable[FrameType], rto: float = 1.0, max_tries: int = 5,
                 idle_timeout: float = 30.0) -> None:
        super().__init__(rto=rto, max_tries=max_tries, idle_timeout=idle_timeout)
        self.out = Out(type, dump_json(payload), ref=ref)
        self.ref = ref
        self.answers = frozenset(answers)
        self.response: Frame | None = None

    def start(self, now: float) -> list[Out]:
        """The request frame."""
        self._heard(now)
        self._tries = 1
        self._arm(now)
        return [self.out]

    def poll(self, now: float) -> list[Out]:
        """Resend when the answer is late."""
        if self.finished or self._idle(now, f"waiting for the answer to {self.out.type.name}"):
            return []
        return self._resend(now, self.out)

    def handle(self, ev: Event, now: float) -> list[Out]:
        """Take a frame; finishes on the answer."""
        if self.finished or isinstance(ev, Damaged):
            return []
        self._heard(now)
        if ev.ref != self.ref:
            return []
        if ev.type in (FrameType.REJECT, FrameType.CANCEL):
            self._fail(rejected_from(ev, "server"))
        elif ev.type in self.answers:
            self.response = ev
            self._finish()
        return []


# -- transfer -------------------------------------------------------------------------------------------


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


@dataclass
class _Flight:
    sent: float
    order: int


class Sender(_Machine):
    """Sends one file: OFFER, then DATA within a window, resending what is lost or damaged.

    Args:
        offer: The offer (identity and chunking).
        read_chunk: Returns the bytes of chunk ``index`` (exactly ``offer.chunk_len(index)``),
            or a :class:`Prepared` payload of them.
        ref: The request number (the push's own, or the GET it answers).
        window: Chunks in flight at most.
        rto: First resend timeout in seconds (doubles while nothing is acknowledged).
        max_tries: Sends of one chunk (or of OFFER/DONE) before giving up.
        idle_timeout: Give up after this long without any frame.
        announce: Send the OFFER in :meth:`start` (False when the OFFER is already out).

    Attributes:
        chunks_sent: DATA frames sent, resends included.
        chunks_resent: Resent DATA frames.
        chunks_skipped: Chunks the receiver already held (resume).
        sent_indices: Set of chunk indices sent at least once in this session.
        bytes_acked: Bytes the receiver acknowledged (progress).
        result: The VERIFIED payload, or ``{"skipped": True, ...}``.
    """

    def __init__(self, offer: Offer,
                 read_chunk: Callable[[int], bytes | bytearray | memoryview | Prepared], *,
                 ref: int = 0, window: int = 16, rto: float = 1.0, max_tries: int = 8,
                 idle_timeout: float = 30.0) -> None:
        super().__init__(rto=rto, max_tries=max_tries, idle_timeout=idle_timeout)
        self.offer = offer
        self.read_chunk = read_chunk
        self.ref = ref
        self.window = max(1, window)
        self.state = "offer"
        self.acked = bytearray(offer.chunks)
        self._acked_count = 0
        self._pending: deque[int] = deque()
        self._flight: dict[int, _Flight] = {}
        self._sends: dict[int, int] = {}
        self._order = 0
        self.chunks_sent = 0
        self.chunks_resent = 0
        self.chunks_skipped = 0
        self.sent_indices: set[int] = set()
        self.bytes_acked = 0
        self.result: dict[str, Any] = {}
        self._offer_out = Out(FrameType.OFFER, dump_json({**offer.json(), "window": self.window}), ref=ref)

    def start(self, now: float) -> list[Out]:
        """The OFFER frame."""
        self._heard(now)
        self._tries = 1
        self._arm(now)
        return [self._offer_out]

    def offer_out(self) -> Out:
        """The OFFER frame again (for a repeated GET)."""
        return self._offer_out

    def handle(self, ev: Event, now: float) -> list[Out]:
        """Take a frame from the receiver."""
        if self.finished:
            return []
        self._heard(now)
        if isinstance(ev, Damaged):
            return []
        return self._guarded(ev, now, "receiver")

    def _handle(self, f: Frame, now: float) -> list[Out]:
        t = f.type
        if f.ref != self.ref and t != FrameType.PING:
            return []
        if t == FrameType.ACCEPT and self.state == "offer":
            d = f.json()
            if d.get("skip"):
                self.result = {"skipped": True, **d}
                self._finish()
                return []
            have = decode_bitmap(d.get("have", ""), self.offer.chunks)
            w = d.get("window")
            if isinstance(w, int) and w > 0:
                self.window = min(self.window, w)
            self.acked = have
            self._acked_count = sum(have)
            self.chunks_skipped = self._acked_count
            self.bytes_acked = self._bytes_of_acked()
            self._pending = deque(i for i in range(self.offer.chunks) if not have[i]) \
                if self._acked_count else deque(range(self.offer.chunks))
            self.state = "data"
            self._timer = None
            self._tries = 0
            return self._fill(now)
        if t == FrameType.ACK and self.state in ("data", "done"):
            self._ack(f.json(), now)
            return self._fill(now)
        if t == FrameType.VERIFIED:
            self.result = f.json()
            self.bytes_acked = self.offer.size
            self._finish()
            return []
        if t == FrameType.PING:
            return [Out(FrameType.PONG, f.payload, ref=f.ref)]
        return []

    def _bytes_of_acked(self) -> int:
        n = self._acked_count * self.offer.chunk_size
        if self.offer.chunks and self.acked[-1]:
            n -= self.offer.chunk_size - self.offer.chunk_len(self.offer.chunks - 1)
        return n

    def _mark(self, i: int) -> None:
        if not self.acked[i]:
            self.acked[i] = 1
            self._acked_count += 1
            self.bytes_acked += self.offer.chunk_len(i)
        self._flight.pop(i, None)

    def _ack(self, d: dict[str, Any], now: float) -> None:
        n = self.offer.chunks
        nxt = d.get("next", 0)
        if not isinstance(nxt, int) or not 0 <= nxt <= n:
            raise ProtocolError(f"ACK next={nxt!r} outside 0..{n}")
        before = self._acked_count
        # everything below `next` is held, and each sack range
        spans = [[0, nxt]]
        for r in d.get("sack", []):
            if not (isinstance(r, list) and len(r) == 2 and isinstance(r[0], int)
                    and isinstance(r[1], int) and 0 <= r[0] <= r[1] <= n):
                raise ProtocolError(f"ACK has a bad range {r!r}")
            spans.append(r)
        acked = self.acked
        newest = -1  # send order of the newest in-flight chunk this ACK covers
        flight = self._flight
        for a, b in spans:
            j = acked.find(0, a, b)
            while j >= 0:
                fl = flight.get(j)
                if fl is not None and fl.order > newest:
                    newest = fl.order
                self._mark(j)
                j = acked.find(0, j + 1, b)
        # fast resend: chunks sent before one that arrived are lost (exact on ordered links)
        if newest >= 0:
            lost = []
            for i, fl in flight.items():
                if fl.order >= newest:
                    break
                lost.append(i)
            for i in lost:
                del flight[i]
            self._pending.extendleft(reversed(lost))
        progress = self._acked_count > before
        for i in d.get("nack", []):
            if isinstance(i, int) and 0 <= i < n and not self.acked[i] and i in self._flight:
                del self._flight[i]
                self._pending.appendleft(i)
        if progress:
            self._tries = 0
            self._timer = None

    def _send(self, i: int, now: float) -> Out:
        data = self.read_chunk(i)
        if len(data) != self.offer.chunk_len(i):
            raise LocalTransferError(f"{self.offer.name}: chunk {i} has {len(data)} bytes, expected "
                                     f"{self.offer.chunk_len(i)} (the file changed while sending?)")
        sends = self._sends.get(i, 0) + 1
        if sends > self.max_tries:
            raise TimeoutTransferError(f"chunk {i} of {self.offer.name} not acknowledged after "
                                       f"{self.max_tries} sends")
        self._sends[i] = sends
        retx = sends > 1
        self._flight.pop(i, None)
        self._order += 1
        self._flight[i] = _Flight(now, self._order)
        self.chunks_sent += 1
        if retx:
            self.chunks_resent += 1
        self.sent_indices.add(i)
        return Out(FrameType.DATA, data, ref=i, flags=Flag.RETX if retx else 0)

    def _fill(self, now: float) -> list[Out]:
        out: list[Out] = []
        while self._pending and len(self._flight) < self.window:
            i = self._pending.popleft()
            if not self.acked[i]:
                out.append(self._send(i, now))
        if out and (len(self._flight) >= self.window or not self._pending):
            last = out[-1]  # window full or nothing more to send: ask for an ACK now
            out[-1] = Out(last.type, last.payload, ref=last.ref, flags=last.flags | Flag.ACKREQ)
        if self._acked_count == self.offer.chunks and self.state == "data":
            # everything arrived: VERIFIED should follow; ask with DONE only if it is late
            self.state = "done"
            self._tries = 0
            self._arm(now)
        elif self._flight and self._timer is None:
            self._arm(now)
        return out

    def poll(self, now: float) -> list[Out]:
        """Resend OFFER, DONE or the oldest unacknowledged chunks when their time is up."""
        if self.finished or self._idle(now, f"sending {self.offer.name}"):
            return []
        try:
            return self._poll(now)
        except TransferError as err:
            return self.fail(err, self.ref)

    def _poll(self, now: float) -> list[Out]:
        if self._timer is None or now < self._timer:
            return self._fill(now) if self.state == "data" else []
        if self.state in ("offer", "done"):
            if self._tries >= self.max_tries:
                what = "OFFER" if self.state == "offer" else "DONE"
                raise TimeoutTransferError(f"no answer to {what} for {self.offer.name} after "
                                           f"{self._tries} tries")
            self._tries += 1
            self._arm(now)
            return [self._offer_out if self.state == "offer" else
                    Out(FrameType.DONE, b"{}", ref=self.ref)]
        # data: resend every chunk sent before the timer's start
        self._tries += 1
        cutoff = now - self.rto * 0.5
        stale = [i for i, fl in self._flight.items() if fl.sent <= cutoff] or list(self._flight)[:1]
        out = [self._send(i, now) for i in stale]
        if out:
            last = out[-1]
            out[-1] = Out(last.type, last.payload, ref=last.ref, flags=last.flags | Flag.ACKREQ)
        self._arm(now)
        return out + self._fill(now)


class Receiver(_Machine):
    """Receives one file: answers the OFFER, takes DATA, acknowledges, reports completion.

    The application stores each :class:`ChunkReceived` (from :meth:`pop_events`) and, on
    :class:`TransferComplete`, checks the whole file and calls :meth:`verified` or :meth:`fail`.

    Args:
        offer: The sender's offer (the application has checked name and size).
        ref: The OFFER's ref.
        have: Chunks already held (resume), byte-per-chunk, or None.
        window: Largest window the sender may use.
        ack_every: Acknowledge after this many new chunks (default: half the smaller of the
            sender's and this window). DATA with :attr:`Flag.ACKREQ` is acknowledged at once.
        idle_timeout: Give up after this long without a frame.

    Attributes:
        have: Byte-per-chunk bitmap of held chunks.
        held: Number of held chunks.
        bytes_received: Bytes held (progress).
        duplicates: Chunks received again.
        damaged: Damaged DATA frames seen.
    """

    def __init__(self, offer: Offer, *, ref: int = 0, have: bytearray | None = None,
                 window: int = 64, ack_every: int | None = None, idle_timeout: float = 30.0,
                 sender_window: int | None = None) -> None:
        super().__init__(rto=1.0, max_tries=1, idle_timeout=idle_timeout)
        self.offer = offer
        self.ref = ref
        self.have = bytearray(have) if have is not None else bytearray(offer.chunks)
        if len(self.have) != offer.chunks:
            raise ValueError("have bitmap does not match the number of chunks")
        self.held = sum(self.have)
        self.window = window
        self.ack_every = ack_every or max(1, min(window, sender_window or window) // 2)
        self._next = self.have.find(0)
        if self._next < 0:
            self._next = offer.chunks
        self._unacked = 0
        self.state = "new"
        self._final: Out | None = None
        self.duplicates = 0
        self.damaged = 0
        self.bytes_received = self.held * offer.chunk_size
        if self.held and self.have[-1]:
            self.bytes_received -= offer.chunk_size - offer.chunk_len(offer.chunks - 1)

    @property
    def complete(self) -> bool:
        """True when every chunk is held."""
        return self.held == self.offer.chunks

    def start(self, now: float) -> list[Out]:
        """Same as :meth:`accept`."""
        return self.accept(now)

    def accept(self, now: float) -> list[Out]:
        """The ACCEPT frame (with the held-chunks bitmap for resume)."""
        self._heard(now)
        self.state = "data"
        out = [self._accept_out()]
        if self.complete:
            self.state = "verify"
            self._events.append(TransferComplete(self.offer))
        return out

    def skip(self, info: dict[str, Any]) -> list[Out]:
        """Decline the data because this side already has the file (ACCEPT with ``skip``)."""
        self._finish()
        return [Out(FrameType.ACCEPT, dump_json({"skip": True, **info}), ref=self.ref)]

    def _accept_out(self) -> Out:
        return Out(FrameType.ACCEPT, dump_json({"have": encode_bitmap(self.have), "window": self.window}),
                   ref=self.ref)

    def _ack_out(self, nack: list[int] | None = None) -> Out:
        self._unacked = 0
        d: dict[str, Any] = {"next": self._next,
                             "sack": ranges_from_bitmap(self.have, self._next, 32)}
        if nack:
            d["nack"] = nack
        return Out(FrameType.ACK, dump_json(d), ref=self.ref)

    def handle(self, ev: Event, now: float) -> list[Out]:
        """Take a frame from the sender."""
        self._heard(now)
        if isinstance(ev, Damaged):
            if ev.type == FrameType.DATA and self.state == "data" and 0 <= ev.ref < self.offer.chunks \
                    and not self.have[ev.ref]:
                self.damaged += 1
                return [self._ack_out([ev.ref])]
            return []
        if self.finished:
            if ev.type in (FrameType.DONE, FrameType.DATA, FrameType.OFFER) and self._final is not None:
                return [self._final]
            return []
        return self._guarded(ev, now, "sender")

    def _handle(self, f: Frame, now: float) -> list[Out]:
        t = f.type
        if t == FrameType.PING:
            return [Out(FrameType.PONG, f.payload, ref=f.ref)]
        if f.ref != self.ref and t != FrameType.DATA:
            return []
        if t == FrameType.OFFER:
            return [self._accept_out()] if self.state != "new" else []
        if t == FrameType.DATA:
            return self._data(f)
        if t == FrameType.DONE:
            return [] if self.state == "verify" else [self._ack_out()]
        return []

    def _data(self, f: Frame) -> list[Out]:
        i = f.ref
        if self.state == "new":
            raise ProtocolError("DATA before ACCEPT")
        if not 0 <= i < self.offer.chunks:
            raise ProtocolError(f"DATA for chunk {i}, the file has {self.offer.chunks}")
        if len(f.payload) != self.offer.chunk_len(i):
            raise ProtocolError(f"DATA for chunk {i} has {len(f.payload)} bytes, expected "
                                f"{self.offer.chunk_len(i)}")
        if self.have[i]:
            self.duplicates += 1
            return [self._ack_out()] if self.state == "data" else []
        if self.state != "data":
            return []
        self.have[i] = 1
        self.held += 1
        self.bytes_received += len(f.payload)
        self._events.append(ChunkReceived(i, i * self.offer.chunk_size, f.payload, f.crc))
        in_order = i == self._next
        if in_order:
            nxt = self.have.find(0, i)
            self._next = self.offer.chunks if nxt < 0 else nxt
        self._unacked += 1
        if self.complete:
            self.state = "verify"
            self._events.append(TransferComplete(self.offer))
            return [self._ack_out()]
        if self._unacked >= self.ack_every or not in_order or f.flags & Flag.ACKREQ:
            return [self._ack_out()]
        return []

    def verified(self, info: dict[str, Any], now: float) -> list[Out]:
        """The application checked and published the file: send VERIFIED with ``info``."""
        self._final = Out(FrameType.VERIFIED, dump_json(info), ref=self.ref)
        self._finish()
        return [self._final]

    def fail(self, err: TransferError, ref: int | None = None) -> list[Out]:
        """Give up (file check failed, disk full...): the CANCEL to send, kept for repeats."""
        if self.finished:
            return []
        out = super().fail(err, self.ref if ref is None else ref)
        self._final = out[0] if out else None
        return out

    def poll(self, now: float) -> list[Out]:
        """Check the idle timeout (the receiver never resends on its own)."""
        if self.state != "verify" and self._idle(now, f"receiving {self.offer.name}"):
            assert self.error is not None
            self._final = reject_out(self.error, self.ref, cancel=True)
            return [self._final]
        return []
