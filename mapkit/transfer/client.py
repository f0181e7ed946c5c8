"""The terminal side: send, fetch, list and load maps on a robot running ``mapkit serve``.

:class:`Client` keeps one authenticated session open for several requests; the functions
:func:`send_file`, :func:`fetch_file`, :func:`list_maps` and :func:`load_map` open one each.

Examples:
    >>> import pathlib, tempfile
    >>> from mapkit.transfer import MapServer, send_file, list_maps
    >>> robot_dir, here = pathlib.Path(tempfile.mkdtemp()), pathlib.Path(tempfile.mkdtemp())
    >>> _ = (here / "office.map").write_text("2D-Map\\nDATA\\n1 2\\n")
    >>> with MapServer(robot_dir, port=0, insecure=True) as robot:
    ...     host, port = robot.address
    ...     sent = send_file(here / "office.map", host, port, insecure=True)
    ...     listing = list_maps(host, port, insecure=True)
    >>> sent["name"], sent["chunks_sent"], [m["name"] for m in listing["maps"]]
    ('office.map', 1, ['office.map'])
"""

from __future__ import annotations

import contextlib
import os
import secrets
import socket
import ssl
import threading
import time
from collections.abc import Callable, Sequence
from typing import Any

from mapkit.errors import LocalTransferError, TransferError
from mapkit.transfer.protocol import (
    AUTH_METHODS,
    DEFAULT_CHUNK_SIZE,
    DEFAULT_PORT,
    Channel,
    ClientHandshake,
    FrameType,
    Offer,
    Receiver,
    Rejected,
    Request,
    Sender,
    Status,
    kind_of,
)
from mapkit.transfer.server import validate_map_file
from mapkit.transfer.store import (
    PartialFile,
    PreparedReader,
    check_name,
    chunk_reader,
    file_digests,
)
from mapkit.transfer.tcp import FrameLink, connect, run

__all__ = [
    "Client",
    "Progress",
    "fetch_file",
    "list_maps",
    "load_map",
    "offer_for_file",
    "receive_files",
    "send_file",
]

#: ``progress(done_bytes, total_bytes)``, called a few times a second during a transfer.
Progress = Callable[[int, int], None]

#: Chunk size of the TCP client: few, large frames keep Python's per-frame work out of the way
#: (the robot's ``max_chunk`` caps it; ROS bindings use smaller chunks).
TCP_CHUNK_SIZE = 1 << 20

# (device, inode, size, mtime, ctime) -> (sha256, md5 or None): a file sent again in this
# process (a resumed or repeated push) is not hashed again. A stale entry cannot slip through:
# the receiver checks the SHA-256 of what arrived, and a mismatch makes the sender hash afresh.
_DIGESTS: dict[tuple[int, int, int, int, int], tuple[str, str | None]] = {}
_DIGESTS_MAX = 64
_DIGESTS_LOCK = threading.Lock()


def offer_for_file(
    path: str | os.PathLike[str],
    *,
    name: str | None = None,
    chunk_size: int = DEFAULT_CHUNK_SIZE,
    cached: bool = True,
    on_open: Callable[[int, os.stat_result], None] | None = None,
) -> tuple[int, Offer]:
    """Open a local file and describe it: ``(fd, offer)`` (SHA-256 always, MD5 for maps).

    Args:
        path: The file.
        name: Name to offer (default: the file's).
        chunk_size: Bytes per chunk.
        cached: Reuse the digests computed for this very file (same device, inode, size, mtime
            and ctime) earlier in this process; False hashes it again.
        on_open: Called with the open file and its status before it is hashed (to start work
            that can run meanwhile).

    Raises:
        LocalTransferError: When the file cannot be read or the name is not a plain file name.
    """
    name = name or os.path.basename(os.fspath(path))
    check_name(name, suffixes=None)
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError as err:
        raise LocalTransferError(f"{os.fspath(path)}: {err.strerror}") from err
    try:
        st = os.fstat(fd)
        if on_open is not None:
            on_open(fd, st)
        kind = kind_of(name)
        key = (st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns, st.st_ctime_ns)
        with _DIGESTS_LOCK:
            known = _DIGESTS.get(key) if cached else None
        if known is not None and (known[1] is not None or kind != "map"):
            sha, md5 = known[0], known[1] if kind == "map" else None
        else:
            sha, md5 = file_digests(fd, st.st_size, md5=kind == "map")
            with _DIGESTS_LOCK:
                _DIGESTS.pop(key, None)
                _DIGESTS[key] = (sha, md5)
                while len(_DIGESTS) > _DIGESTS_MAX:
                    del _DIGESTS[next(iter(_DIGESTS))]
    except BaseException:
        os.close(fd)
        raise
    return fd, Offer(name, st.st_size, sha, chunk_size, md5, kind, round(st.st_mtime, 3))


