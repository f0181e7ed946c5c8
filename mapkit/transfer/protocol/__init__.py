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

from mapkit.transfer.protocol.bitmaps import (
    bitmap_from_ranges,
    decode_bitmap,
    encode_bitmap,
    ranges_from_bitmap,
)
from mapkit.transfer.protocol.channel import (
    BufferPool,
    Channel,
    crc32_strip as crc32_strip,
)
from mapkit.transfer.protocol.constants import (
    AUTH_METHODS,
    DEFAULT_CHUNK_SIZE,
    DEFAULT_MAX_PAYLOAD as DEFAULT_MAX_PAYLOAD,
    DEFAULT_PORT,
    HEADER as HEADER,
    HEADER_SIZE,
    MAC_HEADER as MAC_HEADER,
    MAGIC,
    MAX_CHUNK_SIZE,
    MAX_CHUNKS as MAX_CHUNKS,
    MAX_CONTROL_PAYLOAD as MAX_CONTROL_PAYLOAD,
    MAX_HANDSHAKE_PAYLOAD as MAX_HANDSHAKE_PAYLOAD,
    MAX_REFUSAL_PAYLOAD as MAX_REFUSAL_PAYLOAD,
    MIN_SECRET as MIN_SECRET,
    NONCE_SIZE as NONCE_SIZE,
    SOFTWARE as SOFTWARE,
    TAG_SIZE,
    VERSION,
    Flag,
    FrameType,
    Status,
)
from mapkit.transfer.protocol.errors import (
    AuthenticationError,
    ProtocolError,
    Rejected,
    ReplayError,
    TimeoutTransferError as TimeoutTransferError,
    status_of as status_of,
)
from mapkit.transfer.protocol.events import (
    ChunkReceived,
    Damaged,
    Event as Event,
    Frame,
    Out,
    TransferComplete,
)
from mapkit.transfer.protocol.frames import (
    Prepared,
    dump_json as dump_json,
    encode_frame,
    parse_json as parse_json,
    prepare_payload,
)
from mapkit.transfer.protocol.handshake import (
    ClientHandshake,
    ServerHandshake,
)
from mapkit.transfer.protocol.keys import (
    derive_keys,
    load_secret,
)
from mapkit.transfer.protocol.machine import (
    reject_out as reject_out,
    rejected_from as rejected_from,
)
from mapkit.transfer.protocol.offer import (
    Offer,
    kind_of as kind_of,
)
from mapkit.transfer.protocol.receiver import (
    Receiver,
)
from mapkit.transfer.protocol.request import (
    Request,
)
from mapkit.transfer.protocol.sender import (
    Sender,
)

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
