"""Who may hold a connection to a server: bookkeeping for unauthenticated and authenticated peers.

A TCP connection costs the server a thread and a socket before the peer has proved anything.
Without limits, 64 silent connections (no secret needed) filled every slot of ``mapkit serve``
for the 30 s idle timeout, and renewing them kept a robot unreachable. :class:`Admission` keeps
two separate pools:

* **pending** (connected, handshake not finished): at most ``max_pending`` in all and
  ``per_address`` per peer address, each with a handshake deadline (a few seconds after the
  connection, however slowly bytes trickle in). When a pool is full, a new connection is still
  admitted and the *least useful* pending one is evicted instead: a silent one before one
  with bytes waiting, and both before one that sent a complete frame; the oldest first, from
  the address holding the most. So an attacker's silent or byte-per-second connections make
  room for an honest client that completes its handshake in milliseconds, and cannot fill the
  pool for longer than the deadline.
* **sessions** (authenticated): up to ``max_sessions``, never taken by pending connections, so
  room is always kept for peers that know the secret.

This module does no I/O: the server closes what :meth:`Admission.admit` and
:meth:`Admission.expired` name. All methods are thread-safe.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Hashable
from dataclasses import dataclass

__all__ = ["Admission"]


@dataclass
class _Entry:
    address: str
    since: float
    deadline: float
    progressed: bool = False
    authenticated: bool = False


class Admission:
    """Connection slots of a server (see the module docstring).

    Args:
        max_sessions: Authenticated sessions at once.
        max_pending: Connections still in their handshake at once.
        per_address: Connections in their handshake per peer address.
        handshake_timeout: Seconds from connecting to the end of the handshake.

    Examples:
        >>> a = Admission(max_pending=2, per_address=2, handshake_timeout=5)
        >>> a.admit("x", "10.0.0.9", now=0.0), a.admit("y", "10.0.0.9", now=1.0)
        ([], [])
        >>> a.admit("z", "10.0.0.9", now=2.0)  # the address is full: its oldest goes
        ['x']
        >>> a.expired(now=6.5)
        ['y']
    """

    def __init__(
        self,
        *,
        max_sessions: int = 64,
        max_pending: int = 32,
        per_address: int = 8,
        handshake_timeout: float = 5.0,
    ) -> None:
        if min(max_sessions, max_pending, per_address) < 1:
            raise ValueError("connection limits must be at least 1")
        self.max_sessions = max_sessions
        self.max_pending = max_pending
        self.per_address = per_address
        self.handshake_timeout = handshake_timeout
        self._entries: dict[Hashable, _Entry] = {}
        self._lock = threading.Lock()
        self.evicted = 0
        self.timed_out = 0

    # counts ---------------------------------------------------------------------------------
    def pending(self, address: str | None = None) -> int:
        """Connections in their handshake (from ``address``, or in all)."""
        with self._lock:
            return sum(
                1
                for e in self._entries.values()
                if not e.authenticated and (address is None or e.address == address)
            )

    def sessions(self) -> int:
        """Authenticated sessions."""
        with self._lock:
            return sum(1 for e in self._entries.values() if e.authenticated)

    # transitions ----------------------------------------------------------------------------
    def admit(
        self,
        key: Hashable,
        address: str,
        now: float,
        waiting: Callable[[Hashable], bool] | None = None,
    ) -> list[Hashable]:
        """A new connection ``key`` from ``address``; returns the pending connections to close
        to make room for it (it is always admitted).

        Args:
            key: The new connection.
            address: Its peer address.
            now: The clock.
            waiting: Tells whether a connection has bytes waiting to be read (its peer is
                not silent): among those that have not sent a complete frame, such ones are
                evicted after the silent ones.
        """
        with self._lock:
            evict: list[Hashable] = []
            mine = [
                k for k, e in self._entries.items() if not e.authenticated and e.address == address
            ]
            if len(mine) >= self.per_address:
                evict.append(self._victim(mine, waiting))
            pending = [
                k for k, e in self._entries.items() if not e.authenticated and k not in evict
            ]
            if len(pending) >= self.max_pending:
                counts: dict[str, int] = {}
                for k in pending:
                    counts[self._entries[k].address] = counts.get(self._entries[k].address, 0) + 1
                top = max(counts.values())
                evict.append(
                    self._victim(
                        [k for k in pending if counts[self._entries[k].address] == top], waiting
                    )
                )
            for k in evict:
                del self._entries[k]
            self.evicted += len(evict)
            self._entries[key] = _Entry(address, now, now + self.handshake_timeout)
            return evict

    def _victim(self, keys: list[Hashable], waiting: Callable[[Hashable], bool] | None) -> Hashable:
        """The least useful of ``keys``: silent, then with bytes waiting, then with a complete
        frame; the oldest first."""

        def rank(k: Hashable) -> tuple[int, float]:
            e = self._entries[k]
            level = 2 if e.progressed else 1 if waiting is not None and waiting(k) else 0
            return level, e.since

        return min(keys, key=rank)

    def progressed(self, key: Hashable) -> None:
        """The connection sent a complete, valid frame (it is less likely an attacker's)."""
        with self._lock:
            e = self._entries.get(key)
            if e is not None:
                e.progressed = True

    def authenticated(self, key: Hashable) -> bool:
        """The handshake of ``key`` succeeded: it becomes a session. False (and it is
        forgotten) when ``max_sessions`` sessions are already open, or it was evicted."""
        with self._lock:
            e = self._entries.get(key)
            if e is None:
                return False
            if sum(1 for x in self._entries.values() if x.authenticated) >= self.max_sessions:
                del self._entries[key]
                return False
            e.authenticated = True
            return True

    def release(self, key: Hashable) -> None:
        """The connection ended (idempotent)."""
        with self._lock:
            self._entries.pop(key, None)

    def expired(self, now: float) -> list[Hashable]:
        """Pending connections past their handshake deadline (forgotten here; close them)."""
        with self._lock:
            late = [
                k for k, e in self._entries.items() if not e.authenticated and now >= e.deadline
            ]
            for k in late:
                del self._entries[k]
            self.timed_out += len(late)
            return late

    def next_deadline(self) -> float | None:
        """The earliest handshake deadline of a pending connection."""
        with self._lock:
            return min(
                (e.deadline for e in self._entries.values() if not e.authenticated), default=None
            )
