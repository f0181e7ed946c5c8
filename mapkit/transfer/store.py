"""Where received files go: a temp file beside the target, a resume journal, an atomic publish.

An incoming file ``NAME`` in folder ``DIR`` is written to ``DIR/.NAME.mkpart`` at each chunk's
offset; ``DIR/.NAME.mkpart.json`` (the journal) records which chunks are on disk and their CRC-32,
and is rewritten (atomically, after an fsync of the temp file) at most every
``checkpoint_interval`` seconds and when a session ends. A later transfer of the same file
(same SHA-256, size and chunk size) picks up the journal, re-checks the CRC of every chunk it
claims, and asks only for the rest. When every chunk is there the temp file is fsynced, its
SHA-256 compared with the offer, the content checked (a ``.map`` must parse), and only then
renamed over ``DIR/NAME`` (then the folder is fsynced). The target is never partially written;
a file that fails a check is deleted and the old target stays.

One writer per name: the temp file is locked (``flock``), so a second session, in this process or
another, is refused with :attr:`~mapkit.transfer.protocol.Status.BUSY`.
"""

from __future__ import annotations

import array
import base64
import contextlib
import errno
import fcntl
import hashlib
import json
import logging
import os
import queue
import threading
import time
import zlib
from collections.abc import Callable
from typing import Any

from mapkit._atomic import atomic_write, fsync_dir
from mapkit.errors import ChecksumError, LocalTransferError, TransferError
from mapkit.transfer.protocol import (
    ChunkReceived,
    Offer,
    Out,
    Receiver,
    Status,
    TransferComplete,
    decode_bitmap,
    encode_bitmap,
)
from mapkit.transfer.reading import (
    PREPARE_FROM as PREPARE_FROM,
    READ_BLOCK as READ_BLOCK,
    PreparedReader,
    chunk_reader,
    file_digests,
)

__all__ = [
    "PartialFile",
    "PreparedReader",
    "StoreChecksumError",
    "StoreError",
    "check_name",
    "chunk_reader",
    "expire_partials",
    "file_digests",
    "partial_paths",
]

log = logging.getLogger(__name__)

JOURNAL_VERSION = 1
THREADS_FROM = 8 << 20  # files from this size are written and hashed in background threads

# Indirections so tests can inject faults (a full disk) or watch the order of writes and
# fsyncs without touching the real os module.
_pwrite = os.pwrite
_fsync = os.fsync


def _read_umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


_UMASK = _read_umask()  # read once, at import: os.umask is process-wide, not thread-safe


class StoreError(LocalTransferError):
    """A destination could not be written or a received file failed its checks.

    Attributes:
        status: The :class:`~mapkit.transfer.protocol.Status` to report to the peer.
    """

    def __init__(self, message: str, status: Status) -> None:
        super().__init__(message)
        self.status = status


class StoreChecksumError(ChecksumError):
    """The assembled file's SHA-256 (or MD5) is not the offered one."""

    def __init__(self, message: str, status: Status = Status.HASH_MISMATCH) -> None:
        super().__init__(message)
        self.status = status


def partial_paths(folder: str, name: str) -> tuple[str, str]:
    """``(temp file, journal)`` paths for an incoming ``name`` in ``folder``."""
    temp = os.path.join(folder, f".{name}.mkpart")
    return temp, temp + ".json"


def _os_error(err: OSError, what: str) -> StoreError:
    if err.errno in (errno.ENOSPC, errno.EDQUOT):
        return StoreError(f"{what}: no space left on the device", Status.NO_SPACE)
    return StoreError(f"{what}: {err.strerror or err}", Status.IO_ERROR)


