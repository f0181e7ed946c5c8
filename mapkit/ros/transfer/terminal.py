"""The terminal side: client sessions driven over the bus, and :class:`Terminal`, which runs
pushes, fetches, listings and loads against robots."""

from __future__ import annotations

import contextlib
import os
import secrets
import socket
import time
from collections.abc import Callable, Generator, Iterable
from dataclasses import dataclass, field
from typing import Any

from mapkit.errors import TransferError
from mapkit.ros.errors import RosError
from mapkit.ros.transfer.discovery import Robot
from mapkit.ros.transfer.session import _Conn, _session_id
from mapkit.ros.transport import DEFAULT_WINDOW, RosLink
from mapkit.transfer.protocol import (
    DEFAULT_CHUNK_SIZE,
    AuthenticationError,
    Channel,
    ClientHandshake,
    Frame,
    FrameType,
    Offer,
    Out,
    Receiver,
    Rejected,
    Request,
    Sender,
    kind_of,
)
from mapkit.transfer.store import PartialFile

__all__ = ["PushResult", "Script", "Terminal"]


# -- terminal side ----------------------------------------------------------------------------

Script = Generator[Any, None, None]


class _ClientSession:
    """A terminal's session with one robot node, driven by a script (a generator of machines)."""

    def __init__(
        self,
        link: RosLink,
        robot_node: str,
        secret: bytes | None,
        peer: str,
        idle_timeout: float = 30.0,
        rto: float = 1.0,
    ) -> None:
        channel = Channel(initiator=True, session=secrets.randbits(64) or 1, ordered=False)
        self.conn = _Conn(link, robot_node, channel)
        self.secret = secret
        self.peer = peer
        self.idle_timeout = idle_timeout
        self.rto = rto
        self.machine: Any = None
        self.on_events: Callable[[float], list[Out]] | None = None
        self.script: Script | None = None
        self.done = False
        self.error: BaseException | None = None

    def handshake(self) -> ClientHandshake:
        return ClientHandshake(
            self.conn.channel,
            self.secret,
            peer=self.peer,
            rto=self.rto,
            idle_timeout=self.idle_timeout,
        )

    def begin(self, script: Script, now: float) -> None:
        self.script = script
        self._next(now, None)

    def _next(self, now: float, err: BaseException | None) -> None:
        assert self.script is not None
        try:
            nxt = self.script.throw(err) if err is not None else next(self.script)
        except StopIteration:
            self.done = True
            return
        except (TransferError, RosError) as e:
            self.done, self.error = True, e
            return
        if isinstance(nxt, tuple):
            self.machine, self.on_events = nxt
        else:
            self.machine, self.on_events = nxt, None
        self.conn.send(self.machine.start(now) + self._events(now))
        self._check(now)

    def _events(self, now: float) -> list[Out]:
        return self.on_events(now) if self.on_events is not None else []

    def _check(self, now: float) -> None:
        m = self.machine
        if m is not None and m.finished and not self.done:
            self._next(now, m.error)

    def feed(self, data: bytes, now: float) -> None:
        try:
            events = self.conn.events(data)
        except AuthenticationError as err:
            if self.machine is not None and not self.machine.finished:
                self.machine.fail(err)  # nothing to send: the robot has other keys
                self._check(now)
            return
        for ev in events:
            if self.done or self.machine is None:
                return
            self.conn.send(self.machine.handle(ev, now))
            self.conn.send(self._events(now))
            self._check(now)

    def poll(self, now: float) -> None:
        if not self.done and self.machine is not None:
            self.conn.send(self.machine.poll(now))
            self._check(now)

    def deadline(self) -> float | None:
        return None if self.done or self.machine is None else self.machine.deadline()

    def bye(self) -> None:
        with contextlib.suppress(TransferError):
            self.conn.send([Out(FrameType.BYE, b"{}", ref=0xFFFF)])


def _drive(
    link: Any,
    sessions: list[_ClientSession],
    *,
    tick: Callable[[], None] | None = None,
    stopped: Callable[[], bool] | None = None,
) -> None:
    """Run client sessions until each is done (every machine has its own timeouts)."""
    by_id = {s.conn.channel.session: s for s in sessions}
    while not all(s.done for s in sessions):
        if stopped is not None and stopped():
            raise RosError("ROS shut down during the transfer")
        now = time.monotonic()
        dls = [d for d in (s.deadline() for s in sessions) if d is not None]
        wait = max(0.0, min([0.2, *(d - now for d in dls)]))
        item = link.receive(wait)
        while item is not None:
            src, data = item
            s = by_id.get(_session_id(data))
            if s is not None and s.conn.peer == src:
                s.feed(data, time.monotonic())
            item = link.receive(0)
        now = time.monotonic()
        for s in sessions:
            s.poll(now)
        if tick is not None:
            tick()
    for s in sessions:
        s.bye()


