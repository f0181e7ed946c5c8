"""``mapkit.aria``: the Python API for ARNL/ARAM robots over ArNetworking (port 7272).

Examples:
    Not run here (they need a robot)::

        import mapkit
        with mapkit.aria.connect("robot:7272", user="admin", password=pw) as robot:
            print(robot.map_name)
            m = robot.fetch_map()
            robot.send_map("new.map", load=True)
            for change in robot.watch():
                print(change.name, change.md5)

The password is never read from the command line by mapkit's CLI; :func:`password_from_env`
gives what ``--password-file``, ``MAPKIT_ARIA_PASSWORD_FILE`` and ``MAPKIT_ARIA_PASSWORD`` say.
"""

from __future__ import annotations

import os

from mapkit.arnet import (
    DEFAULT_PORT,
    AriaConnectionError,
    AriaError,
    AriaLoginError,
    AriaMapRefusedError,
    AriaPermissionError,
    AriaProtocolError,
    AriaRemoteError,
    AriaTimeoutError,
    AriaValueError,
    DirEntry,
    FetchedMap,
    LoadResult,
    MapChange,
    MapId,
    Robot,
    connect,
)
from mapkit.errors import MapkitError

__all__ = [
    "DEFAULT_PORT",
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
    "password_from_env",
]


def password_from_env(password_file: str | None = None) -> str:
    """The robot password: from ``password_file``, else ``$MAPKIT_ARIA_PASSWORD_FILE``, else
    ``$MAPKIT_ARIA_PASSWORD``, else "" (no password). One trailing newline of a file is dropped.

    Raises:
        MapkitError: When the password file cannot be read.
    """
    path = password_file or os.environ.get("MAPKIT_ARIA_PASSWORD_FILE")
    if path:
        try:
            with open(path, "rb") as fh:
                text = fh.read(4097)
        except OSError as e:
            raise MapkitError(f"{path}: cannot read the password file: {e.strerror or e}") from e
        if len(text) > 4096:
            raise MapkitError(f"{path}: too long for a password file")
        return text.decode("utf-8", "surrogateescape").removesuffix("\n").removesuffix("\r")
    return os.environ.get("MAPKIT_ARIA_PASSWORD", "")