class PartialFile:
    """The destination of one incoming file (see the module docstring).

    Use :meth:`open`; then :meth:`write` each chunk, :meth:`finalize` at the end, or
    :meth:`close` (keeping the partial data for a resume) on failure.

    Attributes:
        target: The final path.
        offer: The offer being received.
        have: Byte-per-chunk bitmap of chunks on disk.
        resumed: Chunks found on disk at open (journal of an earlier, interrupted transfer).
    """

    def __init__(
        self,
        folder: str,
        name: str,
        offer: Offer,
        fd: int,
        have: bytearray,
        crcs: array.array[int],
        *,
        checkpoint_interval: float,
        validate: Callable[[str], dict[str, Any]] | None,
    ) -> None:
        self.folder = folder
        self.name = name
        self.target = os.path.join(folder, name)
        self.temp, self.journal = partial_paths(folder, name)
        self.offer = offer
        self.have = have
        self.crcs = crcs
        self.resumed = sum(have)
        self.checkpoint_interval = checkpoint_interval
        self.validate = validate
        self._fd: int | None = fd
        self._hasher = hashlib.sha256()
        self._hashed = 0  # chunks fed to the hasher, in order
        self._dirty = False
        self._last_checkpoint = time.monotonic()
        self._queues: list[queue.Queue[Any]] = []
        self._threads: list[threading.Thread] = []
        self._stop = threading.Event()
        self._ck_lock = threading.Lock()
        self._error: BaseException | None = None

    # opening ---------------------------------------------------------------------------------
    @classmethod
    def open(
        cls,
        folder: str,
        name: str,
        offer: Offer,
        *,
        checkpoint_interval: float = 0.5,
        validate: Callable[[str], dict[str, Any]] | None = None,
        reserve: int = 1 << 20,
    ) -> PartialFile:
        """Open (or resume) the destination for ``offer`` as ``folder/name``.

        Args:
            folder: Destination folder (must exist).
            name: Plain file name (already checked by the caller).
            offer: The offer.
            checkpoint_interval: Seconds between journal updates.
            validate: Called with the temp file's path before publishing; returns extra info
                (e.g. ``{"md5": ...}``) or raises (e.g. :class:`~mapkit.errors.MapFormatError`).
            reserve: Bytes to leave free on the device beyond the file.

        Returns:
            The open destination, its ``have`` bitmap filled from a matching journal.

        Raises:
            StoreError: ``BUSY`` when another session writes this name, ``NO_SPACE`` when the
                file does not fit, ``IO_ERROR`` for other file-system errors.
        """
        temp, journal = partial_paths(folder, name)
        try:
            fd = os.open(
                temp,
                os.O_RDWR | os.O_CREAT | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_CLOEXEC", 0),
                0o600,
            )
        except OSError as err:
            raise _os_error(err, f"{name}: cannot create the temp file") from err
        try:
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError as err:
                raise StoreError(
                    f"{name} is being written by another client; try again when it is done",
                    Status.BUSY,
                ) from err
            have, crcs = cls._load_journal(fd, journal, offer)
            self = cls(
                folder,
                name,
                offer,
                fd,
                have,
                crcs,
                checkpoint_interval=checkpoint_interval,
                validate=validate,
            )
        except BaseException:
            os.close(fd)
            raise
        try:
            if self.resumed:
                self._verify_held()
            else:
                self._prepare(reserve)  # discards the temp file itself on failure
        except BaseException:
            self._close_fd()
            raise
        return self

    @staticmethod
    def _load_journal(fd: int, journal: str, offer: Offer) -> tuple[bytearray, array.array[int]]:
        n = offer.chunks
        empty = bytearray(n), array.array("I", bytes(4 * n))
        try:
            with open(journal, encoding="utf-8") as fh:
                j = json.load(fh)
        except (OSError, ValueError):
            return empty
        same = (
            isinstance(j, dict)
            and j.get("version") == JOURNAL_VERSION
            and j.get("sha256") == offer.sha256
            and j.get("size") == offer.size
            and j.get("chunk_size") == offer.chunk_size
        )
        if not same or os.fstat(fd).st_size != offer.size:
            return empty
        try:
            have = decode_bitmap(j.get("have", ""), n)
            crcs = array.array("I")
            crcs.frombytes(base64.b64decode(j.get("crc", "")))
            if len(crcs) != n:
                return empty
            if crcs.itemsize != 4:  # pragma: no cover - exotic platforms
                return empty
        except Exception:  # a damaged journal only costs a full transfer
            return empty
        return have, crcs

    def _prepare(self, reserve: int) -> None:
        assert self._fd is not None
        size = self.offer.size
        try:
            os.ftruncate(self._fd, 0)
            with contextlib.suppress(FileNotFoundError):
                os.unlink(self.journal)
            st = os.statvfs(self.folder)
            free = st.f_bavail * st.f_frsize
            if size + reserve > free:
                raise StoreError(
                    f"{self.name}: no space: {size} bytes needed, {free} free", Status.NO_SPACE
                )
            # sparse: blocks are allocated as chunks arrive, so an offer cut after 1 MiB holds
            # 1 MiB of disk, not its whole size (the check above, with the caller's ledger of
            # other transfers in `reserve`, keeps concurrent offers from overcommitting)
            os.ftruncate(self._fd, size)
        except OSError as err:
            self._discard()
            raise _os_error(err, f"{self.name}: cannot reserve {size} bytes") from err
        except StoreError:
            self._discard()
            raise

    def _verify_held(self) -> None:
        """Re-check the CRC of every chunk the journal claims; forget the ones that differ."""
        assert self._fd is not None
        dropped = 0
        i = self.have.find(1)
        while i >= 0:
            data = os.pread(self._fd, self.offer.chunk_len(i), i * self.offer.chunk_size)
            if zlib.crc32(data) != self.crcs[i]:
                self.have[i] = 0
                dropped += 1
            elif i == self._hashed:
                self._hasher.update(data)
                self._hashed += 1
            i = self.have.find(1, i + 1)
        self.resumed = sum(self.have)
        if dropped:
            log.warning(
                "%s: %d chunks of the partial file failed their CRC and will be fetched again",
                self.name,
                dropped,
            )

    @property
    def outstanding(self) -> int:
        """Bytes of the file not written yet (what it may still take of the disk)."""
        n = self.have.count(1)
        if not n:
            return self.offer.size
        written = n * self.offer.chunk_size
        if self.have[-1]:
            written -= self.offer.chunk_size - self.offer.chunk_len(self.offer.chunks - 1)
        return max(0, self.offer.size - written)

    @property
    def is_open(self) -> bool:
        """True until the file was published, kept or discarded."""
        return self._fd is not None

    # writing -----------------------------------------------------------------------------------
    def start_writer(self, depth: int = 8, *, min_size: int | None = None) -> None:
        """Work in background threads from now on, so that the network (the caller's thread),
        the disk writes, the SHA-256 and the fsyncs overlap: one thread writes chunks, one hashes
        them, one checkpoints (fsync, then journal) every ``checkpoint_interval`` seconds.
        :meth:`write` then only queues; errors come out of the next call.

        Args:
            depth: Chunks queued per thread at most (then :meth:`write` waits).
            min_size: Stay in the caller's thread when less than this many bytes are still to
                come (default ``THREADS_FROM``, 8 MiB): for a small file, handing chunks to
                threads costs more than it saves.
        """
        todo = self.offer.size - self.resumed * self.offer.chunk_size
        if not self._threads and todo >= (THREADS_FROM if min_size is None else min_size):
            self._queues = [queue.Queue(depth), queue.Queue(depth)]
            self._stop.clear()
            jobs: list[tuple[Callable[..., None], tuple[Any, ...], str]] = [
                (self._work, (self._queues[0], self._write_now), "write"),
                (self._work, (self._queues[1], self._hash_now), "hash"),
                (self._sync_loop, (), "sync"),
            ]
            for target, args, what in jobs:
                t = threading.Thread(
                    target=target, args=args, daemon=True, name=f"mapkit-{what}-{self.name}"
                )
                t.start()
                self._threads.append(t)

    def _work(self, q: queue.Queue[Any], job: Callable[..., None]) -> None:
        while True:
            item = q.get()
            try:
                if item is None:
                    return
                if self._error is None:
                    job(*item)
            except BaseException as err:
                self._error = err
            finally:
                q.task_done()

    def _sync_loop(self) -> None:
        while not self._stop.wait(self.checkpoint_interval):
            if self._error is None:
                try:
                    self.checkpoint()
                except BaseException as err:
                    self._error = err

    def flush(self) -> None:
        """Wait until queued chunks are written and hashed.

        Raises:
            StoreError: A background thread failed.
        """
        for q in self._queues:
            q.join()
        if self._error is not None:
            err, self._error = self._error, None
            raise err

    def _stop_writer(self) -> None:
        self._stop.set()
        for q in self._queues:
            q.put(None)
        for t in self._threads:
            if t is not threading.current_thread():
                t.join()
        self._queues, self._threads = [], []

    def write(
        self, index: int, data: bytes | bytearray | memoryview, crc: int | None = None
    ) -> None:
        """Store chunk ``index`` (``crc``: its CRC-32 if already known).

        Raises:
            StoreError: ``NO_SPACE`` or ``IO_ERROR`` (with background threads: of an earlier chunk).
        """
        if self._error is not None:
            self.flush()
        if self._queues:
            self._queues[0].put((index, data, crc))
            self._queues[1].put((index, data))
        else:
            self._write_now(index, data, crc)
            self._hash_now(index, data)
            if time.monotonic() - self._last_checkpoint >= self.checkpoint_interval:
                self.checkpoint()

    def _hash_now(self, index: int, data: bytes | bytearray | memoryview) -> None:
        """Hash a chunk that continues the in-order prefix, then the chunks after it that are
        already on disk (they arrived ahead of it); others wait for their turn."""
        if index != self._hashed:
            return
        self._hasher.update(data)
        self._hashed += 1
        self._catch_up()

    def _write_now(self, index: int, data: bytes | bytearray | memoryview, crc: int | None) -> None:
        assert self._fd is not None
        off = index * self.offer.chunk_size
        try:
            mv = memoryview(data)
            while mv:
                n = _pwrite(self._fd, mv, off)
                mv, off = mv[n:], off + n
        except OSError as err:
            raise _os_error(err, f"writing {self.name}") from err
        # the CRC first, then the bit: whoever sees the bit (checkpoint, hasher) sees both
        self.crcs[index] = zlib.crc32(data) if crc is None else crc
        self.have[index] = 1
        self._dirty = True

    def _catch_up(self) -> None:
        """Hash, in order, chunks already on disk that arrived ahead of the hash cursor."""
        assert self._fd is not None
        n = self.offer.chunks
        while self._hashed < n and self.have[self._hashed]:
            i = self._hashed
            self._hasher.update(
                os.pread(self._fd, self.offer.chunk_len(i), i * self.offer.chunk_size)
            )
            self._hashed += 1

    def checkpoint(self) -> None:
        """Make the chunks written so far durable, then record them in the journal.

        The list of chunks is taken before the fsync, so the journal never claims a chunk
        whose data is not on disk.

        Raises:
            StoreError: ``NO_SPACE`` or ``IO_ERROR``.
        """
        with self._ck_lock:
            if not self._dirty or self._fd is None:
                return
            self._dirty = False
            have = bytes(self.have)  # chunks written so far (their CRCs were set before)
            crcs = self.crcs.tobytes()
            try:
                _fsync(self._fd)
                j = {
                    "version": JOURNAL_VERSION,
                    "name": self.name,
                    "size": self.offer.size,
                    "sha256": self.offer.sha256,
                    "chunk_size": self.offer.chunk_size,
                    "have": encode_bitmap(have),
                    "crc": base64.b64encode(crcs).decode("ascii"),
                }
                atomic_write(self.journal, json.dumps(j).encode("utf-8"))
            except OSError as err:
                self._dirty = True
                raise _os_error(err, f"saving the resume journal of {self.name}") from err
            self._last_checkpoint = time.monotonic()

    # ending ---------------------------------------------------------------------------------------
    def finalize(self) -> dict[str, Any]:
        """Check the complete file and rename it into place.

        Returns:
            ``{"name", "size", "sha256", "path"}`` plus what ``validate`` returned.

        Raises:
            StoreChecksumError: The SHA-256 (or the map's MD5) differs from the offer; the temp
                file is deleted, the target untouched.
            StoreError: ``PARSE_ERROR`` (or the validator's status) when the content is refused,
                ``NO_SPACE`` / ``IO_ERROR`` on file-system errors. The target is untouched.
        """
        assert self._fd is not None
        try:
            self.flush()
            self._stop_writer()
            if sum(self.have) != self.offer.chunks:
                raise StoreError(f"{self.name}: finalize with chunks missing", Status.INTERNAL)
            self._catch_up()
            _fsync(self._fd)
            sha = self._hasher.hexdigest()
            if sha != self.offer.sha256:
                raise StoreChecksumError(
                    f"{self.name}: SHA-256 of the received file is {sha}, the "
                    f"sender announced {self.offer.sha256}"
                )
            info: dict[str, Any] = {"name": self.name, "size": self.offer.size, "sha256": sha}
            if self.validate is not None:
                try:
                    info.update(self.validate(self.temp))
                except StoreError:
                    raise
                except ChecksumError:
                    raise
                except Exception as err:
                    raise StoreError(f"{self.name} refused: {err}", Status.PARSE_ERROR) from err
            if self.offer.md5 and info.get("md5") and info["md5"] != self.offer.md5:
                raise StoreChecksumError(
                    f"{self.name}: MD5 of the received map is {info['md5']}, "
                    f"the sender announced {self.offer.md5}",
                    Status.MD5_MISMATCH,
                )
            try:
                mode = os.stat(self.target).st_mode & 0o7777
            except FileNotFoundError:
                mode = 0o666 & ~_UMASK
            os.fchmod(self._fd, mode)
            os.replace(self.temp, self.target)
            fsync_dir(self.folder)
        except OSError as err:
            self._discard()
            raise _os_error(err, f"publishing {self.name}") from err
        except BaseException:
            self._discard()
            raise
        with contextlib.suppress(FileNotFoundError):
            os.unlink(self.journal)
        self._close_fd()
        info["path"] = self.target
        return info

    def take(self, rx: Receiver) -> list[Out]:
        """Handle a :class:`~mapkit.transfer.protocol.Receiver`'s events: store each chunk, and
        on completion :meth:`finalize` and answer VERIFIED; a failure answers CANCEL.

        Returns:
            The frames to send.
        """
        out: list[Out] = []
        for e in rx.pop_events():
            try:
                if isinstance(e, ChunkReceived):
                    self.write(e.index, e.data, e.crc)
                elif isinstance(e, TransferComplete):
                    info = self.finalize()
                    info.pop("path", None)
                    out += rx.verified(info, time.monotonic())
            except TransferError as err:
                out += rx.fail(err)
                break
        return out

    def close(self, *, keep: bool = True) -> None:
        """End without publishing: keep the partial data and journal for a resume, or delete
        them."""
        if self._fd is None:
            return
        try:
            self.flush()
        except StoreError as err:
            keep = keep and err.status != Status.NO_SPACE
        self._stop_writer()
        held = any(self.have)
        if keep and held:
            try:
                self.checkpoint()
            except StoreError:
                keep = False
        if keep and held:
            self._close_fd()
        else:
            self._discard()

    def _discard(self) -> None:
        if self._threads and threading.current_thread() not in self._threads:
            self._error = self._error or StoreError("discarded", Status.INTERNAL)
            self._stop_writer()
        for p in (self.temp, self.journal):
            with contextlib.suppress(FileNotFoundError):
                os.unlink(p)
        self._close_fd()

    def _close_fd(self) -> None:
        if self._fd is not None:
            with contextlib.suppress(OSError):
                os.close(self._fd)  # also releases the lock
            self._fd = None

    def __enter__(self) -> PartialFile:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close(keep=True)


