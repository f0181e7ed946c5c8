"""The errors mapkit raises: one root, :class:`MapkitError`, and a class per family.

Every error mapkit raises on purpose derives from :class:`MapkitError`, so a caller can catch one
type. Format errors are also :class:`ValueError`; I/O-flavoured ones are also :class:`OSError`.

Examples:
    >>> import mapkit
    >>> try:
    ...     mapkit.loads("2D-Map\\nMinPos: 1 2 3\\nDATA\\n", source="bad.map")
    ... except mapkit.MapFormatError as err:
    ...     print(err)
    bad.map:2: MinPos: expects exactly 2 integers, got 3 arguments: '1 2 3'
"""

from __future__ import annotations

__all__ = [
    "ChecksumError",
    "EditError",
    "FormatError",
    "LocalTransferError",
    "LogFormatError",
    "MapFormatError",
    "MapkitError",
    "RemoteTransferError",
    "TransferError",
    "UnsupportedFormatError",
]


class MapkitError(Exception):
    """Root of every error mapkit raises on purpose."""


class FormatError(MapkitError, ValueError):
    """A file could not be parsed. Says where: ``source:line: message``.

    Args:
        message: What was wrong and what was expected.
        source: The file name (or ``"<string>"``) the text came from.
        line: 1-based line number, or ``None`` when the problem is not on one line.
        text: The offending line's text, when there is one.
    """

    def __init__(
        self, message: str, *, source: str = "<string>", line: int | None = None, text: str = ""
    ) -> None:
        self.message = message
        self.source = source
        self.line = line
        self.text = text
        where = f"{source}:{line}" if line is not None else source
        super().__init__(f"{where}: {message}")


class MapFormatError(FormatError):
    """An ARIA ``.map`` file (or text) is not a map mapkit can read."""


class LogFormatError(FormatError):
    """An ARIA ``.2d`` laser log could not be read."""


class UnsupportedFormatError(MapkitError, ValueError):
    """No reader or writer is registered for a file name or format."""


class EditError(MapkitError, ValueError):
    """An edit was refused (bad name, bad geometry, unknown object, ...); nothing was changed."""


class TransferError(MapkitError):
    """A map transfer failed."""


class LocalTransferError(TransferError):
    """This side gave up (bad input, timeout, local disk, protocol violation by the peer)."""


class RemoteTransferError(TransferError):
    """The peer refused or cancelled, with a reason it sent."""


class ChecksumError(TransferError):
    """Data did not match its checksum (a frame's CRC, a file's SHA-256 or a map's MD5)."""
