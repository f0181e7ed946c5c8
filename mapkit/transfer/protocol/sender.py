"""The sending state machine: OFFER, then DATA within a window, resending what is lost or
damaged."""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from mapkit.errors import LocalTransferError, TransferError
from mapkit.transfer.protocol.bitmaps import decode_bitmap
from mapkit.transfer.protocol.constants import Flag, FrameType
from mapkit.transfer.protocol.errors import ProtocolError, TimeoutTransferError
from mapkit.transfer.protocol.events import Damaged, Event, Frame, Out
from mapkit.transfer.protocol.frames import Prepared, dump_json
from mapkit.transfer.protocol.machine import _Machine
from mapkit.transfer.protocol.offer import Offer

__all__ = ["Sender"]


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

    def __init__(
        self,
        offer: Offer,
        read_chunk: Callable[[int], bytes | bytearray | memoryview | Prepared],
        *,
        ref: int = 0,
        window: int = 16,
        rto: float = 1.0,
        max_tries: int = 8,
        idle_timeout: float = 30.0,
    ) -> None:
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
        self._offer_out = Out(
            FrameType.OFFER, dump_json({**offer.json(), "window": self.window}), ref=ref
        )

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
            self._pending = (
                deque(i for i in range(self.offer.chunks) if not have[i])
                if self._acked_count
                else deque(range(self.offer.chunks))
            )
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
            if not (
                isinstance(r, list)
                and len(r) == 2
                and isinstance(r[0], int)
                and isinstance(r[1], int)
                and 0 <= r[0] <= r[1] <= n
            ):
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
            raise LocalTransferError(
                f"{self.offer.name}: chunk {i} has {len(data)} bytes, expected "
                f"{self.offer.chunk_len(i)} (the file changed while sending?)"
            )
        sends = self._sends.get(i, 0) + 1
        if sends > self.max_tries:
            raise TimeoutTransferError(
                f"chunk {i} of {self.offer.name} not acknowledged after {self.max_tries} sends"
            )
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
                raise TimeoutTransferError(
                    f"no answer to {what} for {self.offer.name} after {self._tries} tries"
                )
            self._tries += 1
            self._arm(now)
            return [
                self._offer_out
                if self.state == "offer"
                else Out(FrameType.DONE, b"{}", ref=self.ref)
            ]
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
