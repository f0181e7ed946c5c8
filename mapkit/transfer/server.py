"""The robot side: a folder of maps served over MKT/1 to many clients at once.

:class:`MapFolder` is the transport-free part (names, listing with digests, safe writes through
:class:`~mapkit.transfer.store.PartialFile`, reading for pulls, activating a map with rollback),
so a ROS binding can reuse it. :class:`MapServer` serves a folder over TCP, one thread per
connection: push (OFFER), pull (GET, optionally only when the MD5/SHA-256 changed), LIST, LOAD,
PING and BYE.

The active map: LOAD checks that the named file parses as a map and has the MD5 the client
gave, then writes its bytes atomically to ``active.map`` in the folder, after keeping the
previous active map as ``previous.map``; ``.mapkit-active.json`` records which names they came
from. Point ARNL (or the ROS bridge) at ``active.map``. ``LOAD {"rollback": true}`` swaps back.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import logging
import os
import select
import socket
import ssl
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

from mapkit._atomic import atomic_write, fsync_dir
from mapkit.errors import LocalTransferError, MapFormatError, TransferError
from mapkit.formats.map import parse_map
from mapkit.transfer.admission import Admission
from mapkit.transfer.protocol import (
    AUTH_METHODS,
    DEFAULT_CHUNK_SIZE,
    DEFAULT_PORT,
    AuthenticationError,
    Channel,
    Frame,
    FrameType,
    Offer,
    Out,
    ProtocolError,
    Receiver,
    Sender,
    ServerHandshake,
    Status,
    dump_json,
    kind_of,
    reject_out,
)
from mapkit.transfer.store import (
    PartialFile,
    PreparedReader,
    StoreError,
    check_name,
    chunk_reader,
    expire_partials,
    file_digests,
)
from mapkit.transfer.tcp import FrameLink, listen, run, tune_socket

__all__ = [
    "ACTIVE_NAME",
    "PREVIOUS_NAME",
    "MapFolder",
    "MapServer",
    "same_transfer",
    "validate_map_file",
]

log = logging.getLogger(__name__)

ACTIVE_NAME = "active.map"
PREVIOUS_NAME = "previous.map"
STATE_NAME = ".mapkit-active.json"
DEFAULT_MAX_SIZE = 1 << 30
DEFAULT_PARTIAL_TTL = 24 * 3600.0  # an interrupted transfer not resumed for a day is abandoned


def validate_map_file(path: str) -> dict[str, Any]:
    """Parse a received ``.map`` file with mapkit; returns ``{"md5": ...}``.

    Raises:
        StoreError: ``PARSE_ERROR`` with the parser's message (file and line).
    """
    with open(path, "rb") as fh:
        data = fh.read()
    name = os.path.basename(path)
    if name.startswith(".") and name.endswith(".mkpart"):
        name = name[1 : -len(".mkpart")]
    try:
        parse_map(data, source=name)
    except MapFormatError as err:
        raise StoreError(f"not a valid map: {err}", Status.PARSE_ERROR) from err
    return {"md5": hashlib.md5(data).hexdigest(), "kind": "map"}


def same_transfer(a: Offer, b: Offer) -> bool:
    """True when two offers are the same transfer: same name, SHA-256, size and chunk size
    (the resume journal and every chunk offset then mean the same bytes)."""
    return (a.name, a.sha256, a.size, a.chunk_size) == (b.name, b.sha256, b.size, b.chunk_size)


def _validator(name: str) -> Callable[[str], dict[str, Any]] | None:
    return validate_map_file if kind_of(name) == "map" else None


@dataclass
class _Digest:
    key: tuple[int, int, int, int]
    sha256: str
    md5: str


class MapFolder:
    """A folder of maps: the file-system side of the server, without any networking.

    Args:
        root: The folder (created if missing).
        max_size: Largest file accepted, in bytes.
        suffixes: Accepted file suffixes.
        reserve: Bytes to keep free on the device.
        on_load: Called with ``(name, active_path)`` after a map became active.
    """

    def __init__(
        self,
        root: str | os.PathLike[str],
        *,
        max_size: int = DEFAULT_MAX_SIZE,
        suffixes: tuple[str, ...] = (".map", ".2d"),
        reserve: int = 1 << 20,
        on_load: Callable[[str, str], None] | None = None,
    ) -> None:
        self.root = os.path.abspath(os.fspath(root))
        os.makedirs(self.root, exist_ok=True)
        self.max_size = max_size
        self.suffixes = suffixes
        self.reserve = reserve
        self.on_load = on_load
        self._digests: dict[str, _Digest] = {}
        self._valid: dict[str, None] = {}  # SHA-256 of map contents that parsed (recent first)
        self._lock = threading.Lock()
        self._load_lock = threading.Lock()
        self._partials: list[PartialFile] = []  # destinations being written (disk ledger)

    # names and digests ----------------------------------------------------------------------------
    def check_name(self, name: object) -> str:
        """:func:`~mapkit.transfer.store.check_name` with this folder's suffixes and reserved
        names."""
        return check_name(name, suffixes=self.suffixes, reserved=(ACTIVE_NAME, PREVIOUS_NAME))

    def path(self, name: str) -> str:
        """The path of a (checked) name."""
        return os.path.join(self.root, name)

    def _open(self, name: str) -> int:
        try:
            return os.open(self.path(name), os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0))
        except FileNotFoundError as err:
            raise StoreError(f"{name}: no such map on this robot", Status.NOT_FOUND) from err
        except OSError as err:
            raise StoreError(f"{name}: {err.strerror}", Status.IO_ERROR) from err

    def digests(self, name: str, fd: int | None = None) -> tuple[str, str, os.stat_result]:
        """``(sha256, md5, stat)`` of a file in the folder, cached by inode, size and mtime."""
        own = fd is None
        if fd is None:
            fd = self._open(name)
        try:
            st = os.fstat(fd)
            key = (st.st_ino, st.st_size, st.st_mtime_ns, st.st_ctime_ns)
            with self._lock:
                d = self._digests.get(name)
            if d is None or d.key != key:
                sha, md5 = file_digests(fd, st.st_size)
                assert md5 is not None
                d = _Digest(key, sha, md5)
                with self._lock:
                    self._digests[name] = d
            return d.sha256, d.md5, st
        finally:
            if own:
                os.close(fd)

    def state(self) -> dict[str, Any]:
        """The active-map record (``{}`` when no map was loaded)."""
        try:
            with open(os.path.join(self.root, STATE_NAME), encoding="utf-8") as fh:
                d = json.load(fh)
            return d if isinstance(d, dict) else {}
        except (OSError, ValueError):
            return {}

    def listing(self) -> dict[str, Any]:
        """Every map in the folder with size, MD5, SHA-256, mtime and whether it is active."""
        state = self.state()
        maps = []
        for entry in sorted(os.scandir(self.root), key=lambda e: e.name):
            try:
                self.check_name(entry.name)
            except StoreError:
                continue
            if not entry.is_file(follow_symlinks=False):
                continue
            try:
                sha, md5, st = self.digests(entry.name)
            except (StoreError, OSError):
                continue
            maps.append(
                {
                    "name": entry.name,
                    "size": st.st_size,
                    "md5": md5,
                    "sha256": sha,
                    "mtime": round(st.st_mtime, 3),
                    "kind": kind_of(entry.name),
                    "active": entry.name == state.get("name") and sha == state.get("sha256"),
                }
            )
        return {
            "maps": maps,
            "active": state.get("name"),
            "active_md5": state.get("md5"),
            "previous": (state.get("previous") or {}).get("name"),
        }

    # transfers ------------------------------------------------------------------------------------
    def begin_write(self, offer: Offer, *, checkpoint_interval: float = 0.5) -> PartialFile:
        """Check an incoming offer and open its destination (resuming a partial one).

        Raises:
            StoreError: ``BAD_NAME``, ``TOO_LARGE``, ``NO_SPACE``, ``BUSY`` or ``IO_ERROR``.
        """
        name = self.check_name(offer.name)
        if offer.size > self.max_size:
            raise StoreError(
                f"{name} has {offer.size} bytes, this robot accepts at most {self.max_size}",
                Status.TOO_LARGE,
            )
        check = _validator(name)

        def validate(path: str) -> dict[str, Any]:
            assert check is not None
            info = check(path)  # called after the SHA-256 check: the content is offer.sha256
            self._parsed(offer.sha256)
            return info

        with self._lock:  # the disk other transfers in progress may still take
            self._partials = [p for p in self._partials if p.is_open]
            pending = sum(p.outstanding for p in self._partials if p.name != name)
        dest = PartialFile.open(
            self.root,
            name,
            offer,
            checkpoint_interval=checkpoint_interval,
            validate=validate if check else None,
            reserve=self.reserve + pending,
        )
        with self._lock:
            self._partials.append(dest)
        return dest

    def expire_partials(self, max_age: float) -> list[str]:
        """Delete partial files no session holds and nothing touched for ``max_age`` seconds
        (see :func:`~mapkit.transfer.store.expire_partials`); returns their names."""
        return expire_partials(self.root, max_age)

    def _parsed(self, sha256: str) -> None:
        with self._lock:
            self._valid.pop(sha256, None)
            self._valid[sha256] = None
            while len(self._valid) > 256:
                del self._valid[next(iter(self._valid))]

    def open_read(self, name: str, *, chunk_size: int = DEFAULT_CHUNK_SIZE) -> tuple[int, Offer]:
        """Open a map for a pull: ``(fd, offer)``; the fd is a snapshot even if the file is
        replaced.

        Raises:
            StoreError: ``BAD_NAME``, ``NOT_FOUND``, ``IO_ERROR``.
        """
        if name in (ACTIVE_NAME, PREVIOUS_NAME):
            check_name(name, suffixes=self.suffixes)
        else:
            self.check_name(name)
        fd = self._open(name)
        try:
            sha, md5, st = self.digests(name, fd)
        except BaseException:
            os.close(fd)
            raise
        kind = kind_of(name)
        return fd, Offer(
            name,
            st.st_size,
            sha,
            chunk_size,
            md5 if kind == "map" else None,
            kind,
            round(st.st_mtime, 3),
        )

    # activation -----------------------------------------------------------------------------------
    def load(
        self, name: str | None, md5: str | None = None, *, rollback: bool = False
    ) -> dict[str, Any]:
        """Make a map the active one (or go back to the previous one).

        The file is read once; those bytes are checked (MD5, then parsed by mapkit) and written
        atomically to ``active.map`` after the current ``active.map`` was kept as ``previous.map``.

        Args:
            name: The map to activate (ignored with ``rollback``).
            md5: Expected MD5 (hex); the load is refused if the file differs.
            rollback: Re-activate ``previous.map``.

        Returns:
            The new state: ``{"name", "md5", "sha256", "loaded_at", "previous"}``.

        Raises:
            StoreError: ``BAD_NAME``, ``NOT_FOUND``, ``MD5_MISMATCH``, ``PARSE_ERROR``,
                ``IO_ERROR``.
        """
        with self._load_lock:
            state = self.state()
            if rollback:
                prev = state.get("previous")
                if not prev or not os.path.exists(self.path(PREVIOUS_NAME)):
                    raise StoreError("no previous map to roll back to", Status.NOT_FOUND)
                src, src_name = self.path(PREVIOUS_NAME), str(prev.get("name"))
            else:
                src_name = self.check_name(name)
                src = self.path(src_name)
            try:
                fd = os.open(src, os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0))
                with os.fdopen(fd, "rb") as fh:
                    data = fh.read()
            except FileNotFoundError as err:
                raise StoreError(
                    f"{src_name}: no such map on this robot", Status.NOT_FOUND
                ) from err
            except OSError as err:
                raise StoreError(
                    f"{src_name}: cannot read it: {err.strerror or err}", Status.IO_ERROR
                ) from err
            got = hashlib.md5(data).hexdigest()
            if md5 and got != md5.lower():
                raise StoreError(
                    f"{src_name} on the robot has MD5 {got}, expected {md5.lower()}",
                    Status.MD5_MISMATCH,
                )
            sha = hashlib.sha256(data).hexdigest()
            with self._lock:
                known = sha in self._valid
            if not known:  # content that parsed when it arrived parses now: mapkit is deterministic
                try:
                    parse_map(data, source=src_name)
                except MapFormatError as err:
                    raise StoreError(f"not a valid map: {err}", Status.PARSE_ERROR) from err
                self._parsed(sha)
            active = self.path(ACTIVE_NAME)
            try:
                if os.path.exists(active):
                    tmp = self.path(f".{PREVIOUS_NAME}.tmp")
                    with contextlib.suppress(FileNotFoundError):
                        os.unlink(tmp)
                    try:
                        os.link(active, tmp)
                    except OSError:
                        import shutil

                        shutil.copyfile(active, tmp)
                    os.replace(tmp, self.path(PREVIOUS_NAME))
                atomic_write(active, data)
                new = {
                    "name": src_name,
                    "md5": got,
                    "sha256": sha,
                    "size": len(data),
                    "loaded_at": round(time.time(), 3),
                    "previous": {k: state[k] for k in ("name", "md5", "sha256") if k in state}
                    or None,
                }
                atomic_write(
                    os.path.join(self.root, STATE_NAME), json.dumps(new, indent=1).encode()
                )
                fsync_dir(self.root)
            except OSError as err:
                raise StoreError(
                    f"cannot activate {src_name}: {err.strerror or err}",
                    Status.NO_SPACE if err.errno == 28 else Status.IO_ERROR,
                ) from err
        log.info("active map is now %s (MD5 %s)", src_name, got)
        if self.on_load is not None:
            self.on_load(src_name, active)
        return new


class MapServer:
    """Serves a :class:`MapFolder` over TCP (optionally TLS), one thread per client.

    Args:
        folder: The maps folder (path or :class:`MapFolder`).
        host: Address to listen on.
        port: TCP port (0 picks a free one; see :attr:`address`).
        secret: Pre-shared secret, or None.
        insecure: Accept clients without authentication (required when ``secret`` is None).
        tls: Server TLS context (see :func:`~mapkit.transfer.tcp.server_tls_context`).
        push_only: Only accept pushes (``mapkit receive``): no pull, list or load.
        max_clients: Authenticated sessions at once; a client that authenticates when all are
            taken is refused with ``BUSY``.
        idle_timeout: Seconds without a frame before a session is dropped.
        max_chunk: Largest chunk size accepted.
        name: This server's name in HELLO_ACK.
        takeover_after: A push of a name whose current writer has sent nothing for this many
            seconds ends that stale session and resumes its partial file (a terminal that lost
            its Wi-Fi and reconnects); a writer active more recently makes the push ``busy``,
            unless the new offer is of the very same file (same SHA-256, size and chunk size):
            then it is the same transfer resumed, and it takes over at once.
        on_received: Called with each VERIFIED info dict after a push was published.
        auth_methods: Per-frame tag algorithms accepted (see
            :data:`~mapkit.transfer.protocol.AUTH_METHODS`); each client gets its most preferred.
        handshake_timeout: Seconds from connecting (TLS included) to the end of the MKT
            handshake; a peer that has not authenticated by then is disconnected.
        max_pending: Connections still in their handshake at once (apart from the sessions);
            a new one evicts the least useful (see :class:`~mapkit.transfer.admission.Admission`).
        per_address: Connections in their handshake per peer address.
        partial_ttl: Seconds after which an abandoned partial file (an interrupted transfer no
            session is resuming) is deleted; checked at start and every ``sweep_interval``.
        sweep_interval: Seconds between two sweeps for abandoned partial files.

    Examples:
        >>> import tempfile
        >>> with MapServer(tempfile.mkdtemp(), port=0, insecure=True) as srv:
        ...     srv.address[0]
        '127.0.0.1'
    """

    def __init__(
        self,
        folder: str | os.PathLike[str] | MapFolder,
        *,
        host: str = "127.0.0.1",
        port: int = DEFAULT_PORT,
        secret: bytes | None = None,
        insecure: bool = False,
        tls: ssl.SSLContext | None = None,
        push_only: bool = False,
        max_clients: int = 64,
        idle_timeout: float = 30.0,
        max_chunk: int = 1 << 20,
        name: str = "",
        rto: float = 2.0,
        window: int = 16,
        takeover_after: float = 5.0,
        on_received: Callable[[dict[str, Any]], None] | None = None,
        auth_methods: Sequence[str] = AUTH_METHODS,
        handshake_timeout: float = 5.0,
        max_pending: int = 32,
        per_address: int = 8,
        partial_ttl: float = DEFAULT_PARTIAL_TTL,
        sweep_interval: float = 60.0,
    ) -> None:
        if secret is None and not insecure:
            raise LocalTransferError(
                "no shared secret: give --secret-file or MAPKIT_SECRET, or "
                "--insecure to accept anyone"
            )
        self.folder = folder if isinstance(folder, MapFolder) else MapFolder(folder)
        self.secret = secret
        self.insecure = insecure
        self.tls = tls
        self.push_only = push_only
        self.max_clients = max_clients
        self.idle_timeout = idle_timeout
        self.max_chunk = max_chunk
        self.rto = rto
        self.window = window
        self.name = name or socket.gethostname()
        self.on_received = on_received
        self.takeover_after = takeover_after
        self.auth_methods = tuple(auth_methods)
        self.handshake_timeout = handshake_timeout
        self.partial_ttl = partial_ttl
        self.sweep_interval = sweep_interval
        self.admission = Admission(
            max_sessions=max_clients,
            max_pending=max_pending,
            per_address=per_address,
            handshake_timeout=handshake_timeout,
        )
        self._writers: dict[str, tuple[FrameLink, Receiver]] = {}
        self._sock = listen(host, port, backlog=max(128, max_pending + max_clients))
        self.address: tuple[str, int] = self._sock.getsockname()[:2]
        self._threads: set[threading.Thread] = set()
        self._conns: dict[int, _Connection] = {}
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._wake = threading.Event()
        self._acceptor: threading.Thread | None = None
        self._reaper: threading.Thread | None = None
        self._next_id = 0
        self.sessions = 0

    # lifecycle ------------------------------------------------------------------------------------
    def start(self) -> MapServer:
        """Accept clients in a background thread (and watch deadlines in another)."""
        self.sweep()
        self._reaper = threading.Thread(
            target=self._reap_forever, name="mapkit-reaper", daemon=True
        )
        self._reaper.start()
        self._acceptor = threading.Thread(
            target=self.serve_forever, name="mapkit-accept", daemon=True
        )
        self._acceptor.start()
        return self

    def serve_forever(self) -> None:
        """Accept clients until :meth:`close`. Nothing a client does ends this loop."""
        while not self._stop.is_set():
            try:
                conn, addr = self._sock.accept()
            except OSError:
                if self._stop.is_set():
                    return
                time.sleep(0.05)
                continue
            try:
                self._admit(conn, addr)
            except Exception:  # e.g. no thread could be started: drop this one, keep serving
                log.exception("%s: could not start a session", addr)
                with contextlib.suppress(OSError):
                    conn.close()
                time.sleep(0.05)

    def _admit(self, conn: socket.socket, addr: Any) -> None:
        with self._lock:
            self._next_id += 1
            c = _Connection(self._next_id, conn, f"{addr[0]}:{addr[1]}", str(addr[0]))
            self._conns[c.id] = c
        for key in self.admission.admit(c.id, c.address, time.monotonic(), self._waiting):
            self._drop(key, "evicted: too many connections in their handshake")
        t = threading.Thread(
            target=self._connection, args=(c,), daemon=True, name=f"mapkit-{c.peer}"
        )
        with self._lock:
            self._threads.add(t)
        try:
            t.start()
        except BaseException:
            with self._lock:
                self._threads.discard(t)
                self._conns.pop(c.id, None)
            self.admission.release(c.id)
            raise
        self._wake.set()

    def _waiting(self, key: Any) -> bool:
        """True when a connection has bytes waiting to be read (its peer is not silent)."""
        c = self._conns.get(key)
        if c is None:
            return False
        try:
            poller = select.poll()
            poller.register(c.sock, select.POLLIN)
            return any(ev & select.POLLIN for _, ev in poller.poll(0))
        except (OSError, ValueError):
            return False

    def _drop(self, key: Any, why: str) -> None:
        """Disconnect a connection (its thread ends and cleans up)."""
        with self._lock:
            c = self._conns.get(key)
        if c is not None:
            log.info("%s: %s", c.peer, why)
            c.shutdown()

    def _reap_forever(self) -> None:
        """Disconnect peers whose handshake deadline passed; sweep abandoned partial files."""
        next_sweep = time.monotonic() + self.sweep_interval
        while not self._stop.is_set():
            try:
                now = time.monotonic()
                for key in self.admission.expired(now):
                    self._drop(key, f"no handshake within {self.handshake_timeout:g} s, closing")
                if now >= next_sweep:
                    next_sweep = now + self.sweep_interval
                    self.sweep()
                dl = self.admission.next_deadline()
                wait = min(next_sweep, dl if dl is not None else next_sweep) - time.monotonic()
            except Exception:  # pragma: no cover - keep watching whatever happens
                log.exception("connection reaper")
                wait = 1.0
            self._wake.wait(max(0.01, min(wait, 1.0)))
            self._wake.clear()

    def sweep(self) -> list[str]:
        """Delete abandoned partial files older than ``partial_ttl``; returns their names."""
        try:
            gone = self.folder.expire_partials(self.partial_ttl)
        except OSError as err:
            log.warning("cannot sweep %s for abandoned partial files: %s", self.folder.root, err)
            return []
        for name in gone:
            log.info("deleted the abandoned partial file of %s", name)
        return gone

    def close(self, timeout: float = 5.0) -> None:
        """Stop accepting, end open sessions, wait for their threads."""
        self._stop.set()
        self._wake.set()
        with contextlib.suppress(OSError):
            self._sock.shutdown(socket.SHUT_RDWR)
        self._sock.close()
        with self._lock:
            conns, threads = list(self._conns.values()), list(self._threads)
        for c in conns:
            c.shutdown()
        for t in threads:
            t.join(timeout)
        for helper in (self._acceptor, self._reaper):
            if helper is not None:
                helper.join(timeout)

    def __enter__(self) -> MapServer:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.close()

    # one connection -------------------------------------------------------------------------------
    def _connection(self, c: _Connection) -> None:
        peer = c.peer
        link: FrameLink | None = None
        try:
            tune_socket(c.sock, keepalive=True)
            if self.tls is not None:
                c.sock.settimeout(self.handshake_timeout)
                tls = self.tls.wrap_socket(c.sock, server_side=True, do_handshake_on_connect=False)
                c.sock = tls  # from now on the reaper shuts this one down at the deadline
                if c.closing:  # evicted meanwhile
                    return
                tls.do_handshake()
            link = FrameLink(c.sock, Channel(initiator=False), peer=peer)
            self._session(link, c)
        except (TransferError, OSError, ssl.SSLError) as err:
            log.info("%s: session ended: %s", peer, err)
        except Exception:  # never let one client kill the server
            log.exception("%s: internal error", peer)
        finally:
            if link is not None:
                link.close()
            else:
                c.shutdown()
                with contextlib.suppress(OSError):
                    c.sock.close()
            self.admission.release(c.id)
            with self._lock:
                self._threads.discard(threading.current_thread())
                self._conns.pop(c.id, None)

    def _session(self, link: FrameLink, c: _Connection) -> None:
        peer = c.peer
        features = ["push"] if self.push_only else ["push", "pull", "list", "load"]
        hs = ServerHandshake(
            link.channel,
            self.secret,
            insecure=self.insecure,
            peer=self.name,
            auth_methods=self.auth_methods,
            info={
                "max_chunk": self.max_chunk,
                "max_size": self.folder.max_size,
                "features": features,
            },
            idle_timeout=self.idle_timeout,
            timeout=self.handshake_timeout,
        )
        try:
            run(link, hs, tick=lambda: self.admission.progressed(c.id))
        except (AuthenticationError, ProtocolError) as err:
            if hs.error is None:  # the channel refused a frame; the machine has not answered
                with contextlib.suppress(TransferError):
                    link.send([reject_out(err, plain=True)])
            log.warning("%s: refused: %s", peer, err)
            return
        if not self.admission.authenticated(c.id):
            if not c.closing:
                log.warning("%s: refused: %d sessions already", peer, self.max_clients)
                with contextlib.suppress(TransferError):
                    link.send(
                        [
                            reject_out(
                                StoreError(
                                    f"this robot serves {self.max_clients} sessions "
                                    "already; try again later",
                                    Status.BUSY,
                                )
                            )
                        ]
                    )
            return
        with self._lock:
            self.sessions += 1
        log.info(
            "%s: session %016x (%s, auth %s)",
            peer,
            link.channel.session,
            hs.client.get("peer", "?"),
            hs.auth,
        )
        last: Any = None  # the last transfer's machine, for its late frames
        while True:
            try:
                ev = link.receive(self.idle_timeout)
            except ProtocolError as err:
                with contextlib.suppress(TransferError):
                    link.send([reject_out(err)])
                log.warning("%s: %s", peer, err)
                return
            if ev is None:
                log.info("%s: idle for %g s, closing", peer, self.idle_timeout)
                return
            if not isinstance(ev, Frame):
                continue
            if ev.type == FrameType.BYE:
                link.send([Out(FrameType.BYE, b"{}", ref=ev.ref)])
                return
            if ev.type == FrameType.AUTH:
                link.send(hs.resend(ev))  # the client missed AUTH_OK
                continue
            if last is not None and (
                ev.type == FrameType.DATA
                or (
                    ev.ref == last.ref
                    and ev.type in (FrameType.DONE, FrameType.ACK, FrameType.OFFER)
                )
            ):
                link.send(last.handle(ev, time.monotonic()))  # late frames of the last transfer
                continue
            what = FrameType(ev.type).name if ev.type in FrameType._value2member_map_ else ev.type
            try:
                last = self._request(link, ev, peer, features) or last
            except _Ended as err:  # the peer was told (CANCEL); it may try again in this session
                last = err.machine
            except (ProtocolError, StoreError) as err:
                log.warning("%s: %s refused: %s", peer, what, err)
                link.send([reject_out(err, ev.ref)])
                if isinstance(err, (AuthenticationError,)) or err.status in (Status.REPLAY,):
                    return
            except OSError as err:  # the folder failed under a request: say so, go on
                log.warning("%s: %s failed: %s", peer, what, err)
                failed = StoreError(
                    f"the robot's file system failed: {err.strerror or err}", Status.IO_ERROR
                )
                link.send([reject_out(failed, ev.ref)])
            except TransferError:
                raise  # the link broke: the session is over
            except Exception as err:  # a bug met by one request: tell the peer, end this session
                log.exception("%s: internal error in %s", peer, what)
                link.send([reject_out(err, ev.ref)])
                return

    def _request(self, link: FrameLink, f: Frame, peer: str, features: list[str]) -> Any:
        t = f.type
        if t == FrameType.PING:
            link.send([Out(FrameType.PONG, f.payload, ref=f.ref)])
        elif t == FrameType.OFFER:
            return self._push(link, f, peer)
        elif t == FrameType.GET and "pull" in features:
            return self._pull(link, f, peer)
        elif t == FrameType.LIST and "list" in features:
            link.send([Out(FrameType.LISTING, dump_json(self.folder.listing()), ref=f.ref)])
        elif t == FrameType.LOAD and "load" in features:
            d = f.json()
            md5 = d.get("md5") if isinstance(d.get("md5"), str) else None
            state = self.folder.load(d.get("name"), md5, rollback=bool(d.get("rollback")))
            log.info("%s: loaded %s", peer, state["name"])
            link.send([Out(FrameType.LOADED, dump_json(state), ref=f.ref)])
        elif t in (FrameType.GET, FrameType.LIST, FrameType.LOAD):
            raise ProtocolError(
                f"this peer only receives files ({FrameType(t).name} is not served)",
                Status.UNSUPPORTED,
            )
        else:
            raise ProtocolError(
                f"unexpected {FrameType(t).name if t in FrameType._value2member_map_ else t} "
                "frame between requests"
            )
        return None

    def _push(self, link: FrameLink, f: Frame, peer: str) -> Receiver:
        d = f.json()
        offer = Offer.from_json(d, max_chunk=self.max_chunk)
        dest = self._begin_write(offer, peer)
        w = d.get("window")
        rx = Receiver(
            offer,
            ref=f.ref,
            have=dest.have,
            window=max(self.window * 4, 64),
            idle_timeout=self.idle_timeout,
            sender_window=w if isinstance(w, int) else None,
        )
        with self._lock:
            self._writers[dest.name] = (link, rx)
        ok = False
        try:

            def on_events() -> list[Out]:
                return dest.take(rx)

            if dest.resumed:
                log.info(
                    "%s: resuming %s with %d of %d chunks",
                    peer,
                    offer.name,
                    dest.resumed,
                    offer.chunks,
                )
            dest.start_writer()
            link.send(rx.accept(time.monotonic()))
            link.send(on_events())
            run(link, rx, start=False, on_events=on_events)
            ok = True
            log.info(
                "%s: received %s (%d bytes, SHA-256 %s, %d chunks resumed, %d duplicates)",
                peer,
                offer.name,
                offer.size,
                offer.sha256,
                dest.resumed,
                rx.duplicates,
            )
            if self.on_received is not None:
                self.on_received(
                    {
                        "name": offer.name,
                        "size": offer.size,
                        "sha256": offer.sha256,
                        "md5": offer.md5,
                        "peer": peer,
                        "resumed": dest.resumed,
                        "path": dest.target,
                    }
                )
            return rx
        except TransferError as err:
            log.warning("%s: push of %s failed: %s", peer, offer.name, err)
            no_space = getattr(rx.error, "status", None) == Status.NO_SPACE
            dest.close(keep=not no_space)  # a full disk keeps no partial file
            raise _Ended(str(err), rx) from err
        finally:
            with self._lock:
                if self._writers.get(dest.name, (None,))[0] is link:
                    del self._writers[dest.name]
            if not ok:
                dest.close(keep=True)

    def _begin_write(self, offer: Offer, peer: str) -> PartialFile:
        """:meth:`MapFolder.begin_write`, taking over from a writer that went silent."""
        try:
            return self.folder.begin_write(offer)
        except StoreError as err:
            if err.status != Status.BUSY:
                raise
            with self._lock:
                holder = self._writers.get(offer.name)
            if holder is None:
                raise
            silent = time.monotonic() - holder[1].last_heard
            if same_transfer(holder[1].offer, offer):
                # the same file (SHA-256, size, chunk size): the sender resuming after a cut
                # the robot did not notice (no FIN); whoever sends, the same bytes land
                log.warning(
                    "%s: resuming %s, taking it over from a session silent for %.1f s",
                    peer,
                    offer.name,
                    silent,
                )
            elif silent < self.takeover_after:
                raise
            else:
                log.warning(
                    "%s: taking over %s from a session silent for %.1f s", peer, offer.name, silent
                )
            with contextlib.suppress(OSError):  # its thread ends, keeps the partial, unlocks
                holder[0].sock.shutdown(socket.SHUT_RDWR)
            end = time.monotonic() + 5.0
            while True:
                time.sleep(0.02)
                try:
                    return self.folder.begin_write(offer)
                except StoreError as again:
                    if again.status != Status.BUSY or time.monotonic() > end:
                        raise

    def _pull(self, link: FrameLink, f: Frame, peer: str) -> Sender | None:
        d = f.json()
        name = d.get("name")
        cs = d.get("chunk_size", DEFAULT_CHUNK_SIZE)
        cs = min(cs, self.max_chunk) if isinstance(cs, int) and cs > 0 else DEFAULT_CHUNK_SIZE
        fd, offer = self.folder.open_read(name if isinstance(name, str) else "", chunk_size=cs)
        try:
            if (d.get("if_md5") and d.get("if_md5") == offer.md5) or (
                d.get("if_sha256") and d.get("if_sha256") == offer.sha256
            ):
                link.send([Out(FrameType.NOT_MODIFIED, dump_json(offer.json()), ref=f.ref)])
                return None

            ahead = PreparedReader.for_file(
                fd, offer.size, offer.chunk_size, link.channel.preparer()
            )
            try:
                tx = Sender(
                    offer,
                    ahead or chunk_reader(fd, offer),
                    ref=f.ref,
                    window=self.window,
                    rto=self.rto,
                    idle_timeout=self.idle_timeout,
                )
                if ahead is not None:
                    ahead.skip = lambda i: tx.acked[i]  # a resumed pull needs only the rest
                    ahead.start()
                run(link, tx)
            except TransferError as err:
                log.warning("%s: pull of %s failed: %s", peer, offer.name, err)
                raise _Ended(str(err), tx) from err
            finally:
                if ahead is not None:
                    ahead.close()
            log.info(
                "%s: sent %s (%d bytes, %d chunks sent, %d skipped)",
                peer,
                offer.name,
                offer.size,
                tx.chunks_sent,
                tx.chunks_skipped,
            )
            return tx
        finally:
            os.close(fd)


class _Connection:
    """One accepted TCP connection: its socket (replaced by the TLS one once wrapped)."""

    def __init__(self, id: int, sock: socket.socket, peer: str, address: str) -> None:
        self.id = id
        self.sock = sock
        self.peer = peer
        self.address = address
        self.closing = False

    def shutdown(self) -> None:
        """Wake and end whatever reads or writes the socket (idempotent, any thread)."""
        self.closing = True
        with contextlib.suppress(OSError, ValueError):
            self.sock.shutdown(socket.SHUT_RDWR)


class _Ended(TransferError):
    """A transfer ended in failure; the peer was told; the session goes on.

    Attributes:
        machine: The failed transfer's machine (it answers the transfer's late frames).
    """

    def __init__(self, message: str, machine: Any) -> None:
        super().__init__(message)
        self.machine = machine
