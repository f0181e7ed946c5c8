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

from mapkit.ros.transfer.actions import (
    fetch,
    list_maps,
    load_map,
    push,
)
from mapkit.ros.transfer.discovery import (
    Robot,
    Watcher as Watcher,
    discover,
)
from mapkit.ros.transfer.robot import (
    FEATURES_RECEIVE as FEATURES_RECEIVE,
    FEATURES_SERVE as FEATURES_SERVE,
    LINGER as LINGER,
    STALE as STALE,
    RobotNode,
)
from mapkit.ros.transfer.session import (
    log as log,
)
from mapkit.ros.transfer.terminal import (
    PushResult,
    Script as Script,
    Terminal,
)

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