def expire_partials(folder: str, max_age: float, *, now: float | None = None) -> list[str]:
    """Delete abandoned partial files in ``folder``: a ``.NAME.mkpart`` (with its journal) that
    no session holds (its lock is free) and that nothing touched for ``max_age`` seconds, and a
    journal as old whose temp file is gone.

    Returns:
        The names (``NAME``) whose partial files were deleted.
    """
    now = time.time() if now is None else now
    gone = []
    with os.scandir(folder) as it:
        entries = [
            e for e in it if e.name.startswith(".") and e.name.endswith((".mkpart", ".mkpart.json"))
        ]
    names = {e.name for e in entries}
    for e in [e for e in entries if e.name.endswith(".json")]:  # a journal without its file
        entries.remove(e)
        if e.name[: -len(".json")] not in names and e.is_file(follow_symlinks=False):
            with contextlib.suppress(OSError):
                if now - e.stat(follow_symlinks=False).st_mtime >= max_age:
                    os.unlink(e.path)
    for e in entries:
        name = e.name[1 : -len(".mkpart")]
        temp, journal = partial_paths(folder, name)
        try:
            fd = os.open(
                temp, os.O_RDWR | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_CLOEXEC", 0)
            )
        except OSError:
            continue
        try:
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError:
                continue  # a session is writing it
            newest = os.fstat(fd).st_mtime
            with contextlib.suppress(OSError):
                newest = max(newest, os.stat(journal).st_mtime)
            if now - newest < max_age:
                continue
            for p in (journal, temp):  # the journal first: a temp file alone is never resumed
                with contextlib.suppress(FileNotFoundError):
                    os.unlink(p)
            gone.append(name)
        finally:
            os.close(fd)
    return gone


