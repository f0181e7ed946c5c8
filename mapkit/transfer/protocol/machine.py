"""What every state machine shares: refusals, deadlines and resending."""

from __future__ import annotations

from typing import Any

from mapkit.errors import TransferError
from mapkit.transfer.protocol.constants import FrameType, Status
from mapkit.transfer.protocol.errors import ProtocolError, Rejected, TimeoutTransferError, status_of
from mapkit.transfer.protocol.events import Frame, Out
from mapkit.transfer.protocol.frames import dump_json

__all__ = ["reject_out", "rejected_from"]


# -- machine plumbing -----------------------------------------------------------------------------


def _reject(
    code: Status,
    message: str,
    ref: int = 0,
    *,
    plain: bool = False,
    ftype: FrameType = FrameType.REJECT,
) -> Out:
    return Out(
        ftype,
        dump_json({"code": int(code), "reason": code.reason, "message": message}),
        ref=ref,
        plain=plain,
    )


def rejected_from(frame: Frame, peer: str = "peer") -> Rejected:
    """A :class:`Rejected` error from a REJECT or CANCEL frame."""
    try:
        d = frame.json()
    except ProtocolError:
        d = {}
    code = d.get("code", int(Status.INTERNAL))
    code = code if isinstance(code, int) else int(Status.INTERNAL)
    try:
        default_reason = Status(code).reason
    except ValueError:
        default_reason = f"code {code}"
    reason = str(d["reason"]) if isinstance(d.get("reason"), str) else default_reason
    message = str(d["message"]) if isinstance(d.get("message"), str) else ""
    return Rejected(code, reason, message, peer=peer)


def reject_out(
    err: BaseException, ref: int = 0, *, plain: bool = False, cancel: bool = False
) -> Out:
    """The REJECT (or CANCEL) frame that reports ``err`` to the peer."""
    return _reject(
        status_of(err),
        str(err),
        ref,
        plain=plain,
        ftype=FrameType.CANCEL if cancel else FrameType.REJECT,
    )


class _Machine:
    """Shared state: finished/error, a resend timer and an idle timer."""

    def __init__(self, *, rto: float, max_tries: int, idle_timeout: float) -> None:
        self.rto = rto
        self.max_tries = max_tries
        self.idle_timeout = idle_timeout
        self.finished = False
        self.error: TransferError | None = None
        self._timer: float | None = None
        self._tries = 0
        self._last_heard = 0.0
        self._events: list[Any] = []

    @property
    def last_heard(self) -> float:
        """When (on the driver's clock) the last frame from the peer arrived."""
        return self._last_heard

    def pop_events(self) -> list[Any]:
        """Events for the application since the last call."""
        ev, self._events = self._events, []
        return ev

    def _fail(self, err: TransferError) -> None:
        if not self.finished:
            self.finished = True
            self.error = err
            self._timer = None

    def _finish(self) -> None:
        self.finished = True
        self._timer = None

    def _arm(self, now: float) -> None:
        self._timer = now + self.rto * min(2 ** max(self._tries - 1, 0), 8)

    def _heard(self, now: float) -> None:
        self._last_heard = now

    def deadline(self) -> float | None:
        """When :meth:`poll` should run next (None: only on a frame)."""
        if self.finished:
            return None
        idle = self._last_heard + self.idle_timeout
        return idle if self._timer is None else min(self._timer, idle)

    def _idle(self, now: float, what: str) -> bool:
        if not self.finished and now >= self._last_heard + self.idle_timeout:
            self._fail(
                TimeoutTransferError(
                    f"no frame from the peer for {self.idle_timeout:g} s while {what}"
                )
            )
            return True
        return False

    ref = 0

    def _handle(self, f: Frame, now: float) -> list[Out]:  # pragma: no cover - overridden
        return []

    def _guarded(self, f: Frame, now: float, peer: str) -> list[Out]:
        """A REJECT/CANCEL of this exchange ends it; a local error is answered with CANCEL."""
        if f.type in (FrameType.REJECT, FrameType.CANCEL):
            if f.ref == self.ref:
                self._fail(rejected_from(f, peer))
            return []
        try:
            return self._handle(f, now)
        except TransferError as err:
            return self.fail(err, self.ref)

    def _resend(self, now: float, out: Out | None) -> list[Out]:
        """``[out]`` again when the resend timer expired; fail after ``max_tries`` sends."""
        if self._timer is None or now < self._timer or out is None:
            return []
        if self._tries >= self.max_tries:
            self._fail(
                TimeoutTransferError(f"no answer to {out.type.name} after {self._tries} tries")
            )
            return []
        self._tries += 1
        self._arm(now)
        return [out]

    def fail(self, err: TransferError, ref: int = 0) -> list[Out]:
        """Give up with ``err`` (e.g. the application's disk is full); returns the CANCEL to
        send."""
        if self.finished:
            return []
        self._fail(err)
        return [reject_out(err, ref, cancel=True)]
