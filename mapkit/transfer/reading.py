"""Reading files to send: whole-file digests, a chunk reader over a file descriptor, and the
:class:`PreparedReader` that reads and tags big files ahead of the sender."""

from __future__ import annotations

import hashlib
import os
import threading
import zlib
from collections.abc import Callable
from typing import Any

from mapkit.errors import LocalTransferError
from mapkit.transfer.protocol import (
    BufferPool,
    Offer,
    Prepared,
)

__all__ = ["PreparedReader", "chunk_reader", "file_digests"]


READ_BLOCK = 1 << 20
PREPARE_FROM = 4 << 20  # files from this size are sent with a PreparedReader


def file_digests(fd: int, size: int, *, md5: bool = True) -> tuple[str, str | None]:
    """SHA-256 (and MD5) of the first ``size`` bytes of an open file, read in 1 MiB blocks."""
    sha = hashlib.sha256()
    m = hashlib.md5() if md5 else None
    buf = bytearray(min(READ_BLOCK, size))
    view = memoryview(buf)
    off = 0
    while off < size:
        n = _preadv(fd, view[: min(READ_BLOCK, size - off)], off)
        if not n:
            raise LocalTransferError(f"file shrank while reading it (at byte {off} of {size})")
        sha.update(view[:n])
        if m is not None:
            m.update(view[:n])
        off += n
    return sha.hexdigest(), m.hexdigest() if m is not None else None


def _preadv(fd: int, buf: memoryview | bytearray, offset: int) -> int:
    """Read into ``buf`` at ``offset`` (one ``preadv``); returns the byte count."""
    if hasattr(os, "preadv"):
        return os.preadv(fd, [buf], offset)
    data = os.pread(fd, len(buf), offset)  # pragma: no cover - platforms without preadv
    buf[: len(data)] = data
    return len(data)


def chunk_reader(fd: int, offer: Offer) -> Callable[[int], bytes | bytearray]:
    """The ``read_chunk`` of a :class:`~mapkit.transfer.protocol.Sender` for an open file:
    chunk ``i`` read into a pooled buffer (see :class:`~mapkit.transfer.protocol.BufferPool`).

    A short read (the file shrank) returns fewer bytes, which the sender reports.
    """
    pool = BufferPool()

    def read(i: int) -> bytes | bytearray:
        n = offer.chunk_len(i)
        buf = pool.get(n)
        got = _preadv(fd, buf, i * offer.chunk_size)
        return buf if got == n else bytes(buf[:got])

    return read


class PreparedReader:
    """The ``read_chunk`` of a :class:`~mapkit.transfer.protocol.Sender` that does the per-byte
    work of each chunk's frame ahead, in a background thread: the CRC-32 and, for ``blake2b``
    tags, the keyed BLAKE2b of the payload (see :class:`~mapkit.transfer.protocol.Prepared`).

    Started while the sender hashes the file for its offer, the thread uses the second core;
    started with the transfer, it keeps ahead of the sending loop. A chunk is read again when
    it is sent; if its CRC-32 changed meanwhile (the file is being modified), the frame's tag is
    computed from the bytes actually sent, and the receiver's SHA-256 check reports the change.

    Args:
        fd: The open file (the reader works on a duplicate of it, closed by :meth:`close`).
        size: Its size in bytes.
        chunk_size: Bytes per chunk.
        prepare: :meth:`~mapkit.transfer.protocol.Channel.preparer` of the session's channel.

    Attributes:
        skip: Chunks the background pass may leave out (those the receiver already holds, for
            a resume): a function of the chunk index, or None.
    """

    def __init__(
        self,
        fd: int,
        size: int,
        chunk_size: int,
        prepare: Callable[[bytes | bytearray | memoryview], Prepared],
    ) -> None:
        self.fd, self.size, self.chunk_size, self.prepare = os.dup(fd), size, chunk_size, prepare
        self.skip: Callable[[int], Any] | None = None
        self.chunks = -(-size // chunk_size)
        self._done: list[Prepared | None] = []
        self._cond = threading.Condition()
        self._stop = False
        self._running = False
        self._pool = BufferPool()
        self._thread = threading.Thread(target=self._run, daemon=True, name="mapkit-prepare")

    @classmethod
    def for_file(
        cls,
        fd: int,
        size: int,
        chunk_size: int,
        prepare: Callable[[bytes | bytearray | memoryview], Prepared],
    ) -> PreparedReader | None:
        """A reader for a file worth it: from ``PREPARE_FROM`` bytes (4 MiB) and at most 4096
        chunks (the pass keeps a small state per chunk); else None."""
        if size < PREPARE_FROM or -(-size // chunk_size) > 4096:
            return None
        return cls(fd, size, chunk_size, prepare)

    def start(self) -> PreparedReader:
        """Start the background pass (once)."""
        if not self._running and not self._stop:
            self._running = True
            self._thread.start()
        return self

    def _run(self) -> None:
        buf = bytearray(min(self.chunk_size, self.size))
        view = memoryview(buf)
        try:
            for i in range(self.chunks):
                if self._stop:
                    return
                skip = self.skip
                p = None
                if skip is None or not skip(i):
                    n = min(self.chunk_size, self.size - i * self.chunk_size)
                    if _preadv(self.fd, view[:n], i * self.chunk_size) != n:
                        return  # the file shrank: the sender reports it
                    p = self.prepare(view[:n])
                    p.data = b""  # keep the CRC and the state, not the bytes
                with self._cond:
                    self._done.append(p)
                    self._cond.notify_all()
        except OSError:
            return  # the sender reads again and reports errors itself
        finally:
            with self._cond:
                self._running = False
                self._cond.notify_all()

    def __call__(self, i: int) -> bytes | bytearray | Prepared:
        n = min(self.chunk_size, self.size - i * self.chunk_size)
        buf = self._pool.get(n)
        got = _preadv(self.fd, buf, i * self.chunk_size)
        if got != n:
            return bytes(buf[:got])
        with self._cond:
            while len(self._done) <= i and self._running:
                self._cond.wait()
            ahead = self._done[i] if i < len(self._done) else None
        crc = zlib.crc32(buf)
        prepared = ahead.with_data(buf, crc) if ahead is not None else None
        return prepared if prepared is not None else Prepared(buf, crc)

    def close(self) -> None:
        """Stop the background pass and close the file (idempotent)."""
        self._stop = True
        if self._thread.is_alive() and self._thread is not threading.current_thread():
            self._thread.join()
        if self.fd >= 0:
            os.close(self.fd)
            self.fd = -1