# -- names ----------------------------------------------------------------------------------------

_WINDOWS_RESERVED = {
    "con",
    "prn",
    "aux",
    "nul",
    *(f"com{i}" for i in range(1, 10)),
    *(f"lpt{i}" for i in range(1, 10)),
}
MAX_NAME = 200


def check_name(
    name: object,
    *,
    suffixes: tuple[str, ...] | None = (".map", ".2d"),
    reserved: tuple[str, ...] = (),
) -> str:
    """Check that a received name is a plain file name, safe to join to a folder.

    Refused: empty or longer than 200 bytes in UTF-8; ``/`` or ``\\``; ``..`` anywhere; a leading
    ``.`` (hidden and temp files) or ``-``; control and format characters (C0, C1, DEL, bidi
    overrides); trailing space or dot; Windows device names; a suffix not in ``suffixes``; a name
    in ``reserved``.

    Args:
        name: The name from the wire.
        suffixes: Allowed suffixes (case-insensitive), or None for any.
        reserved: Names that may not be used (case-insensitive).

    Returns:
        The name, unchanged.

    Raises:
        StoreError: With status ``BAD_NAME`` and the reason.

    Examples:
        >>> check_name("office.map")
        'office.map'
        >>> try:
        ...     check_name("../etc/passwd.map")
        ... except StoreError as err:
        ...     print(err)
        bad name '../etc/passwd.map': no folders allowed, only a plain file name
    """
    import unicodedata

    def bad(why: str) -> StoreError:
        return StoreError(f"bad name {name!r}: {why}", Status.BAD_NAME)

    if not isinstance(name, str) or not name:
        raise bad("empty")
    if len(name) > MAX_NAME or len(name.encode("utf-8", "surrogatepass")) > MAX_NAME:
        # bytes, not characters: the file system's limit (255 bytes) is in bytes, and the
        # temp file and journal names add up to 35 bytes
        raise bad(f"longer than {MAX_NAME} bytes (UTF-8)")
    if "/" in name or "\\" in name:
        raise bad("no folders allowed, only a plain file name")
    if ".." in name:
        raise bad("'..' is not allowed")
    if name[0] in ".-":
        raise bad("must not start with '.' or '-'")
    if any(unicodedata.category(c) in ("Cc", "Cf", "Cs", "Co", "Zl", "Zp") for c in name):
        raise bad("control characters are not allowed")
    if name[-1] in " .":
        raise bad("must not end with a space or '.'")
    if name.split(".")[0].lower() in _WINDOWS_RESERVED:
        raise bad("a device name")
    low = name.lower()
    if suffixes is not None and not low.endswith(tuple(s.lower() for s in suffixes)):
        raise bad(f"only {', '.join(suffixes)} files are accepted")
    if low in (r.lower() for r in reserved):
        raise bad("reserved for the active map")
    return name
