"""A control request that is resent until its answer comes."""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

from mapkit.transfer.protocol.constants import FrameType
from mapkit.transfer.protocol.events import Damaged, Event, Frame, Out
from mapkit.transfer.protocol.frames import dump_json
from mapkit.transfer.protocol.machine import _Machine, rejected_from

__all__ = ["Request"]


# -- requests --------------------------------------------------------------------------------------


class Request(_Machine):
    """A control request (GET, LIST, LOAD, PING, BYE) resent until its answer arrives.

    Args:
        type: The request's frame type.
        payload: JSON object to send.
        ref: The request number (answers carry it).
        answers: Frame types that answer it (REJECT always ends it with :class:`Rejected`).

    Attributes:
        response: The answering frame once :attr:`finished` without error.
    """

    def __init__(
        self,
        type: FrameType,
        payload: dict[str, Any],
        *,
        ref: int,
        answers: Iterable[FrameType],
        rto: float = 1.0,
        max_tries: int = 5,
        idle_timeout: float = 30.0,
    ) -> None:
        super().__init__(rto=rto, max_tries=max_tries, idle_timeout=idle_timeout)
        self.out = Out(type, dump_json(payload), ref=ref)
        self.ref = ref
        self.answers = frozenset(answers)
        self.response: Frame | None = None

    def start(self, now: float) -> list[Out]:
        """The request frame."""
        self._heard(now)
        self._tries = 1
        self._arm(now)
        return [self.out]

    def poll(self, now: float) -> list[Out]:
        """Resend when the answer is late."""
        if self.finished or self._idle(now, f"waiting for the answer to {self.out.type.name}"):
            return []
        return self._resend(now, self.out)

    def handle(self, ev: Event, now: float) -> list[Out]:
        """Take a frame; finishes on the answer."""
        if self.finished or isinstance(ev, Damaged):
            return []
        self._heard(now)
        if ev.ref != self.ref:
            return []
        if ev.type in (FrameType.REJECT, FrameType.CANCEL):
            self._fail(rejected_from(ev, "server"))
        elif ev.type in self.answers:
            self.response = ev
            self._finish()
        return []
