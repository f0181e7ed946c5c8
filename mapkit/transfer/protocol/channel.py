"""Reading frames: the :class:`Channel` that numbers, tags, checks and decodes frames, and the
buffer pool it reads into."""

from __future__ import annotations

import hmac
import sys
import zlib
from collections.abc import Callable

from mapkit.errors import LocalTransferError
from mapkit.transfer.protocol.constants import (
    DEFAULT_MAX_PAYLOAD,
    HEADER,
    HEADER_SIZE,
    MAC_HEADER,
    MAGIC,
    MAX_CONTROL_PAYLOAD,
    TAG_SIZE,
    VERSION,
    Flag,
    FrameType,
    Status,
)
from mapkit.transfer.protocol.errors import AuthenticationError, ProtocolError, ReplayError
from mapkit.transfer.protocol.events import Damaged, Event, Frame, Out
from mapkit.transfer.protocol.frames import (
    _TAGGERS,
    Prepared,
    _Bytes,
    _type_name,
    encode_frame,
    prepare_payload,
)

__all__ = ["BufferPool", "Channel", "crc32_strip"]


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
        self.stats = {
            "frames_in": 0,
            "frames_out": 0,
            "damaged": 0,
            "garbage": 0,
            "duplicates": 0,
            "foreign": 0,
            "forged": 0,
        }

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
        return encode_frame(
            out.type,
            out.payload,
            session=self.session,
            seq=self._seq,
            ref=out.ref,
            flags=out.flags,
            key=key,
            auth=self.auth,
        )

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
            body[self._body_fill : self._body_fill + k] = data[:k]
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
                n = recv(view[self._body_fill :])
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
            if len(buf) - pos >= 4 and buf[pos : pos + 4] != MAGIC:
                self._resync(pos + 1)
                return _AGAIN
            return None
        if buf[pos : pos + 4] != MAGIC:
            self._resync(pos + 1)
            return _AGAIN
        (_, version, ftype, flags, session, seq, ref, length, body_crc, head_crc) = (
            HEADER.unpack_from(buf, pos)
        )
        with memoryview(buf) as view:
            head_ok = zlib.crc32(view[pos : pos + 32]) == head_crc
        if not head_ok:
            self._resync(pos + 1)
            return _AGAIN
        if version != VERSION:
            raise ProtocolError(
                f"peer speaks MKT version {version}, this side only {VERSION}", Status.BAD_VERSION
            )
        limit = self.max_payload if ftype == FrameType.DATA else MAX_CONTROL_PAYLOAD
        if length > max(limit, MAX_CONTROL_PAYLOAD):
            raise ProtocolError(
                f"{_type_name(ftype)} frame of {length} bytes exceeds the limit of {limit} bytes",
                Status.TOO_LARGE,
            )
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
                body[:k] = view[start : start + k]
            self._body, self._body_fill = body, k
            self._body_head = (head, ftype, flags, session, seq, ref, body_crc, tagged)
            self._pos = start + k
            return self._finish_body()
        with memoryview(buf) as view:
            payload = bytes(view[start : start + length])
            tag = bytes(view[start + length : pos + total])
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
        tag = bytes(self._buf[self._pos : self._pos + n])
        self._pos += n
        self._body, self._body_head, self._body_fill = None, None, 0
        return self._check(head, ftype, flags, session, seq, ref, body_crc, tagged, body, tag)

    def _check(
        self,
        head: bytes,
        ftype: int,
        flags: int,
        session: int,
        seq: int,
        ref: int,
        body_crc: int,
        tagged: bool,
        payload: bytes | bytearray,
        tag: bytes,
    ) -> Event | object:
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
                raise ProtocolError(
                    f"frame for session {session:016x} on session {self.session:016x}"
                )
            self.stats["foreign"] += 1
            return _AGAIN
        # authentication
        authentic = False
        if key is not None:
            if tag_ok or (
                tagged
                and len(payload) < _TAG_FIRST
                and hmac.compare_digest(self._tagger(key, head[:MAC_HEADER], payload), tag)
            ):
                authentic = True
            elif ftype == FrameType.REJECT and not tagged:
                authentic = False  # an untagged refusal: delivered, marked as not authentic
            else:
                what = "has no tag" if not tagged else "has a wrong tag"
                if self.ordered or ftype in (FrameType.AUTH, FrameType.AUTH_OK):
                    raise AuthenticationError(
                        f"{_type_name(ftype)} frame (seq {seq}) {what}: "
                        "altered, forged, or sent with another secret"
                    )
                self.stats["forged"] += 1
                return _AGAIN
        # replay
        if not self._replay_ok(seq):
            if self.ordered:
                raise ReplayError(
                    f"replayed frame: {_type_name(ftype)} seq {seq} after seq {self._highest}"
                )
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