def _attr(obj: Any, name: str) -> Callable[[], int]:
    return lambda: int(getattr(obj, name))


class _Ticker:
    def __init__(
        self, progress: Progress | None, total: int, get: Callable[[], int], interval: float
    ) -> None:
        self.progress, self.total, self.get, self.interval = progress, total, get, interval
        self._last = 0.0

    def __call__(self, force: bool = False) -> None:
        if self.progress is None:
            return
        now = time.monotonic()
        if force or now - self._last >= self.interval:
            self._last = now
            self.progress(self.get(), self.total)


class Client:
    """One authenticated MKT/1 session with a robot.

    Args:
        host: Robot address.
        port: TCP port.
        secret: Pre-shared secret (see :func:`~mapkit.transfer.protocol.load_secret`), or None.
        insecure: Allow a session without authentication (required when ``secret`` is None).
        tls: TLS client context, or None for plain TCP.
        timeout: Connect timeout and idle timeout in seconds.
        rto: First resend timeout in seconds.
        chunk_size: Bytes per chunk.
        window: Chunks in flight.
        progress_interval: Seconds between progress callbacks (0: after every frame).
        auth_methods: Per-frame tag algorithms to offer, preferred first (see
            :data:`~mapkit.transfer.protocol.AUTH_METHODS`).

    Attributes:
        server: The server's HELLO_ACK (name, limits, features).
        auth: The per-frame tag algorithm in use (``"none"`` without a secret).

    Raises:
        LocalTransferError: Cannot connect, or no secret and not insecure.
        Rejected: The robot refused the session (e.g. wrong secret).
    """

    def __init__(
        self,
        host: str,
        port: int = DEFAULT_PORT,
        *,
        secret: bytes | None = None,
        insecure: bool = False,
        tls: ssl.SSLContext | None = None,
        timeout: float = 10.0,
        rto: float = 2.0,
        chunk_size: int = TCP_CHUNK_SIZE,
        window: int = 16,
        progress_interval: float = 0.1,
        auth_methods: Sequence[str] = AUTH_METHODS,
    ) -> None:
        if secret is None and not insecure:
            raise LocalTransferError(
                "no shared secret: give --secret-file or MAPKIT_SECRET, or "
                "--insecure if the robot runs without one"
            )
        self.host, self.port = host, port
        self.timeout, self.rto, self.window = timeout, rto, window
        self.chunk_size = chunk_size
        self.progress_interval = progress_interval
        self._ref = 0
        sock = connect(host, port, timeout=timeout, tls=tls)
        session = int.from_bytes(secrets.token_bytes(8), "big")
        self.link = FrameLink(sock, Channel(initiator=True, session=session), peer=f"{host}:{port}")
        hs = ClientHandshake(
            self.link.channel,
            secret,
            peer=socket.gethostname(),
            rto=rto,
            idle_timeout=timeout,
            auth_methods=auth_methods,
        )
        try:
            run(self.link, hs)
        except BaseException:
            self.link.close()
            raise
        self.server = hs.server
        self.auth = hs.auth
        max_chunk = self.server.get("max_chunk")
        if isinstance(max_chunk, int) and max_chunk > 0:
            self.chunk_size = min(self.chunk_size, max_chunk)

    def _next_ref(self) -> int:
        self._ref += 1
        return self._ref

    def _request(
        self, type: FrameType, payload: dict[str, Any], answers: tuple[FrameType, ...]
    ) -> Any:
        req = Request(
            type,
            payload,
            ref=self._next_ref(),
            answers=answers,
            rto=self.rto,
            idle_timeout=max(self.timeout, 60.0),
        )
        run(self.link, req)
        assert req.response is not None
        return req.response

    # requests ------------------------------------------------------------------------------------
    def send(
        self,
        path: str | os.PathLike[str],
        *,
        name: str | None = None,
        progress: Progress | None = None,
    ) -> dict[str, Any]:
        """Push a file. Resumes a partial upload the robot kept; resends once if the file changed.

        Returns:
            ``{"name", "size", "sha256", "md5", "chunks", "chunks_sent", "chunks_resent",
            "chunks_skipped", "seconds", "mb_per_s"}``.

        Raises:
            Rejected: The robot refused (bad name, too large, busy, not a valid map...).
            TransferError: The transfer failed.
        """
        for attempt in (1, 2):
            t0 = time.monotonic()
            readers: list[PreparedReader] = []

            def prepare_ahead(
                fd: int, st: os.stat_result, readers: list[PreparedReader] = readers
            ) -> None:
                # CRC and tag work of every chunk in a second thread, meanwhile (see PreparedReader)
                reader = PreparedReader.for_file(
                    fd, st.st_size, self.chunk_size, self.link.channel.preparer()
                )
                if reader is not None:
                    readers.append(reader.start())

            try:
                fd, offer = offer_for_file(
                    path,
                    name=name,
                    chunk_size=self.chunk_size,
                    cached=attempt == 1,
                    on_open=prepare_ahead,
                )
            except BaseException:
                for r in readers:
                    r.close()
                raise
            try:
                read = readers[0] if readers else chunk_reader(fd, offer)
                tx = Sender(
                    offer,
                    read,
                    ref=self._next_ref(),
                    window=self.window,
                    rto=self.rto,
                    idle_timeout=max(self.timeout, 60.0),
                )
                if readers:
                    readers[0].skip = lambda i, tx=tx: tx.acked[i]  # a resume needs only the rest
                tick = _Ticker(
                    progress, offer.size, _attr(tx, "bytes_acked"), self.progress_interval
                )
                try:
                    run(self.link, tx, tick=tick)
                except Rejected as err:
                    if attempt == 1 and err.status == Status.HASH_MISMATCH:
                        continue  # the file changed while we read it: hash again, send again
                    raise
                tick(force=True)
            finally:
                for r in readers:
                    r.close()
                os.close(fd)
            dt = time.monotonic() - t0
            return {
                **offer.json(),
                "host": self.host,
                "auth": self.auth,
                "chunks_sent": tx.chunks_sent,
                "chunks_resent": tx.chunks_resent,
                "chunks_skipped": tx.chunks_skipped,
                "chunks_distinct": len(tx.sent_indices),
                "seconds": round(dt, 4),
                "mb_per_s": round(offer.size / dt / 1e6, 2) if dt else None,
                "verified": tx.result,
            }
        raise LocalTransferError("unreachable")  # pragma: no cover

    def fetch(
        self,
        name: str,
        dest: str | os.PathLike[str],
        *,
        if_changed: bool = False,
        progress: Progress | None = None,
    ) -> dict[str, Any]:
        """Pull ``name`` into the file ``dest`` (atomic; resumes an interrupted pull).

        Args:
            name: The map's name on the robot.
            dest: Local file to write (or a folder: the file keeps its name).
            if_changed: Skip the transfer when ``dest`` already has the robot's content (by MD5
                for maps, SHA-256 otherwise).
            progress: Progress callback.

        Returns:
            ``{"name", "size", "sha256", "md5", "path", "modified", "chunks_received",
            "chunks_resumed", "seconds", "mb_per_s"}``; ``modified`` is False when skipped.

        Raises:
            Rejected: Not found, bad name...
            TransferError: The transfer failed or the received file failed its checks (the
                old ``dest`` stays).
        """
        t0 = time.monotonic()
        dest = os.path.abspath(os.fspath(dest))
        if os.path.isdir(dest):
            dest = os.path.join(dest, check_name(name, suffixes=None))
        folder, local = os.path.dirname(dest), os.path.basename(dest)
        req: dict[str, Any] = {"name": name, "chunk_size": self.chunk_size}
        if if_changed and os.path.isfile(dest):
            with open(dest, "rb") as fh:
                fd = fh.fileno()
                sha, md5 = file_digests(fd, os.fstat(fd).st_size)
            req["if_sha256"] = sha
            if kind_of(name) == "map":
                req["if_md5"] = md5
        resp = self._request(FrameType.GET, req, (FrameType.OFFER, FrameType.NOT_MODIFIED))
        d = resp.json()
        offer = Offer.from_json(d)
        if offer.name != name:
            raise LocalTransferError(f"asked for {name!r}, the robot offered {offer.name!r}")
        base = {**offer.json(), "host": self.host, "path": dest}
        if resp.type == FrameType.NOT_MODIFIED:
            return {
                **base,
                "modified": False,
                "chunks_received": 0,
                "chunks_resumed": 0,
                "seconds": round(time.monotonic() - t0, 4),
                "mb_per_s": None,
            }
        validate = validate_map_file if kind_of(local) == "map" and kind_of(name) == "map" else None
        store = PartialFile.open(folder, local, offer, validate=validate)
        w = d.get("window")
        rx = Receiver(
            offer,
            ref=resp.ref,
            have=store.have,
            window=max(self.window * 4, 64),
            idle_timeout=max(self.timeout, 60.0),
            sender_window=w if isinstance(w, int) else None,
        )
        tick = _Ticker(progress, offer.size, _attr(rx, "bytes_received"), self.progress_interval)
        ok = False

        def on_events() -> list[Any]:
            return store.take(rx)

        try:
            store.start_writer()
            self.link.send(rx.accept(time.monotonic()))
            self.link.send(on_events())
            run(self.link, rx, start=False, on_events=on_events, tick=tick)
            ok = True
            tick(force=True)
        finally:
            if not ok:
                store.close(keep=True)
        dt = time.monotonic() - t0
        return {
            **base,
            "modified": True,
            "chunks_received": offer.chunks - store.resumed,
            "chunks_resumed": store.resumed,
            "seconds": round(dt, 4),
            "mb_per_s": round(offer.size / dt / 1e6, 2) if dt else None,
        }

    def list(self) -> dict[str, Any]:
        """The robot's maps:
        ``{"maps": [{name, size, md5, sha256, mtime, kind, active}], "active", ...}``.

        Raises:
            Rejected: The robot does not serve listings (a ``mapkit receive`` terminal).
        """
        d = self._request(FrameType.LIST, {}, (FrameType.LISTING,)).json()
        maps = d.get("maps") if isinstance(d.get("maps"), list) else []
        for m in maps:  # never trust names from the wire
            check_name(m.get("name") if isinstance(m, dict) else None, suffixes=None)
        return dict(d)

    def load(
        self, name: str | None = None, *, md5: str | None = None, rollback: bool = False
    ) -> dict[str, Any]:
        """Make ``name`` the robot's active map (it checks MD5 and parses it first), or roll back.

        Args:
            name: Map name on the robot.
            md5: Expected MD5; None uses the MD5 the robot lists for ``name`` right now.
            rollback: Re-activate the previous map instead.

        Returns:
            The robot's new active-map record.

        Raises:
            Rejected: Not found, MD5 mismatch, not a valid map.
        """
        if rollback:
            return dict(
                self._request(FrameType.LOAD, {"rollback": True}, (FrameType.LOADED,)).json()
            )
        if name is None:
            raise LocalTransferError("load needs a map name")
        if md5 is None:
            for m in self.list().get("maps", []):
                if m.get("name") == name:
                    md5 = m.get("md5")
            if md5 is None:
                raise Rejected(
                    int(Status.NOT_FOUND),
                    "not_found",
                    f"{name}: no such map on this robot",
                    peer="robot",
                )
        return dict(
            self._request(FrameType.LOAD, {"name": name, "md5": md5}, (FrameType.LOADED,)).json()
        )

    def close(self) -> None:
        """Say BYE and close the connection."""
        if not self.link.closed:
            with contextlib.suppress(TransferError):
                self._request(FrameType.BYE, {}, (FrameType.BYE,))
            self.link.close()

    def __enter__(self) -> Client:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def send_file(
    path: str | os.PathLike[str],
    host: str,
    port: int = DEFAULT_PORT,
    *,
    name: str | None = None,
    load: bool = False,
    progress: Progress | None = None,
    **options: Any,
) -> dict[str, Any]:
    """Push a file to a robot (one session); with ``load`` also make it the active map.

    ``options`` are :class:`Client` arguments (``secret``, ``insecure``, ``tls``, ``timeout``...).
    """
    with Client(host, port, **options) as c:
        result = c.send(path, name=name, progress=progress)
        if load:
            result["loaded"] = c.load(result["name"], md5=result.get("md5"))
        return result


