"""The errors of mapkit's ArNetworking client; all derive from :class:`AriaError`.

:class:`AriaError` is a :class:`~mapkit.errors.MapkitError` (and a
:class:`~mapkit.errors.TransferError`), so ``except MapkitError`` catches them and the CLI turns
each into one line.
"""

from __future__ import annotations

from mapkit.errors import TransferError

__all__ = [
    "AriaConnectionError",
    "AriaError",
    "AriaLoginError",
    "AriaMapRefusedError",
    "AriaPermissionError",
    "AriaProtocolError",
    "AriaRemoteError",
    "AriaTimeoutError",
    "AriaValueError",
]


class AriaError(TransferError):
    """Talking to an ArNetworking server (an ARNL/ARAM robot, port 7272) failed."""


class AriaConnectionError(AriaError, OSError):
    """The TCP connection could not be made, or it closed in the middle of an exchange."""


class AriaProtocolError(AriaError):
    """The server sent data that breaks the ArNetworking wire format (checksum, length, layout)."""


class AriaTimeoutError(AriaError, TimeoutError):
    """The server stopped answering for longer than the timeout."""


class AriaLoginError(AriaError):
    """The server refused the login (``REJECTED``): wrong user or password, or another reason.

    Attributes:
        code: The server's rejection code (1 bad user or password, 2 central server, 4 protocol
            version, 6 robot type).
    """

    def __init__(self, message: str, code: int = 0) -> None:
        super().__init__(message)
        self.code = code


class AriaPermissionError(AriaError):
    """The server does not offer a command to this user (not in its command list)."""


class AriaRemoteError(AriaError):
    """The server answered, but with an error code or message (missing file, map not loaded ...).

    Attributes:
        code: The numeric return code when the reply has one, else ``None``.
    """

    def __init__(self, message: str, code: int | None = None) -> None:
        super().__init__(message)
        self.code = code


class AriaMapRefusedError(AriaError):
    """A map was not sent: it has findings that would stop ARIA loading it (nothing was sent)."""


class AriaValueError(AriaError, ValueError):
    """A value cannot be sent to the robot (a name with a NUL byte or that is not text)."""
