"""mapkit's ArNetworking client: talk to ARNL and ARAM robots (TCP port 7272) as they are.

A sans-I/O protocol core in h11's shape (:mod:`~mapkit.arnet.packet` framing and ARIA's
checksum, :mod:`~mapkit.arnet.reader` the incremental frame reader,
:mod:`~mapkit.arnet.connection` the login/command-list state machine producing
:mod:`~mapkit.arnet.events`, :mod:`~mapkit.arnet.services` the map/file/config payloads), a thin
blocking socket driver (:mod:`~mapkit.arnet.client`), and what mapkit does with a robot
(:mod:`~mapkit.arnet.robot`). See docs/aria.md.
"""

from __future__ import annotations

from mapkit.arnet.client import DEFAULT_PORT, AriaClient, parse_host
from mapkit.arnet.errors import (
    AriaConnectionError,
    AriaError,
    AriaLoginError,
    AriaMapRefusedError,
    AriaPermissionError,
    AriaProtocolError,
    AriaRemoteError,
    AriaTimeoutError,
    AriaValueError,
)
from mapkit.arnet.robot import FetchedMap, LoadResult, MapChange, Robot, connect
from mapkit.arnet.services import DirEntry, MapId

__all__ = [
    "DEFAULT_PORT",
    "AriaClient",
    "AriaConnectionError",
    "AriaError",
    "AriaLoginError",
    "AriaMapRefusedError",
    "AriaPermissionError",
    "AriaProtocolError",
    "AriaRemoteError",
    "AriaTimeoutError",
    "AriaValueError",
    "DirEntry",
    "FetchedMap",
    "LoadResult",
    "MapChange",
    "MapId",
    "Robot",
    "connect",
    "parse_host",
]