def fetch_file(
    host: str,
    name: str,
    dest: str | os.PathLike[str] | None = None,
    port: int = DEFAULT_PORT,
    *,
    if_changed: bool = False,
    progress: Progress | None = None,
    **options: Any,
) -> dict[str, Any]:
    """Pull a map from a robot into ``dest`` (default: ``name`` in the current folder)."""
    with Client(host, port, **options) as c:
        return c.fetch(name, dest or name, if_changed=if_changed, progress=progress)


def list_maps(host: str, port: int = DEFAULT_PORT, **options: Any) -> dict[str, Any]:
    """A robot's map listing."""
    with Client(host, port, **options) as c:
        return c.list()


def load_map(
    host: str,
    name: str | None,
    port: int = DEFAULT_PORT,
    *,
    md5: str | None = None,
    rollback: bool = False,
    **options: Any,
) -> dict[str, Any]:
    """Make a map active on a robot (or roll back)."""
    with Client(host, port, **options) as c:
        return c.load(name, md5=md5, rollback=rollback)


def receive_files(
    folder: str | os.PathLike[str],
    host: str = "0.0.0.0",
    port: int = DEFAULT_PORT,
    *,
    count: int = 1,
    timeout: float | None = None,
    on_listening: Callable[[tuple[str, int]], None] | None = None,
    **options: Any,
) -> list[dict[str, Any]]:
    """Wait for peers to push files into ``folder`` (the terminal side of ``mapkit receive``).

    Runs a push-only :class:`~mapkit.transfer.server.MapServer` until ``count`` files arrived or
    ``timeout`` seconds passed. ``options`` are :class:`MapServer` arguments (``secret``,
    ``insecure``, ``tls``...).

    Returns:
        One record per received file:
        ``{"name", "size", "sha256", "md5", "peer", "resumed", "path"}``.

    Examples:
        >>> import tempfile, threading, pathlib
        >>> inbox, src = pathlib.Path(tempfile.mkdtemp()), pathlib.Path(tempfile.mkdtemp()) / "s.2d"
        >>> _ = src.write_bytes(b"laser")
        >>> def robot(addr):
        ...     kw = {"insecure": True}
        ...     threading.Thread(target=send_file, args=(src, *addr), kwargs=kw).start()
        >>> got = receive_files(inbox, "127.0.0.1", 0, insecure=True, on_listening=robot)
        >>> [r["name"] for r in got]
        ['s.2d']
    """
    import threading

    from mapkit.transfer.server import MapServer

    got: list[dict[str, Any]] = []
    done = threading.Event()

    def received(info: dict[str, Any]) -> None:
        got.append(info)
        if len(got) >= count:
            done.set()

    with MapServer(
        folder, host=host, port=port, push_only=True, on_received=received, **options
    ) as srv:
        if on_listening is not None:
            on_listening(srv.address)
        done.wait(timeout)
    return got
