"""The robot side: :class:`RobotNode` answers push (OFFER), pull (GET), LIST and LOAD for every
session on the channel."""

from __future__ import annotations

import contextlib
import os
import socket
import time
from collections.abc import Callable, Iterable
from typing import Any

from mapkit.errors import LocalTransferError, TransferError
from mapkit.ros.node import ros_import, rospy
from mapkit.ros.transfer.session import _Conn, _session_id, log
from mapkit.ros.transport import DEFAULT_WINDOW, RosLink
from mapkit.transfer.admission import Admission
from mapkit.transfer.protocol import (
    DEFAULT_CHUNK_SIZE,
    MAX_CHUNK_SIZE,
    AuthenticationError,
    Channel,
    Damaged,
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
from mapkit.transfer.server import DEFAULT_PARTIAL_TTL, MapFolder, same_transfer
from mapkit.transfer.store import PartialFile, StoreError

__all__ = ["FEATURES_RECEIVE", "FEATURES_SERVE", "LINGER", "STALE", "RobotNode"]


#: Seconds a finished or silent session is kept on the robot (to answer repeats), then dropped.
LINGER = 30.0
#: An unfinished push whose sender is silent this long may be taken over by a new session.
STALE = 3.0
FEATURES_RECEIVE = ("push", "load")
FEATURES_SERVE = ("push", "pull", "list", "load")

# -- robot side -------------------------------------------------------------------------------


class _RobotSession:
    """The robot's side of one session: handshake, then requests one at a time."""

    def __init__(self, node: RobotNode, conn: _Conn, now: float) -> None:
        self.node = node
        self.conn = conn
        info = {
            "max_chunk": MAX_CHUNK_SIZE,
            "max_size": node.folder.max_size,
            "features": list(node.features),
        }
        self.hs = ServerHandshake(
            conn.channel,
            node.secret,
            insecure=node.insecure,
            peer=node.robot,
            info=info,
            idle_timeout=node.idle_timeout,
        )
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
                log.info(
                    "%s: session %016x (auth %s)",
                    self.client,
                    self.conn.channel.session,
                    self.hs.auth,
                )
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
            raise ProtocolError(
                f"this robot node does not serve {FrameType(t).name} (it offers "
                f"{', '.join(feats)})",
                Status.UNSUPPORTED,
            )
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
        rx = Receiver(
            offer,
            ref=f.ref,
            have=dest.have,
            window=max(4 * self.node.window, 64),
            ack_every=max(1, self.node.window // 4),
            idle_timeout=self.node.idle_timeout,
        )
        self.active = rx
        if dest.resumed:
            log.info(
                "%s: resuming %s with %d of %d chunks",
                self.client,
                offer.name,
                dest.resumed,
                offer.chunks,
            )
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
                log.info(
                    "%s: received %s (%d bytes, SHA-256 %s, %d chunks resumed)",
                    self.client,
                    rx.offer.name,
                    rx.offer.size,
                    rx.offer.sha256,
                    dest.resumed,
                )
                o = rx.offer
                self.node.received(
                    {
                        "name": o.name,
                        "size": o.size,
                        "sha256": o.sha256,
                        "md5": o.md5,
                        "robot": self.node.robot,
                        "peer": self.client,
                        "resumed": dest.resumed,
                    }
                )
        return out

    def _pull(self, f: Frame, now: float) -> list[Out]:
        d = f.json()
        name = d.get("name")
        cs = d.get("chunk_size", DEFAULT_CHUNK_SIZE)
        cs = min(cs, MAX_CHUNK_SIZE) if isinstance(cs, int) and cs > 0 else DEFAULT_CHUNK_SIZE
        self._release()
        fd, offer = self.node.folder.open_read(name if isinstance(name, str) else "", chunk_size=cs)
        if (d.get("if_md5") and d.get("if_md5") == offer.md5) or (
            d.get("if_sha256") and d.get("if_sha256") == offer.sha256
        ):
            os.close(fd)
            out = [Out(FrameType.NOT_MODIFIED, dump_json(offer.json()), ref=f.ref)]
            self.answers[(f.type, f.ref)] = out
            return out
        self.fd = fd

        def read(i: int) -> bytes:
            return os.pread(fd, offer.chunk_len(i), i * offer.chunk_size)

        tx = Sender(
            offer,
            read,
            ref=f.ref,
            window=self.node.window,
            rto=self.node.rto,
            idle_timeout=self.node.idle_timeout,
        )
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
            log.info(
                "%s: sent %s (%d chunks sent, %d skipped)",
                self.client,
                m.offer.name,
                m.chunks_sent,
                m.chunks_skipped,
            )
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

    def __init__(
        self,
        folder: MapFolder,
        link: RosLink,
        *,
        robot: str = "",
        secret: bytes | None = None,
        insecure: bool = False,
        features: Iterable[str] = FEATURES_SERVE,
        map_server: str | None = "change_map",
        idle_timeout: float = 30.0,
        window: int = DEFAULT_WINDOW,
        rto: float = 1.0,
        on_received: Callable[[dict[str, Any]], None] | None = None,
        handshake_timeout: float = 5.0,
        max_sessions: int = 64,
        max_pending: int = 32,
        per_node: int = 8,
        partial_ttl: float = DEFAULT_PARTIAL_TTL,
        sweep_interval: float = 60.0,
    ) -> None:
        if secret is None and not insecure:
            raise LocalTransferError(
                "no shared secret: give --secret-file or MAPKIT_SECRET, or "
                "--insecure to accept anyone"
            )
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
        self.admission = Admission(
            max_sessions=max_sessions,
            max_pending=max_pending,
            per_address=per_node,
            handshake_timeout=handshake_timeout,
        )
        # interrupted transfers nobody resumed for partial_ttl seconds are deleted
        self.partial_ttl = partial_ttl
        self.sweep_interval = sweep_interval
        self._next_sweep = 0.0

    # announcement ----------------------------------------------------------------------------
    def announcement(self) -> dict[str, Any]:
        """What this node announces (latched): who it is, what it serves, its maps."""
        doc: dict[str, Any] = {
            "robot": self.robot,
            "node": self.link.node,
            "features": list(self.features),
            "auth": self.secret is not None,
        }
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
            if (
                same_transfer(s.dest.offer, offer)
                or s.client == new.client
                or now - s.last >= STALE
            ):
                log.info(
                    "%s: taking over %s from a silent session of %s", new.client, name, s.client
                )
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
                log.warning(
                    "cannot sweep %s for abandoned partial files: %s", self.folder.root, err
                )
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
        log.exception(
            "internal error while handling %s of session %s",
            what,
            "?" if sid is None else f"{sid:016x}",
        )
        s = self.sessions.pop(sid, None) if sid is not None else None
        if sid is not None:
            self.admission.release(sid)
        if s is not None:
            s.closed = True
            with contextlib.suppress(Exception):
                s._release()
            with contextlib.suppress(Exception):
                s.conn.send(
                    [reject_out(LocalTransferError("internal error on the robot"), plain=True)]
                )

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
        if (
            not was_open
            and s.hs.finished
            and s.hs.error is None
            and not self.admission.authenticated(sid)
        ):
            log.warning(
                "%s: refused: %d sessions already", s.conn.peer, self.admission.max_sessions
            )
            s.conn.send(
                [
                    reject_out(
                        StoreError(
                            f"this robot serves {self.admission.max_sessions} "
                            "sessions already; try again later",
                            Status.BUSY,
                        )
                    )
                ]
            )
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
