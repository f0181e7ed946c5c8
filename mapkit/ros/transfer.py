"""Map transfer over ROS 1 topics: MKT/1 sessions between robot nodes and terminals.

The protocol is :mod:`mapkit.transfer.protocol` (frames, handshake, sender/receiver machines),
the robot's folder of maps is :class:`mapkit.transfer.server.MapFolder` and received files go
through :class:`mapkit.transfer.store.PartialFile` (temp file, resume journal, SHA-256 check,
atomic rename), exactly as over TCP. This module only drives those machines over a lossy,
duplicating message bus (:class:`~mapkit.ros.transport.RosLink`):

* every session has its own :class:`~mapkit.transfer.protocol.Channel` in unordered mode (lost,
  repeated and foreign frames are dropped and counted; the machines resend);
* the robot side keeps each session's last answer and its finished transfer, so a repeated
  request (its answer was lost) gets the same answer again instead of a second action;
* sessions are demultiplexed by the session id in the frame header; one process runs them all
  in one thread (the machines do no I/O; the file writes are short).

Robot side: :class:`RobotNode` (``mapkit ros receive`` and ``mapkit ros serve``) announces itself
on the channel's latched ``announce`` topic and answers push (OFFER), pull (GET), LIST and LOAD.
Terminal side: :func:`push` (to every robot of a fleet at once), :func:`fetch`, :func:`list_maps`,
:func:`load_map`, and :func:`discover` to see who is there.
"""

from __future__ import annotations

import contextlib
import logging
import os
import secrets
import socket
import time
from collections.abc import Callable, Generator, Iterable
from dataclasses import dataclass, field
from typing import Any

from mapkit.errors import LocalTransferError, TransferError
from mapkit.ros.errors import RosError
from mapkit.ros.node import ros_import, rospy, wait_until
from mapkit.ros.transport import DEFAULT_WINDOW, RosLink
from mapkit.transfer.admission import Admission
from mapkit.transfer.protocol import (
    DEFAULT_CHUNK_SIZE,
    MAGIC,
    MAX_CHUNK_SIZE,
    AuthenticationError,
    Channel,
    ClientHandshake,
    Damaged,
    Frame,
    FrameType,
    Offer,
    Out,
    ProtocolError,
    Receiver,
    Rejected,
    Request,
    Sender,
    ServerHandshake,
    Status,
    dump_json,
    kind_of,
    reject_out,
)
from mapkit.transfer.server import DEFAULT_PARTIAL_TTL, MapFolder, same_transfer
from mapkit.transfer.store import PartialFile, StoreError

__all__ = [
    "PushResult",
    "Robot",
    "RobotNode",
    "Terminal",
    "discover",
    "fetch",
    "list_maps",
    "load_map",
    "push",
]

log = logging.getLogger(__name__)

#: Seconds a finished or silent session is kept on the robot (to answer repeats), then dropped.
LINGER = 30.0
#: An unfinished push whose sender is silent this long may be taken over by a new session.
STALE = 3.0
FEATURES_RECEIVE = ("push", "load")
FEATURES_SERVE = ("push", "pull", "list", "load")


def _session_id(data: bytes) -> int | None:
    if len(data) >= 16 and data[:4] == MAGIC:
        return int.from_bytes(data[8:16], "big")
    return None


class _Conn:
    """One session's channel and the node at the other end of it."""

    def __init__(self, link: RosLink, peer: str, channel: Channel) -> None:
        self.link = link
        self.peer = peer
        self.channel = channel

    def send(self, outs: Iterable[Out]) -> None:
        for o in outs:
            self.link.send(self.peer, self.channel.encode(o))

    def events(self, data: bytes) -> list[Frame | Damaged]:
        self.channel.receive_message(data)
        out: list[Frame | Damaged] = []
        while True:
            try:
                ev = self.channel.next_event()
            except AuthenticationError:
                raise  # a handshake frame made with another secret: the session ends
            except ProtocolError as err:  # a frame this side cannot take: drop the message
                log.warning("%s: dropped a frame: %s", self.peer, err)
                return out
            if ev is None:
                return out
            out.append(ev)


# -- robot side -------------------------------------------------------------------------------


