"""MKT/1 frames on ROS 1 topics: one ``std_msgs/UInt8MultiArray`` message per frame.

A *channel* (default ``maps``) is three topics, relative to the node's namespace (set
``ROS_NAMESPACE`` to give each robot its own):

=============================  =========================  ========================================
topic                          type                       what
=============================  =========================  ========================================
``mapkit/<channel>/c2r``       std_msgs/UInt8MultiArray   frames from terminals to robots
``mapkit/<channel>/r2c``       std_msgs/UInt8MultiArray   frames from robots back: acks, resend
                                                          requests, answers, pulled data
``mapkit/<channel>/announce``  std_msgs/String, latched   JSON, one per robot node: its name,
                                                          what it serves, its maps (name, size,
                                                          SHA-256, MD5), the active map
=============================  =========================  ========================================

``data`` holds the frame's bytes as ``bytes`` (genpy's fast path; never a list). A topic is a bus:
every node on the channel sees every message, so each message is addressed in its layout:
``layout.dim[0].label`` is ``"<sender node> <receiving node>"`` and ``layout.dim[0].size`` the
frame's length. A node drops messages addressed to another node before decoding them; the
frame's session id, CRCs, HMAC tag and sequence numbers do the rest (the protocol does not trust
the envelope).

Tuning: subscribers use ``tcp_nodelay`` (Nagle would delay every ack), a receive buffer for a
whole window of frames and no queue limit (the window bounds memory; rospy's queue would drop
frames silently); publishers queue ``4 * window + 16`` messages. The protocol resends whatever
is lost anyway.

For tests, :class:`Faults` drops, duplicates and corrupts incoming messages; the environment
variable ``MAPKIT_ROS_FAULTS`` (e.g. ``drop=0.1,dup=0.05,corrupt=0.02,seed=1``) turns it on in a
``mapkit ros`` process.
"""

from __future__ import annotations

import os
import queue
import random
import re
import threading
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from mapkit.ros.errors import RosError
from mapkit.ros.node import ros_import, rospy, wait_until

__all__ = [
    "DEFAULT_CHANNEL",
    "DEFAULT_WINDOW",
    "FAULTS_ENV",
    "Faults",
    "RosLink",
    "channel_topics",
    "check_channel",
]

DEFAULT_CHANNEL = "maps"
#: Frames in flight per session (32 x 256 KiB: 8 MiB), and what queues and buffers are sized for.
DEFAULT_WINDOW = 32
FAULTS_ENV = "MAPKIT_ROS_FAULTS"
_CHANNEL = re.compile(r"^[A-Za-z][A-Za-z0-9_]*(/[A-Za-z][A-Za-z0-9_]*)*$")


def check_channel(channel: str) -> str:
    """Check a channel name (a ROS graph name without a leading slash).

    Raises:
        RosError: When ROS would refuse the topic names.

    Examples:
        >>> check_channel("maps"), check_channel("fleet/floor2")
        ('maps', 'fleet/floor2')
        >>> check_channel("2maps")  # doctest: +ELLIPSIS
        Traceback (most recent call last):
        ...
        mapkit.ros.errors.RosError: bad channel '2maps': use letters, digits and _ ...
    """
    if not _CHANNEL.match(channel):
        raise RosError(
            f"bad channel {channel!r}: use letters, digits and _ (starting with a "
            "letter), parts separated by /"
        )
    return channel


def channel_topics(channel: str) -> dict[str, str]:
    """The three topic names of a channel (relative: resolved in the node's namespace).

    Examples:
        >>> channel_topics("maps")["c2r"]
        'mapkit/maps/c2r'
    """
    check_channel(channel)
    return {k: f"mapkit/{channel}/{k}" for k in ("c2r", "r2c", "announce")}


