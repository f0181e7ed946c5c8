"""The ROS-facing terminal functions (the ROS node must be started): push to a fleet, list, load
and fetch."""

from __future__ import annotations

import os
import socket
from collections.abc import Callable, Iterable
from typing import Any

from mapkit.ros.errors import RosError
from mapkit.ros.node import rospy
from mapkit.ros.transfer.discovery import Watcher, _one_robot
from mapkit.ros.transfer.terminal import PushResult, Terminal
from mapkit.ros.transport import DEFAULT_WINDOW
from mapkit.transfer.protocol import (
    DEFAULT_CHUNK_SIZE,
    FrameType,
    Offer,
)

__all__ = ["fetch", "list_maps", "load_map", "push"]


# -- the ROS-facing terminal functions (the node must be started) ----------------------------


def _terminal(w: Watcher, secret: bytes | None, **kw: Any) -> Terminal:
    rp = rospy()
    return Terminal(
        w.link, secret, peer=f"{socket.gethostname()}:{rp.get_name()}", stopped=rp.is_shutdown, **kw
    )


def push(
    path: str,
    *,
    channel: str,
    secret: bytes | None,
    name: str | None = None,
    robots: Iterable[str] = (),
    expect: int = 0,
    wait: float = 3.0,
    load: bool = False,
    chunk_size: int = DEFAULT_CHUNK_SIZE,
    window: int = DEFAULT_WINDOW,
    rto: float = 1.0,
    idle_timeout: float = 30.0,
    progress: Callable[[int, int], None] | None = None,
) -> list[PushResult]:
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
    offer = Offer.for_bytes(
        name or os.path.basename(path), data, chunk_size=chunk_size, mtime=os.stat(path).st_mtime
    )
    want = list(robots)
    w = Watcher(channel, window=window, chunk_size=chunk_size)
    try:
        found = w.wait(timeout=wait, expect=expect, feature="push", names=want)
        missing = set(want) - {r.robot for r in found}
        if not found or missing or len(found) < expect:
            extra = f" (missing: {', '.join(sorted(missing))})" if missing else ""
            accept = "robot accepts" if len(found) == 1 else "robots accept"
            raise RosError(
                f"{len(found)} {accept} pushes on channel {channel!r}{extra}; "
                f"expected {max(expect, len(want), 1)}. Is `mapkit ros receive` or "
                "`mapkit ros serve` running there (same channel, same ROS master)?"
            )
        term = _terminal(w, secret, rto=rto, idle_timeout=idle_timeout)
        return term.push(found, data, offer, load=load, window=window, progress=progress)
    finally:
        w.link.close()


def list_maps(
    channel: str, *, secret: bytes | None, robot: str | None = None, timeout: float = 3.0
) -> dict[str, Any]:
    """The maps a robot serves (LIST over an authenticated session), with its name."""
    w = Watcher(channel)
    try:
        r = _one_robot(w, robot, "list", timeout)
        f = _terminal(w, secret).request(r, FrameType.LIST, {}, [FrameType.LISTING])
        return {"robot": r.robot, "node": r.node, **f.json()}
    finally:
        w.link.close()


def load_map(
    name: str,
    *,
    channel: str,
    secret: bytes | None,
    robot: str | None = None,
    md5: str | None = None,
    rollback: bool = False,
    timeout: float = 3.0,
) -> dict[str, Any]:
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


def fetch(
    name: str,
    dest: str,
    *,
    channel: str,
    secret: bytes | None,
    robot: str | None = None,
    if_changed: bool = True,
    chunk_size: int = DEFAULT_CHUNK_SIZE,
    timeout: float = 3.0,
    progress: Callable[[int, int], None] | None = None,
) -> dict[str, Any]:
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
        return _terminal(w, secret).fetch(
            r, name, dest, if_changed=if_changed, chunk_size=chunk_size, progress=progress
        )
    finally:
        w.link.close()
