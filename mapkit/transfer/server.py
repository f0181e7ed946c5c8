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
import os
import select
import socket
import ssl
import threading
import time
from collections.abc import Callable, Sequence
from typing import Any

from mapkit.errors import LocalTransferError, TransferError
from mapkit.transfer.admission import Admission
from mapkit.transfer.folder import (
    ACTIVE_NAME,
    DEFAULT_MAX_SIZE as DEFAULT_MAX_SIZE,
    DEFAULT_PARTIAL_TTL as DEFAULT_PARTIAL_TTL,
    PREVIOUS_NAME,
    STATE_NAME as STATE_NAME,
    MapFolder,
    log as log,
    same_transfer,
    validate_map_file,
)
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
    reject_out,
)
from mapkit.transfer.store import (
    PartialFile,
    PreparedReader,
    StoreError,
    chunk_reader,
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