@dataclass
class PushResult:
    """What one robot did with a pushed file (a row of the fleet table)."""

    robot: str
    node: str
    received: bool = False
    verified: bool = False
    loaded: bool | None = None
    skipped: bool = False
    resumed_chunks: int = 0
    chunks_sent: int = 0
    chunks_resent: int = 0
    error: str | None = None
    info: dict[str, Any] = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        """Verified, and loaded when a load was asked for."""
        return self.verified and self.loaded is not False and self.error is None


class Terminal:
    """The terminal's side of a channel once the robots are known: push, fetch and requests.

    The ROS-facing functions (:func:`push`, :func:`fetch`, :func:`list_maps`, :func:`load_map`)
    find the robots from their announcements and use one of these; tests drive it over an
    in-memory bus.

    Args:
        link: The client link (:class:`RosLink` or anything with ``send``/``receive``/``node``).
        secret: Shared secret, or None for an insecure session.
        peer: This terminal's name, shown in the robots' logs.
        idle_timeout: Give a robot up after this many seconds without a frame from it.
        rto: First resend timeout.
        stopped: Returns True when the node is shutting down (then the transfer stops).
    """

    def __init__(
        self,
        link: Any,
        secret: bytes | None,
        *,
        peer: str = "",
        idle_timeout: float = 30.0,
        rto: float = 1.0,
        stopped: Callable[[], bool] | None = None,
    ) -> None:
        self.link = link
        self.secret = secret
        self.peer = peer or socket.gethostname()
        self.idle_timeout = idle_timeout
        self.rto = rto
        self.stopped = stopped

    def _session(self, robot: Robot) -> _ClientSession:
        return _ClientSession(
            self.link, robot.node, self.secret, self.peer, self.idle_timeout, self.rto
        )

    def push(
        self,
        robots: list[Robot],
        data: bytes,
        offer: Offer,
        *,
        load: bool = False,
        window: int = DEFAULT_WINDOW,
        progress: Callable[[int, int], None] | None = None,
    ) -> list[PushResult]:
        """Push ``data`` (described by ``offer``) to every robot at once; one result each."""
        view = memoryview(data)
        cs = offer.chunk_size
        results, sessions, senders = [], [], []
        for r in robots:
            res = PushResult(r.robot, r.node)
            s = self._session(r)
            tx = Sender(
                offer,
                lambda i: view[i * cs : (i + 1) * cs],
                ref=1,
                window=window,
                rto=self.rto,
                idle_timeout=self.idle_timeout,
            )
            s.begin(_push_script(s, tx, res, r, offer, load), time.monotonic())
            results.append(res)
            sessions.append(s)
            senders.append(tx)
        total = offer.size * len(sessions)

        def tick() -> None:
            if progress is not None:
                progress(sum(t.bytes_acked for t in senders), total)

        _drive(self.link, sessions, tick=tick, stopped=self.stopped)
        for s, res, tx, r in zip(sessions, results, senders, robots, strict=True):
            res.chunks_sent, res.chunks_resent = tx.chunks_sent, tx.chunks_resent
            if s.error is not None and res.error is None:
                res.error = str(_named(s.error, r))
        return results

    def request(
        self, robot: Robot, ftype: FrameType, payload: dict[str, Any], answers: Iterable[FrameType]
    ) -> Frame:
        """One request (LIST, LOAD ...) in its own session; the answering frame.

        Raises:
            RemoteTransferError: When the robot refuses.
            TransferError: When it does not answer.
        """
        s = self._session(robot)
        req = Request(
            ftype, payload, ref=1, answers=answers, rto=self.rto, idle_timeout=self.idle_timeout
        )

        def script() -> Script:
            yield s.handshake()
            yield req

        s.begin(script(), time.monotonic())
        _drive(self.link, [s], stopped=self.stopped)
        if s.error is not None:
            raise _named(s.error, robot)
        assert req.response is not None
        return req.response

    def fetch(
        self,
        robot: Robot,
        name: str,
        dest: str,
        *,
        if_changed: bool = True,
        chunk_size: int = DEFAULT_CHUNK_SIZE,
        progress: Callable[[int, int], None] | None = None,
    ) -> dict[str, Any]:
        """Pull ``name`` from ``robot`` into the file ``dest`` (see :func:`fetch`)."""
        from mapkit.transfer.server import validate_map_file
        from mapkit.transfer.store import file_digests

        folder, target = os.path.split(os.path.abspath(dest))
        os.makedirs(folder, exist_ok=True)
        payload: dict[str, Any] = {"name": name, "chunk_size": chunk_size}
        if if_changed and os.path.isfile(dest):
            fd = os.open(dest, os.O_RDONLY)
            try:
                payload["if_sha256"] = file_digests(fd, os.fstat(fd).st_size, md5=False)[0]
            finally:
                os.close(fd)
        s = self._session(robot)
        out: dict[str, Any] = {}
        state: dict[str, Any] = {}

        def script() -> Script:
            yield s.handshake()
            get = Request(
                FrameType.GET,
                payload,
                ref=1,
                answers=[FrameType.OFFER, FrameType.NOT_MODIFIED],
                rto=self.rto,
                idle_timeout=self.idle_timeout,
            )
            yield get
            assert get.response is not None
            offer = Offer.from_json(get.response.json())
            if get.response.type == FrameType.NOT_MODIFIED:
                out.update(
                    name=name,
                    path=dest,
                    size=offer.size,
                    sha256=offer.sha256,
                    md5=offer.md5,
                    changed=False,
                    resumed=0,
                )
                return
            offer = Offer(
                target,
                offer.size,
                offer.sha256,
                offer.chunk_size,
                offer.md5,
                offer.kind,
                offer.mtime,
            )
            dfile = PartialFile.open(
                folder,
                target,
                offer,
                validate=validate_map_file if kind_of(name) == "map" else None,
            )
            state["dest"] = dfile
            rx = Receiver(
                offer,
                ref=get.response.ref,
                have=dfile.have,
                window=64,
                ack_every=4,
                idle_timeout=self.idle_timeout,
            )

            def on_events(now: float) -> list[Out]:
                outs = dfile.take(rx)
                if rx.finished and rx.error is None:
                    state["dest"] = None
                    out.update(
                        name=name,
                        path=dest,
                        size=offer.size,
                        sha256=offer.sha256,
                        md5=offer.md5,
                        changed=True,
                        resumed=dfile.resumed,
                    )
                if progress is not None:
                    progress(rx.bytes_received, offer.size)
                return outs

            yield rx, on_events

        s.begin(script(), time.monotonic())
        try:
            _drive(self.link, [s], stopped=self.stopped)
        finally:
            if state.get("dest") is not None:  # keep what arrived for a resume
                state["dest"].close(keep=True)
        if s.error is not None:
            raise _named(s.error, robot)
        return {"robot": robot.robot, **out}