class _RobotSession:
    """The robot's side of one session: handshake, then requests one at a time."""

    def __init__(self, node: RobotNode, conn: _Conn, now: float) -> None:
        self.node = node
        self.conn = conn
        info = {"max_chunk": MAX_CHUNK_SIZE, "max_size": node.folder.max_size,
                "features": list(node.features)}
        self.hs = ServerHandshake(conn.channel, node.secret, insecure=node.insecure,
                                  peer=node.robot, info=info,
                                  idle_timeout=node.idle_timeout)
        self.hs.start(now)
        self.active: Sender | Receiver | None = None
        self.dest: PartialFile | None = None
        self.fd: int | None = None
        self.answers: dict[tuple[int, int], list[Out]] = {}
        self.last = now
        self._checkpointed = now
        self.closed = False

    @property
    def client(self) -> str:
        return str(self.hs.client.get("peer") or self.conn.peer)

    def feed(self, data: bytes, now: float) -> None:
        try:
            events = self.conn.events(data)
        except AuthenticationError as err:
            log.warning("%s: refused: %s", self.conn.peer, err)
            self.closed = True
            self.conn.send([reject_out(err, plain=True)])  # untagged: the client has other keys
            return
        for ev in events:
            self.last = now
            try:
                self.conn.send(self._handle(ev, now))
            except TransferError as err:  # anything a request raises is told to the client
                ref = ev.ref if isinstance(ev, Frame) else 0
                log.warning("%s: %s", self.client, err)
                self.conn.send([reject_out(err, ref)])
            except Exception as err:  # a bug met by this request: tell the client, end the session
                log.exception("%s: internal error", self.client)
                self.closed = True
                self._release()
                self.conn.send([reject_out(err, ev.ref if isinstance(ev, Frame) else 0)])
                return

    def _handle(self, ev: Frame | Damaged, now: float) -> list[Out]:
        if not self.hs.finished:
            out = self.hs.handle(ev, now)
            if self.hs.error is not None:
                log.warning("%s: refused: %s", self.conn.peer, self.hs.error)
                self.closed = True
            elif self.hs.finished:
                log.info("%s: session %016x (auth %s)", self.client, self.conn.channel.session,
                         self.hs.auth)
            return out
        if self.hs.error is not None or self.closed:
            return []
        if isinstance(ev, Damaged):
            return self._to_active(ev, now) if isinstance(self.active, Receiver) else []
        t = ev.type
        if t not in FrameType._value2member_map_:
            return []  # an unknown type on a message transport is ignored (spec, section 3)
        if t == FrameType.HELLO:
            return self.hs.handle(ev, now)  # our HELLO_ACK was lost: the same answer again
        if t == FrameType.AUTH:
            return self.hs.resend(ev)
        if t == FrameType.PING:
            return [Out(FrameType.PONG, ev.payload, ref=ev.ref)]
        if t == FrameType.BYE:
            self.closed = True
            self._release()
            return [Out(FrameType.BYE, b"{}", ref=ev.ref)]
        if t in (FrameType.DATA, FrameType.DONE):  # a push: to our receiver
            return self._to_active(ev, now) if isinstance(self.active, Receiver) else []
        if t in (FrameType.ACCEPT, FrameType.ACK, FrameType.VERIFIED):  # a pull: to our sender
            return self._to_active(ev, now) if isinstance(self.active, Sender) else []
        if t in (FrameType.REJECT, FrameType.CANCEL):
            return self._to_active(ev, now) if self.active is not None else []
        key = (t, ev.ref)
        if key in self.answers:  # a repeated request: its answer was lost
            return self.answers[key]
        active = self.active
        if active is not None and active.ref == ev.ref and t in (FrameType.OFFER, FrameType.GET):
            return self._to_active(ev, now)
        try:
            out = self._request(ev, now)
        except TransferError as err:
            out = [reject_out(err, ev.ref)]
            log.warning("%s: %s refused: %s", self.client, FrameType(t).name, err)
        if t not in (FrameType.OFFER, FrameType.GET) or (out and out[0].type == FrameType.REJECT):
            self.answers[key] = out
        return out

    def _request(self, f: Frame, now: float) -> list[Out]:
        t, feats = f.type, self.node.features
        if t == FrameType.OFFER and "push" in feats:
            return self._push(f, now)
        if t == FrameType.GET and "pull" in feats:
            return self._pull(f, now)
        if t == FrameType.LIST and "list" in feats:
            return [Out(FrameType.LISTING, dump_json(self.node.folder.listing()), ref=f.ref)]
        if t == FrameType.LOAD and "load" in feats:
            d = f.json()
            md5 = d.get("md5") if isinstance(d.get("md5"), str) else None
            state = self.node.load(d.get("name"), md5, rollback=bool(d.get("rollback")))
            log.info("%s: loaded %s", self.client, state["name"])
            return [Out(FrameType.LOADED, dump_json(state), ref=f.ref)]
        if t in (FrameType.OFFER, FrameType.GET, FrameType.LIST, FrameType.LOAD):
            raise ProtocolError(f"this robot node does not serve {FrameType(t).name} (it offers "
                                f"{', '.join(feats)})", Status.UNSUPPORTED)
        raise ProtocolError(f"unexpected frame type {t} between requests")

    def _release(self) -> None:
        if self.dest is not None:
            with contextlib.suppress(OSError, TransferError):
                self.dest.close(keep=True)
            self.dest = None
        if self.fd is not None:
            with contextlib.suppress(OSError):
                os.close(self.fd)
            self.fd = None

    def abort(self, why: str) -> None:
        """Give up the current transfer (keeping the partial file for a resume)."""
        if self.active is not None and not self.active.finished:
            self.conn.send(self.active.fail(LocalTransferError(why)))
        self._release()

    def _push(self, f: Frame, now: float) -> list[Out]:
        offer = Offer.from_json(f.json())
        self._release()
        try:
            dest = self.node.folder.begin_write(offer)
        except StoreError as err:
            if err.status != Status.BUSY or not self.node.take_over(self, offer, now):
                raise
            dest = self.node.folder.begin_write(offer)
        self.dest = dest
        # ack every quarter of the sender's window, so that the pipe never runs dry
        rx = Receiver(offer, ref=f.ref, have=dest.have, window=max(4 * self.node.window, 64),
                      ack_every=max(1, self.node.window // 4), idle_timeout=self.node.idle_timeout)
        self.active = rx
        if dest.resumed:
            log.info("%s: resuming %s with %d of %d chunks", self.client, offer.name, dest.resumed,
                     offer.chunks)
        return rx.accept(now) + self._rx_events(now)

    def _rx_events(self, now: float) -> list[Out]:
        rx, dest = self.active, self.dest
        assert isinstance(rx, Receiver)
        if dest is None:
            return []
        out = dest.take(rx)  # store the chunks; at the end check, publish, answer VERIFIED
        if rx.finished:
            self.dest = None
            if rx.error is not None:
                log.warning("%s: %s failed: %s", self.client, rx.offer.name, rx.error)
                self._release()
                dest.close(keep=True)
            else:
                log.info("%s: received %s (%d bytes, SHA-256 %s, %d chunks resumed)", self.client,
                         rx.offer.name, rx.offer.size, rx.offer.sha256, dest.resumed)
                o = rx.offer
                self.node.received({"name": o.name, "size": o.size, "sha256": o.sha256,
                                    "md5": o.md5, "robot": self.node.robot, "peer": self.client,
                                    "resumed": dest.resumed})
        return out

    def _pull(self, f: Frame, now: float) -> list[Out]:
        d = f.json()
        name = d.get("name")
        cs = d.get("chunk_size", DEFAULT_CHUNK_SIZE)
        cs = min(cs, MAX_CHUNK_SIZE) if isinstance(cs, int) and cs > 0 else DEFAULT_CHUNK_SIZE
        self._release()
        fd, offer = self.node.folder.open_read(name if isinstance(name, str) else "", chunk_size=cs)
        if (d.get("if_md5") and d.get("if_md5") == offer.md5) or \
                (d.get("if_sha256") and d.get("if_sha256") == offer.sha256):
            os.close(fd)
            out = [Out(FrameType.NOT_MODIFIED, dump_json(offer.json()), ref=f.ref)]
            self.answers[(f.type, f.ref)] = out
            return out
        self.fd = fd

        def read(i: int) -> bytes:
            return os.pread(fd, offer.chunk_len(i), i * offer.chunk_size)

        tx = Sender(offer, read, ref=f.ref, window=self.node.window, rto=self.node.rto,
                    idle_timeout=self.node.idle_timeout)
        self.active = tx
        return tx.start(now)

    def _to_active(self, ev: Frame | Damaged, now: float) -> list[Out]:
        m = self.active
        assert m is not None
        was_finished = m.finished
        out = m.handle(ev, now)
        if isinstance(m, Receiver):
            # the ack leaves first: checking a whole file can take longer than the sender waits
            self.conn.send(out)
            out = self._rx_events(now)
        if m.finished and not was_finished:
            self._ended(m)
        return out

    def _ended(self, m: Sender | Receiver) -> None:
        if m.error is not None:
            log.warning("%s: transfer of %s failed: %s", self.client, m.offer.name, m.error)
        elif isinstance(m, Sender):
            log.info("%s: sent %s (%d chunks sent, %d skipped)", self.client, m.offer.name,
                     m.chunks_sent, m.chunks_skipped)
        if isinstance(m, Sender) or m.error is not None:
            self._release()

    def poll(self, now: float) -> None:
        m = self.active
        if m is not None and not m.finished:
            self.conn.send(m.poll(now))
            if m.finished:
                self._ended(m)
        dest = self.dest
        if dest is not None and now - self._checkpointed >= dest.checkpoint_interval:
            # also when the link stalls: what is on disk is in the journal, ready for a resume
            self._checkpointed = now
            try:
                dest.checkpoint()
            except TransferError as err:
                log.warning("%s: %s", self.client, err)

    def deadline(self) -> float | None:
        m = self.active
        dl = m.deadline() if m is not None and not m.finished else None
        if self.dest is not None:
            ck = self._checkpointed + self.dest.checkpoint_interval
            dl = ck if dl is None else min(dl, ck)
        return dl


class RobotNode:
    """The robot side of a channel: a folder of maps served to terminals over ROS topics.

    Args:
        folder: The maps folder (received files land here; pulls and loads read from it).
        link: A robot-side :class:`RosLink`.
        robot: This robot's name (shown to terminals and in the fleet table).
        secret: The shared secret (the same as for TCP), or None with ``insecure``.
        insecure: Accept terminals without authentication.
        features: What to serve: ``("push", "load")`` for ``receive``, all four for ``serve``.
        map_server: The ``nav_msgs/LoadMap`` service to call after a load (a running
            ``mapkit ros map-server`` republishes ``/map``); None to call none.
        idle_timeout: Seconds without a frame before a transfer is given up.
        on_received: Called with the VERIFIED info of each file received.
    """

    def __init__(self, folder: MapFolder, link: RosLink, *, robot: str = "",
                 secret: bytes | None = None, insecure: bool = False,
                 features: Iterable[str] = FEATURES_SERVE, map_server: str | None = "change_map",
                 idle_timeout: float = 30.0, window: int = DEFAULT_WINDOW, rto: float = 1.0,
                 on_received: Callable[[dict[str, Any]], None] | None = None,
                 handshake_timeout: float = 5.0, max_sessions: int = 64, max_pending: int = 32,
                 per_node: int = 8, partial_ttl: float = DEFAULT_PARTIAL_TTL,
                 sweep_interval: float = 60.0) -> None:
        if secret is None and not insecure:
            raise LocalTransferError("no shared secret: give --secret-file or MAPKIT_SECRET, or "
                                     "--insecure to accept anyone")
        self.folder = folder
        self.link = link
        self.robot = robot or socket.gethostname()
        self.secret = secret
        self.insecure = insecure
        self.features = tuple(features)
        self.map_server = map_server
        self.idle_timeout = idle_timeout
        self.window = window
        self.rto = rto
        self.on_received = on_received
        self.sessions: dict[int, _RobotSession] = {}
        self.received_count = 0
        # sessions still in their handshake are bounded per sending node and in all, and end
        # at their deadline: a flood of HELLOs cannot fill the robot's memory or its slots
        self.handshake_timeout = handshake_timeout
        self.admission = Admission(max_sessions=max_sessions, max_pending=max_pending,
                                   per_address=per_node, handshake_timeout=handshake_timeout)
        # interrupted transfers nobody resumed for partial_ttl seconds are deleted
        self.partial_ttl = partial_ttl
        self.sweep_interval = sweep_interval
        self._next_sweep = 0.0

    # announcement ----------------------------------------------------------------------------
    def announcement(self) -> dict[str, Any]:
        """What this node announces (latched): who it is, what it serves, its maps."""
        doc: dict[str, Any] = {"robot": self.robot, "node": self.link.node,
                               "features": list(self.features), "auth": self.secret is not None}
        if "list" in self.features:
            listing = self.folder.listing()
            keys = ("name", "size", "sha256", "md5")
            doc["maps"] = [{k: m[k] for k in keys} for m in listing["maps"]]
            doc["active"] = listing.get("active")
            doc["active_md5"] = listing.get("active_md5")
        return doc

    def announce(self) -> None:
        """Publish the announcement again (after a change)."""
        self.link.announce(self.announcement())

    # hooks -----------------------------------------------------------------------------------
    def received(self, info: dict[str, Any]) -> None:
        self.received_count += 1
        if self.on_received is not None:
            self.on_received(info)
        self.announce()

    def load(self, name: Any, md5: str | None, *, rollback: bool = False) -> dict[str, Any]:
        """Activate a map in the folder, then tell the map server (``change_map``) if one runs."""
        state = self.folder.load(name, md5, rollback=rollback)
        state["map_server"] = self._tell_map_server(os.path.join(self.folder.root, "active.map"))
        self.announce()
        return state

    def _tell_map_server(self, path: str) -> int | None:
        if not self.map_server:
            return None
        rp, srv = rospy(), ros_import("nav_msgs.srv")
        try:
            rp.wait_for_service(self.map_server, timeout=0.5)
        except rp.ROSException:
            return None
        try:
            return int(rp.ServiceProxy(self.map_server, srv.LoadMap)(map_url=path).result)
        except (rp.ServiceException, rp.ROSException) as err:
            log.warning("the map server (%s) failed: %s", self.map_server, err)
            return 255

    def take_over(self, new: _RobotSession, offer: Offer, now: float) -> bool:
        """Let ``new`` take a name another session is still writing, when that one is stale
        (its sender restarted: the same file offered again, the same client name, or silent
        for a few seconds)."""
        name = offer.name
        for s in self.sessions.values():
            if s is new or s.dest is None or s.dest.name != name:
                continue
            if same_transfer(s.dest.offer, offer) or s.client == new.client \
                    or now - s.last >= STALE:
                log.info("%s: taking over %s from a silent session of %s", new.client, name,
                         s.client)
                s.abort(f"taken over by a new session of {new.client}")
                return True
        return False

    # the loop --------------------------------------------------------------------------------
    def step(self, timeout: float) -> None:
        """Handle what arrives within ``timeout`` seconds, then the timers."""
        now = time.monotonic()
        dls = [d for d in (s.deadline() for s in self.sessions.values()) if d is not None]
        wait = max(0.0, min([timeout, *(d - now for d in dls)]))
        item = self.link.receive(wait)
        while item is not None:
            try:
                self._dispatch(*item)
            except Exception:  # no message may end the node: drop its session, go on
                self._failed(_session_id(item[1]), "a message")
            item = self.link.receive(0)
        now = time.monotonic()
        if now >= self._next_sweep:
            self._next_sweep = now + self.sweep_interval
            try:
                for name in self.folder.expire_partials(self.partial_ttl):
                    log.info("deleted the abandoned partial file of %s", name)
            except OSError as err:
                log.warning("cannot sweep %s for abandoned partial files: %s", self.folder.root,
                            err)
        for sid in self.admission.expired(now):
            self._forget(sid, f"no handshake within {self.handshake_timeout:g} s")
        for sid, s in list(self.sessions.items()):
            try:
                s.poll(now)
            except Exception:
                self._failed(sid, "a timer")
                continue
            if s.closed or now - s.last > max(LINGER, self.idle_timeout):
                s._release()
                del self.sessions[sid]
                self.admission.release(sid)

    def _forget(self, sid: Any, why: str) -> None:
        s = self.sessions.pop(sid, None)
        self.admission.release(sid)
        if s is not None:
            log.info("%s: session %016x dropped: %s", s.conn.peer, sid, why)
            s.closed = True
            s._release()

    def _failed(self, sid: int | None, what: str) -> None:
        """Log an unexpected error met while handling ``what`` of session ``sid``, tell the
        client (REJECT ``internal``, untagged) and forget the session (its partial file stays)."""
        log.exception("internal error while handling %s of session %s", what,
                      "?" if sid is None else f"{sid:016x}")
        s = self.sessions.pop(sid, None) if sid is not None else None
        if sid is not None:
            self.admission.release(sid)
        if s is not None:
            s.closed = True
            with contextlib.suppress(Exception):
                s._release()
            with contextlib.suppress(Exception):
                s.conn.send([reject_out(LocalTransferError("internal error on the robot"),
                                        plain=True)])

    def _dispatch(self, src: str, data: bytes) -> None:
        sid = _session_id(data)
        if sid is None:
            return
        now = time.monotonic()
        s = self.sessions.get(sid)
        if s is None:
            if len(data) < 6 or data[5] != FrameType.HELLO:
                return  # a frame of a session we forgot (or never had)
            conn = _Conn(self.link, src, Channel(initiator=False, ordered=False))
            s = _RobotSession(self, conn, now)
            self.sessions[sid] = s
            for old in self.admission.admit(sid, src, now):
                self._forget(old, "evicted: too many sessions in their handshake")
        elif s.conn.peer != src:
            return  # another node using this session id
        was_open = s.hs.finished and s.hs.error is None
        s.feed(data, now)
        if not was_open and s.hs.finished and s.hs.error is None \
                and not self.admission.authenticated(sid):
            log.warning("%s: refused: %d sessions already", s.conn.peer,
                        self.admission.max_sessions)
            s.conn.send([reject_out(StoreError(f"this robot serves {self.admission.max_sessions} "
                                               "sessions already; try again later", Status.BUSY))])
            self._forget(sid, "too many sessions")

    def run(self, until: Callable[[], bool] | None = None) -> None:
        """Serve until rospy shuts down (Ctrl-C, SIGTERM) or ``until()`` is true."""
        rp = rospy()
        self.announce()
        try:
            while not rp.is_shutdown() and not (until is not None and until()):
                self.step(0.2)
        finally:
            for s in self.sessions.values():
                s._release()


# -- terminal side ----------------------------------------------------------------------------

Script = Generator[Any, None, None]


class _ClientSession:
    """A terminal's session with one robot node, driven by a script (a generator of machines)."""

    def __init__(self, link: RosLink, robot_node: str, secret: bytes | None, peer: str,
                 idle_timeout: float = 30.0, rto: float = 1.0) -> None:
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
        return ClientHandshake(self.conn.channel, self.secret, peer=self.peer, rto=self.rto,
                               idle_timeout=self.idle_timeout)

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


def _drive(link: Any, sessions: list[_ClientSession], *, tick: Callable[[], None] | None = None,
           stopped: Callable[[], bool] | None = None) -> None:
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
class Robot:
    """A robot node seen on the channel (from its latched announcement)."""

    robot: str
    node: str
    features: list[str]
    doc: dict[str, Any]


def _robot_from(doc: dict[str, Any]) -> Robot | None:
    if isinstance(doc.get("node"), str) and isinstance(doc.get("features"), list):
        features = [str(f) for f in doc["features"]]
        return Robot(str(doc.get("robot", doc["node"])), doc["node"], features, doc)
    return None


class Watcher:
    """A client link that collects robot announcements as they arrive (latched: late joiners
    see them too)."""

    def __init__(self, channel: str, *, window: int = DEFAULT_WINDOW,
                 chunk_size: int = DEFAULT_CHUNK_SIZE) -> None:
        self.robots: dict[str, Robot] = {}
        self.link = RosLink(channel, robot=False, window=window, chunk_size=chunk_size,
                            on_announce=self._on)

    def _on(self, doc: dict[str, Any]) -> None:
        r = _robot_from(doc)
        if r is not None:
            self.robots[r.node] = r

    def publishers(self) -> int:
        """Nodes the master lists as publishing the announcement (stale ones included)."""
        rp = rospy()
        topic = rp.resolve_name(self.link.topics["announce"])
        try:
            pubs = rp.get_master().getSystemState()[2][0]
        except Exception:  # the master's answer is only a hint here
            return 0
        return sum(len(nodes) for name, nodes in pubs if name == topic)

    def wait(self, *, timeout: float, expect: int = 0, feature: str | None = None,
             names: Iterable[str] = ()) -> list[Robot]:
        """Robots announced within ``timeout`` (sooner once every announcing node, or ``expect``
        of them, or all ``names``, were heard), filtered by ``feature`` and ``names``."""
        want = set(names)

        def pick() -> list[Robot]:
            rs = [r for r in self.robots.values() if feature is None or feature in r.features]
            return [r for r in rs if not want or r.robot in want]

        def enough() -> bool:
            got = pick()
            if want:
                return {r.robot for r in got} >= want
            if expect:
                return len(got) >= expect
            n = self.publishers()
            return bool(n) and len(self.robots) >= n

        wait_until(enough, timeout, 0.05)
        robots = sorted(pick(), key=lambda r: r.robot)
        # make sure the frame topics are connected to every robot before the first frame
        self.link.wait_connected(len(robots), timeout=5.0)
        return robots


def discover(channel: str, *, timeout: float = 3.0,
             feature: str | None = None) -> list[dict[str, Any]]:
    """The announcements of the robot nodes on ``channel`` (the node must be started)."""
    w = Watcher(channel)
    try:
        return [r.doc for r in w.wait(timeout=timeout, feature=feature)]
    finally:
        w.link.close()


def _one_robot(w: Watcher, robot: str | None, feature: str, timeout: float) -> Robot:
    robots = w.wait(timeout=timeout, feature=feature, names=[robot] if robot else ())
    if not robots:
        who = f"robot {robot!r}" if robot else "robot node"
        raise RosError(f"no {who} serving {feature!r} on channel {w.link.channel!r} "
                       f"(topic {rospy().resolve_name(w.link.topics['announce'])}); is "
                       "`mapkit ros serve` running there?")
    if len(robots) > 1:
        raise RosError("several robots serve this channel: " + ", ".join(r.robot for r in robots)
                       + "; choose one with --robot")
    return robots[0]


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

    def __init__(self, link: Any, secret: bytes | None, *, peer: str = "",
                 idle_timeout: float = 30.0, rto: float = 1.0,
                 stopped: Callable[[], bool] | None = None) -> None:
        self.link = link
        self.secret = secret
        self.peer = peer or socket.gethostname()
        self.idle_timeout = idle_timeout
        self.rto = rto
        self.stopped = stopped

    def _session(self, robot: Robot) -> _ClientSession:
        return _ClientSession(self.link, robot.node, self.secret, self.peer, self.idle_timeout,
                              self.rto)

    def push(self, robots: list[Robot], data: bytes, offer: Offer, *, load: bool = False,
             window: int = DEFAULT_WINDOW,
             progress: Callable[[int, int], None] | None = None) -> list[PushResult]:
        """Push ``data`` (described by ``offer``) to every robot at once; one result each."""
        view = memoryview(data)
        cs = offer.chunk_size
        results, sessions, senders = [], [], []
        for r in robots:
            res = PushResult(r.robot, r.node)
            s = self._session(r)
            tx = Sender(offer, lambda i: view[i * cs:(i + 1) * cs], ref=1, window=window,
                        rto=self.rto, idle_timeout=self.idle_timeout)
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

    def request(self, robot: Robot, ftype: FrameType, payload: dict[str, Any],
                answers: Iterable[FrameType]) -> Frame:
        """One request (LIST, LOAD ...) in its own session; the answering frame.

        Raises:
            RemoteTransferError: When the robot refuses.
            TransferError: When it does not answer.
        """
        s = self._session(robot)
        req = Request(ftype, payload, ref=1, answers=answers, rto=self.rto,
                      idle_timeout=self.idle_timeout)

        def script() -> Script:
            yield s.handshake()
            yield req

        s.begin(script(), time.monotonic())
        _drive(self.link, [s], stopped=self.stopped)
        if s.error is not None:
            raise _named(s.error, robot)
        assert req.response is not None
        return req.response

    def fetch(self, robot: Robot, name: str, dest: str, *, if_changed: bool = True,
              chunk_size: int = DEFAULT_CHUNK_SIZE,
              progress: Callable[[int, int], None] | None = None) -> dict[str, Any]:
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
            get = Request(FrameType.GET, payload, ref=1,
                          answers=[FrameType.OFFER, FrameType.NOT_MODIFIED], rto=self.rto,
                          idle_timeout=self.idle_timeout)
            yield get
            assert get.response is not None
            offer = Offer.from_json(get.response.json())
            if get.response.type == FrameType.NOT_MODIFIED:
                out.update(name=name, path=dest, size=offer.size, sha256=offer.sha256,
                           md5=offer.md5, changed=False, resumed=0)
                return
            offer = Offer(target, offer.size, offer.sha256, offer.chunk_size, offer.md5, offer.kind,
                          offer.mtime)
            dfile = PartialFile.open(folder, target, offer,
                                     validate=validate_map_file if kind_of(name) == "map" else None)
            state["dest"] = dfile
            rx = Receiver(offer, ref=get.response.ref, have=dfile.have, window=64, ack_every=4,
                          idle_timeout=self.idle_timeout)

            def on_events(now: float) -> list[Out]:
                outs = dfile.take(rx)
                if rx.finished and rx.error is None:
                    state["dest"] = None
                    out.update(name=name, path=dest, size=offer.size, sha256=offer.sha256,
                               md5=offer.md5, changed=True, resumed=dfile.resumed)
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


def _push_script(s: _ClientSession, tx: Sender, res: PushResult, robot: Robot, offer: Offer,
                 load: bool) -> Script:
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
        req = Request(FrameType.LOAD, {"name": offer.name, "md5": offer.md5}, ref=2,
                      answers=[FrameType.LOADED], rto=s.rto, idle_timeout=s.idle_timeout)
        try:
            yield req
        except TransferError as err:
            res.loaded, res.error = False, str(_named(err, robot))
            return
        assert req.response is not None
        res.loaded = True
        res.info["load"] = req.response.json()


# -- the ROS-facing terminal functions (the node must be started) ----------------------------


def _terminal(w: Watcher, secret: bytes | None, **kw: Any) -> Terminal:
    rp = rospy()
    return Terminal(w.link, secret, peer=f"{socket.gethostname()}:{rp.get_name()}",
                    stopped=rp.is_shutdown, **kw)


def push(path: str, *, channel: str, secret: bytes | None, name: str | None = None,
         robots: Iterable[str] = (), expect: int = 0, wait: float = 3.0, load: bool = False,
         chunk_size: int = DEFAULT_CHUNK_SIZE, window: int = DEFAULT_WINDOW, rto: float = 1.0,
         idle_timeout: float = 30.0,
         progress: Callable[[int, int], None] | None = None) -> list[PushResult]:
    """Push a file to every robot on ``channel`` that accepts pushes, at once; each verifies it.

    Args:
        path: The file.
        channel: The channel.
        secret: Shared secret, or None for an insecure push.
        name: Name on the robots (default: the file's name).
        robots: Only these robots (by name); all of them must answer.
        expect: Wait for at least this many robots (else the robots heard within ``wait``).
        wait: Seconds to wait for robots to announce themselves.
        load: After verifying, ask each robot to make the map its active one.
        chunk_size: Bytes per DATA frame.
        window: Frames in flight per robot.
        rto: First resend timeout.
        idle_timeout: Give a robot up after this many seconds without a frame from it.
        progress: Called with (bytes acknowledged by all robots together, total bytes).

    Returns:
        One :class:`PushResult` per robot, sorted by robot name.

    Raises:
        RosError: When no robot (or not every named robot, or fewer than ``expect``) is there.
        OSError: When the file cannot be read.
    """
    with open(path, "rb") as fh:
        data = fh.read()
    offer = Offer.for_bytes(name or os.path.basename(path), data, chunk_size=chunk_size,
                            mtime=os.stat(path).st_mtime)
    want = list(robots)
    w = Watcher(channel, window=window, chunk_size=chunk_size)
    try:
        found = w.wait(timeout=wait, expect=expect, feature="push", names=want)
        missing = set(want) - {r.robot for r in found}
        if not found or missing or len(found) < expect:
            extra = f" (missing: {', '.join(sorted(missing))})" if missing else ""
            accept = "robot accepts" if len(found) == 1 else "robots accept"
            raise RosError(f"{len(found)} {accept} pushes on channel {channel!r}{extra}; "
                           f"expected {max(expect, len(want), 1)}. Is `mapkit ros receive` or "
                           "`mapkit ros serve` running there (same channel, same ROS master)?")
        term = _terminal(w, secret, rto=rto, idle_timeout=idle_timeout)
        return term.push(found, data, offer, load=load, window=window, progress=progress)
    finally:
        w.link.close()


def list_maps(channel: str, *, secret: bytes | None, robot: str | None = None,
              timeout: float = 3.0) -> dict[str, Any]:
    """The maps a robot serves (LIST over an authenticated session), with its name."""
    w = Watcher(channel)
    try:
        r = _one_robot(w, robot, "list", timeout)
        f = _terminal(w, secret).request(r, FrameType.LIST, {}, [FrameType.LISTING])
        return {"robot": r.robot, "node": r.node, **f.json()}
    finally:
        w.link.close()


def load_map(name: str, *, channel: str, secret: bytes | None, robot: str | None = None,
             md5: str | None = None, rollback: bool = False,
             timeout: float = 3.0) -> dict[str, Any]:
    """Make a map on the robot its active one (and tell its map server); the new state."""
    payload: dict[str, Any] = {"name": name}
    if md5:
        payload["md5"] = md5
    if rollback:
        payload["rollback"] = True
    w = Watcher(channel)
    try:
        r = _one_robot(w, robot, "load", timeout)
        f = _terminal(w, secret).request(r, FrameType.LOAD, payload, [FrameType.LOADED])
        return {"robot": r.robot, **f.json()}
    finally:
        w.link.close()


def fetch(name: str, dest: str, *, channel: str, secret: bytes | None, robot: str | None = None,
          if_changed: bool = True, chunk_size: int = DEFAULT_CHUNK_SIZE, timeout: float = 3.0,
          progress: Callable[[int, int], None] | None = None) -> dict[str, Any]:
    """Pull a map from a robot into ``dest`` (a file path), verified and written atomically.

    With ``if_changed`` nothing is transferred when ``dest`` already has the robot's content.

    Returns:
        ``{"robot", "name", "path", "size", "sha256", "md5", "changed", "resumed"}``.

    Raises:
        RosError: When no robot serves the channel.
        RemoteTransferError: When the robot refuses (no such map, bad name ...).
        TransferError: When the transfer fails (timeout, checksum).
    """
    w = Watcher(channel, chunk_size=chunk_size)
    try:
        r = _one_robot(w, robot, "pull", timeout)
        return _terminal(w, secret).fetch(r, name, dest, if_changed=if_changed,
                                          chunk_size=chunk_size, progress=progress)
    finally:
        w.link.close()