@dataclass
class Faults:
    """Loss, duplication and corruption of incoming messages, for tests (seeded, reproducible).

    Attributes:
        drop: Probability that a message is lost.
        dup: Probability that it arrives twice.
        corrupt: Probability that one of its bytes is flipped.
        seed: Random seed.
        only_data: Apply the faults to DATA frames only (control frames pass).
        stall_after: Lose every DATA frame after this many (a link that dies), 0 for never.
    """

    drop: float = 0.0
    dup: float = 0.0
    corrupt: float = 0.0
    seed: int = 0
    only_data: bool = False
    stall_after: int = 0
    counts: dict[str, int] = field(
        default_factory=lambda: {"dropped": 0, "duplicated": 0, "corrupted": 0}
    )

    def __post_init__(self) -> None:
        self._rng = random.Random(self.seed)
        self._lock = threading.Lock()
        self._data_seen = 0

    @classmethod
    def parse(cls, spec: str) -> Faults:
        """Read ``"drop=0.1,dup=0.05,corrupt=0.02,seed=1,only_data=1,stall_after=0"``.

        Raises:
            RosError: For an unknown key or a value that is not a number.

        Examples:
            >>> Faults.parse("drop=0.25, seed=3").drop
            0.25
        """
        kw: dict[str, Any] = {}
        for part in filter(None, (p.strip() for p in spec.split(","))):
            key, _, value = part.partition("=")
            key = key.strip()
            try:
                if key in ("drop", "dup", "corrupt"):
                    kw[key] = float(value)
                elif key in ("seed", "only_data", "stall_after"):
                    kw[key] = int(value)
                else:
                    raise ValueError(key)
            except ValueError as err:
                raise RosError(
                    f"{FAULTS_ENV}: bad entry {part!r} (keys: drop, dup, corrupt, seed, "
                    "only_data, stall_after)"
                ) from err
        kw["only_data"] = bool(kw.get("only_data", 0))
        return cls(**kw)

    def apply(self, data: bytes) -> list[bytes]:
        """What arrives for one message: nothing, the message (possibly damaged), or it twice."""
        is_data = len(data) > 5 and data[5] == 18  # FrameType.DATA
        if self.only_data and not is_data:
            return [data]
        with self._lock:
            if is_data and self.stall_after:
                self._data_seen += 1
                if self._data_seen > self.stall_after:
                    self.counts["dropped"] += 1
                    return []
            rng = self._rng
            if rng.random() < self.drop:
                self.counts["dropped"] += 1
                return []
            if self.corrupt and rng.random() < self.corrupt and data:
                self.counts["corrupted"] += 1
                pos = rng.randrange(len(data))
                data = data[:pos] + bytes([data[pos] ^ (1 << rng.randrange(8))]) + data[pos + 1 :]
            if rng.random() < self.dup:
                self.counts["duplicated"] += 1
                return [data, data]
        return [data]


def _faults_from_env() -> Faults | None:
    spec = os.environ.get(FAULTS_ENV, "").strip()
    return Faults.parse(spec) if spec else None