def _named(err: BaseException, robot: Robot) -> BaseException:
    """A robot's refusal, naming the robot (the protocol core says "server")."""
    if isinstance(err, Rejected):
        named = Rejected(int(err.status), err.reason, err.detail, peer=f"robot {robot.robot!r}")
        named.__cause__ = err
        return named
    return err


def _push_script(
    s: _ClientSession, tx: Sender, res: PushResult, robot: Robot, offer: Offer, load: bool
) -> Script:
    try:
        yield s.handshake()
        yield tx
    except TransferError as err:
        res.received = tx.bytes_acked == offer.size and offer.size > 0
        res.error = str(_named(err, robot))
        return
    res.received = True
    res.skipped = bool(tx.result.get("skipped"))
    res.verified = res.skipped or tx.result.get("sha256") == offer.sha256
    res.resumed_chunks = tx.chunks_skipped
    res.info = dict(tx.result)
    if not res.verified:
        res.error = f"the robot reported SHA-256 {tx.result.get('sha256')}, expected {offer.sha256}"
        return
    if load:
        req = Request(
            FrameType.LOAD,
            {"name": offer.name, "md5": offer.md5},
            ref=2,
            answers=[FrameType.LOADED],
            rto=s.rto,
            idle_timeout=s.idle_timeout,
        )
        try:
            yield req
        except TransferError as err:
            res.loaded, res.error = False, str(_named(err, robot))
            return
        assert req.response is not None
        res.loaded = True
        res.info["load"] = req.response.json()
