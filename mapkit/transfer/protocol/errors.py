"""The protocol's errors and the status code each one is reported with."""

from __future__ import annotations

from mapkit.errors import ChecksumError, LocalTransferError, RemoteTransferError
from mapkit.transfer.protocol.constants import Status

__all__ = [
    "AuthenticationError",
    "ProtocolError",
    "Rejected",
    "ReplayError",
    "TimeoutTransferError",
    "status_of",
]


# -- errors -----------------------------------------------------------------------------------


class ProtocolError(LocalTransferError):
    """The peer broke the protocol (bad frame, unexpected type, limit exceeded).

    Attributes:
        status: The :class:`Status` to report to the peer before giving up.
    """

    def __init__(self, message: str, status: Status = Status.PROTOCOL) -> None:
        super().__init__(message)
        self.status = status


class AuthenticationError(ProtocolError):
    """A frame or proof failed authentication (wrong secret, forged or altered frame)."""

    def __init__(self, message: str, status: Status = Status.AUTH_FAILED) -> None:
        super().__init__(message, status)


class ReplayError(ProtocolError):
    """A frame's sequence number was already used in this session."""

    def __init__(self, message: str) -> None:
        super().__init__(message, Status.REPLAY)


class Rejected(RemoteTransferError):
    """The peer refused a request or cancelled a transfer (REJECT or CANCEL frame).

    Attributes:
        status: The peer's :class:`Status` (or the raw int when unknown).
        reason: The peer's reason word, e.g. ``"bad_name"``.
        detail: The peer's human-readable message.
    """

    def __init__(self, status: int, reason: str, detail: str, *, peer: str = "peer") -> None:
        self.status: Status | int
        try:
            self.status = Status(status)
        except ValueError:
            self.status = status
        self.reason = reason
        self.detail = detail
        super().__init__(
            f"{peer} refused: {reason}: {detail}" if detail else f"{peer} refused: {reason}"
        )


class TimeoutTransferError(LocalTransferError):
    """No answer from the peer in time (after the allowed resends)."""

    status = Status.TIMEOUT


def status_of(err: BaseException) -> Status:
    """The :class:`Status` that best describes ``err`` for a REJECT or CANCEL frame."""
    st = getattr(err, "status", None)
    if isinstance(st, Status):
        return st
    if isinstance(err, ChecksumError):
        return Status.HASH_MISMATCH
    return Status.INTERNAL
