"""Moving maps between robot and terminal: the MKT/1 protocol and its TCP transport.

* :mod:`mapkit.transfer.protocol`: the sans-I/O core (frames, handshake, sender/receiver state
  machines); reuse it for other transports (ROS topics).
* :mod:`mapkit.transfer.store`: atomic destination files with a resume journal; name checks.
* :mod:`mapkit.transfer.tcp`: blocking TCP/TLS links and the driver loop.
* :mod:`mapkit.transfer.server`: :class:`MapFolder` and :class:`MapServer` (``mapkit serve``).
* :mod:`mapkit.transfer.client`: :class:`Client` and one-shot functions.

The wire format is specified in ``docs/transfer-protocol.md``.

Examples:
    >>> from mapkit.transfer import DEFAULT_PORT, MapServer, send_file, fetch_file
    >>> DEFAULT_PORT
    7373
"""

from __future__ import annotations

from mapkit.transfer.client import Client, fetch_file, list_maps, load_map, receive_files, send_file
from mapkit.transfer.protocol import DEFAULT_PORT, Rejected, Status, load_secret
from mapkit.transfer.server import MapFolder, MapServer
from mapkit.transfer.tcp import client_tls_context, parse_address, server_tls_context

__all__ = [
    "DEFAULT_PORT",
    "Client",
    "MapFolder",
    "MapServer",
    "Rejected",
    "Status",
    "client_tls_context",
    "fetch_file",
    "list_maps",
    "load_map",
    "load_secret",
    "parse_address",
    "receive_files",
    "send_file",
    "server_tls_context",
]
