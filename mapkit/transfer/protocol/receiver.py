"""The receiving state machine: answers the OFFER, takes DATA, acknowledges, reports completion."""

from __future__ import annotations

from typing import Any

from mapkit.errors import TransferError
from mapkit.transfer.protocol.bitmaps import encode_bitmap, ranges_from_bitmap
from mapkit.transfer.protocol.constants import Flag, FrameType
from mapkit.transfer.protocol.errors import ProtocolError
from mapkit.transfer.protocol.events import (
    ChunkReceived,
    Damaged,
    Event,
    Frame,
    Out,
    TransferComplete,
)
from mapkit.transfer.protocol.frames import dump_json
from mapkit.transfer.protocol.machine import _Machine, reject_out
from mapkit.transfer.protocol.offer import Offer

__all__ = ["Receiver"]


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

    def __init__(
        self,
        offer: Offer,
        *,
        ref: int = 0,
        have: bytearray | None = None,
        window: int = 64,
        ack_every: int | None = None,
        idle_timeout: float = 30.0,
        sender_window: int | None = None,
    ) -> None:
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
        return Out(
            FrameType.ACCEPT,
            dump_json({"have": encode_bitmap(self.have), "window": self.window}),
            ref=self.ref,
        )

    def _ack_out(self, nack: list[int] | None = None) -> Out:
        self._unacked = 0
        d: dict[str, Any] = {
            "next": self._next,
            "sack": ranges_from_bitmap(self.have, self._next, 32),
        }
        if nack:
            d["nack"] = nack
        return Out(FrameType.ACK, dump_json(d), ref=self.ref)

    def handle(self, ev: Event, now: float) -> list[Out]:
        """Take a frame from the sender."""
        self._heard(now)
        if isinstance(ev, Damaged):
            if (
                ev.type == FrameType.DATA
                and self.state == "data"
                and 0 <= ev.ref < self.offer.chunks
                and not self.have[ev.ref]
            ):
                self.damaged += 1
                return [self._ack_out([ev.ref])]
            return []
        if self.finished:
            if (
                ev.type in (FrameType.DONE, FrameType.DATA, FrameType.OFFER)
                and self._final is not None
            ):
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
            raise ProtocolError(
                f"DATA for chunk {i} has {len(f.payload)} bytes, expected {self.offer.chunk_len(i)}"
            )
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