class RosLink:
    """This node's end of a channel: addressed frames out, frames for this node in.

    Args:
        channel: Channel name (see :func:`channel_topics`).
        robot: True on the robot side (subscribes to ``c2r``, publishes ``r2c`` and the
            announcement); False on a client (the other way round; reads announcements).
        window: Frames in flight per session (sizes queues and buffers).
        chunk_size: Largest DATA payload (sizes the receive buffer).
        faults: Fault injection for incoming messages (default: from ``MAPKIT_ROS_FAULTS``).
        on_announce: Client only: called (in a rospy thread) with each announcement dict.

    The node must be started (:func:`mapkit.ros.node.start_node`).
    """

    def __init__(
        self,
        channel: str = DEFAULT_CHANNEL,
        *,
        robot: bool,
        window: int = DEFAULT_WINDOW,
        chunk_size: int = 256 * 1024,
        faults: Faults | None = None,
        on_announce: Callable[[dict[str, Any]], None] | None = None,
    ) -> None:
        rp = rospy()
        std = ros_import("std_msgs.msg")
        self._std = std
        self.channel = check_channel(channel)
        self.topics = channel_topics(channel)
        self.robot = robot
        self.node = str(rp.get_name())
        self.faults = faults if faults is not None else _faults_from_env()
        self.inbox: queue.Queue[tuple[str, bytes]] = queue.Queue()
        self.stats = {"sent": 0, "bytes_out": 0, "received": 0, "bytes_in": 0, "not_for_us": 0}
        buff = max(65536, 2 * window * (chunk_size + 256))
        out_topic, in_topic = ("r2c", "c2r") if robot else ("c2r", "r2c")
        self._pub = rp.Publisher(
            self.topics[out_topic],
            std.UInt8MultiArray,
            queue_size=4 * window + 16,
            tcp_nodelay=True,
        )
        self._sub = rp.Subscriber(
            self.topics[in_topic],
            std.UInt8MultiArray,
            self._on_message,
            queue_size=None,
            buff_size=buff,
            tcp_nodelay=True,
        )
        self._announce_pub = None
        self._announce_sub = None
        if robot:
            self._announce_pub = rp.Publisher(
                self.topics["announce"], std.String, latch=True, queue_size=2
            )
        elif on_announce is not None:
            from mapkit.transfer.wirejson import WireJSONError, decode_object

            def _on_announce(msg: Any) -> None:
                try:  # any node may publish here: the bounded decoder, never json.loads
                    doc = decode_object(str(msg.data).encode("utf-8", "surrogatepass"))
                except WireJSONError:
                    return
                on_announce(doc)

            self._announce_sub = rp.Subscriber(
                self.topics["announce"], std.String, _on_announce, queue_size=None, tcp_nodelay=True
            )

    # -- sending -------------------------------------------------------------------------------

    def send(self, to: str, frame: bytes) -> None:
        """Publish one frame for node ``to``."""
        std = self._std
        dim = std.MultiArrayDimension(label=f"{self.node} {to}", size=len(frame), stride=len(frame))
        msg = std.UInt8MultiArray(layout=std.MultiArrayLayout(dim=[dim], data_offset=0), data=frame)
        self._pub.publish(msg)
        self.stats["sent"] += 1
        self.stats["bytes_out"] += len(frame)

    def announce(self, doc: dict[str, Any]) -> None:
        """Robot only: publish (latched) this node's announcement."""
        import json

        if self._announce_pub is None:
            raise RosError("only a robot-side link announces")
        self._announce_pub.publish(self._std.String(data=json.dumps(doc, sort_keys=True)))

    # -- receiving -----------------------------------------------------------------------------

    def _on_message(self, msg: Any) -> None:
        dims = msg.layout.dim
        label = dims[0].label if dims else ""
        src, _, dst = label.partition(" ")
        if dst != self.node:
            self.stats["not_for_us"] += 1
            return
        data = msg.data if isinstance(msg.data, bytes) else bytes(msg.data)
        for item in self.faults.apply(data) if self.faults is not None else [data]:
            self.stats["received"] += 1
            self.stats["bytes_in"] += len(item)
            self.inbox.put((src, item))

    def receive(self, timeout: float | None) -> tuple[str, bytes] | None:
        """The next ``(sender node, frame bytes)`` for this node, or None after ``timeout``."""
        try:
            if timeout is not None and timeout <= 0:
                return self.inbox.get_nowait()
            return self.inbox.get(timeout=timeout)
        except queue.Empty:
            return None

    # -- connections ---------------------------------------------------------------------------

    def connections(self) -> tuple[int, int]:
        """``(subscribers of our frames, publishers we receive frames from)``."""
        return self._pub.get_num_connections(), self._sub.get_num_connections()

    def wait_connected(self, peers: int = 1, timeout: float = 5.0) -> bool:
        """Wait until ``peers`` nodes are connected both ways (True) or ``timeout`` passes."""
        return wait_until(lambda: min(self.connections()) >= peers, timeout)

    def close(self) -> None:
        """Withdraw the topics."""
        for t in (self._pub, self._sub, self._announce_pub, self._announce_sub):
            if t is not None:
                t.unregister()
