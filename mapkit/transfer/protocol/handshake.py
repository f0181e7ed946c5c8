"""The handshake state machines: version and auth negotiation, mutual challenge-response,
session keys installed in the channel."""

from __future__ import annotations

import hashlib
import hmac
import os
from collections.abc import Sequence
from typing import Any

from mapkit.errors import TransferError
from mapkit.transfer.protocol.channel import Channel
from mapkit.transfer.protocol.constants import (
    AUTH_METHODS,
    NONCE_SIZE,
    SOFTWARE,
    VERSION,
    FrameType,
    Status,
)
from mapkit.transfer.protocol.errors import AuthenticationError, ProtocolError, TimeoutTransferError
from mapkit.transfer.protocol.events import Damaged, Event, Frame, Out
from mapkit.transfer.protocol.frames import _TAGGERS, _type_name, dump_json
from mapkit.transfer.protocol.keys import _proof, _unhex, derive_keys
from mapkit.transfer.protocol.machine import _Machine, reject_out, rejected_from

__all__ = ["ClientHandshake", "ServerHandshake"]


# -- handshake -------------------------------------------------------------------------------------


class ClientHandshake(_Machine):
    """The initiator's side of HELLO / HELLO_ACK / AUTH / AUTH_OK.

    Args:
        channel: The session's channel (its session id set); keys are installed into it.
        secret: The pre-shared secret, or None for an insecure session (``--insecure``).
        peer: A name for this endpoint (host name), shown in the peer's logs.
        nonce: Fixed nonce for tests; random otherwise.
        rto: First resend timeout (seconds), doubled on each resend.
        max_tries: Sends of one frame before giving up.
        idle_timeout: Give up after this long without any frame.
        auth_methods: Tag algorithms to offer, preferred first (with a secret).

    Attributes:
        server: The HELLO_ACK payload (version, peer name, limits, features).
        auth: ``"none"``, or the tag algorithm the server chose once the handshake is done.
    """

    def __init__(
        self,
        channel: Channel,
        secret: bytes | None,
        *,
        peer: str = "",
        nonce: bytes | None = None,
        rto: float = 1.0,
        max_tries: int = 5,
        idle_timeout: float = 30.0,
        auth_methods: Sequence[str] = AUTH_METHODS,
    ) -> None:
        super().__init__(rto=rto, max_tries=max_tries, idle_timeout=idle_timeout)
        self.channel = channel
        self.secret = secret
        methods = [m for m in auth_methods if m in _TAGGERS]
        if secret is not None and not methods:
            raise ValueError(f"no known tag algorithm in {list(auth_methods)!r}")
        self.offered: list[str] | str = methods if secret is not None else "none"
        self.auth = methods[0] if secret is not None else "none"
        self.nonce = nonce or os.urandom(NONCE_SIZE)
        self.server: dict[str, Any] = {}
        self._hello = dump_json(
            {
                "versions": [VERSION],
                "nonce": self.nonce.hex(),
                "auth": self.offered,
                "peer": peer,
                "software": SOFTWARE,
            }
        )
        self._pending: Out | None = None
        self._th = b""
        self._expect_proof = ""

    def start(self, now: float) -> list[Out]:
        """The HELLO frame."""
        self._heard(now)
        self._pending = Out(FrameType.HELLO, self._hello)
        self._tries = 1
        self._arm(now)
        return [self._pending]

    def poll(self, now: float) -> list[Out]:
        """Resend HELLO or AUTH when its answer is late."""
        if self.finished or self._idle(now, "waiting for the handshake"):
            return []
        return self._resend(now, self._pending)

    def handle(self, ev: Event, now: float) -> list[Out]:
        """Take a frame from the server."""
        if self.finished or isinstance(ev, Damaged):
            return []
        self._heard(now)
        try:
            return self._handle(ev, now)
        except TransferError as err:
            self._fail(err)
            return []

    def _handle(self, f: Frame, now: float) -> list[Out]:
        if f.type in (FrameType.REJECT, FrameType.CANCEL):
            raise rejected_from(f, "server")
        if (
            f.type == FrameType.HELLO_ACK
            and self._pending is not None
            and self._pending.type == FrameType.HELLO
        ):
            d = f.json()
            if d.get("version") != VERSION:
                raise ProtocolError(
                    f"server chose MKT version {d.get('version')!r}", Status.BAD_VERSION
                )
            chosen = d.get("auth")
            if chosen != self.offered and not (
                isinstance(self.offered, list) and chosen in self.offered
            ):
                raise AuthenticationError(
                    f"asked for auth {self.offered!r}, server answered {chosen!r}"
                )
            self.auth = str(chosen)
            self.server = d
            self._th = hashlib.sha256(self._hello + f.payload).digest()
            proof = ""
            if self.secret is not None:
                nonce_s = _unhex(d.get("nonce"), NONCE_SIZE, "HELLO_ACK nonce")
                assert self.channel.session is not None
                c2s, s2c = derive_keys(
                    self.secret, self.channel.session, self.nonce, nonce_s, self._th
                )
                self.channel.install_keys(c2s, s2c, self.auth)
                proof = _proof(c2s, b"MKT1 client proof", self._th)
                self._expect_proof = _proof(s2c, b"MKT1 server proof", self._th)
            self._pending = Out(FrameType.AUTH, dump_json({"proof": proof}))
            self._tries = 1
            self._arm(now)
            return [self._pending]
        if (
            f.type == FrameType.AUTH_OK
            and self._pending is not None
            and self._pending.type == FrameType.AUTH
        ):
            if self.secret is not None:
                got = f.json().get("proof")
                if not (
                    f.authentic
                    and isinstance(got, str)
                    and hmac.compare_digest(got, self._expect_proof)
                ):
                    raise AuthenticationError(
                        "the server could not prove it knows the shared secret"
                    )
            self._pending = None
            self._finish()
            return []
        return []  # a late duplicate answer


class ServerHandshake(_Machine):
    """The responder's side of the handshake.

    Args:
        channel: A fresh responder channel.
        secret: The pre-shared secret, or None.
        insecure: Accept clients without authentication.
        peer: This server's name.
        info: Extra HELLO_ACK fields (limits, features).
        idle_timeout: Give up after this long without a frame.
        auth_methods: Tag algorithms this server accepts; it picks the client's most preferred
            one among them.
        timeout: Give up when the handshake is not done this many seconds after :meth:`start`,
            however often the client sends (a peer that trickles frames or repeats HELLO
            cannot hold the session open); None for no limit but ``idle_timeout``.

    Attributes:
        client: The client's HELLO payload.
        auth: ``"none"``, or the tag algorithm chosen (once the HELLO arrived).
    """

    def __init__(
        self,
        channel: Channel,
        secret: bytes | None,
        *,
        insecure: bool = False,
        peer: str = "",
        info: dict[str, Any] | None = None,
        nonce: bytes | None = None,
        idle_timeout: float = 30.0,
        auth_methods: Sequence[str] = AUTH_METHODS,
        timeout: float | None = None,
    ) -> None:
        super().__init__(rto=1.0, max_tries=1, idle_timeout=idle_timeout)
        self.timeout = timeout
        self._until: float | None = None
        self.channel = channel
        self.secret = secret
        self.insecure = insecure
        self.auth_methods = tuple(m for m in auth_methods if m in _TAGGERS)
        self.auth = "none"
        self.peer = peer
        self.info = dict(info or {})
        self.nonce = nonce or os.urandom(NONCE_SIZE)
        self.client: dict[str, Any] = {}
        self._hello = b""
        self._ack: Out | None = None
        self._ok: Out | None = None
        self._th = b""
        self._expect = ""

    def start(self, now: float) -> list[Out]:
        """Nothing: the client speaks first (the handshake deadline starts now)."""
        self._heard(now)
        if self.timeout is not None:
            self._until = now + self.timeout
        return []

    def deadline(self) -> float | None:
        """The idle deadline, or the handshake's own deadline when that comes first."""
        dl = super().deadline()
        if dl is None or self._until is None:
            return dl
        return min(dl, self._until)

    def poll(self, now: float) -> list[Out]:
        """Check the idle timeout and the handshake deadline."""
        if self._idle(now, "waiting for the client's handshake"):
            return []
        if not self.finished and self._until is not None and now >= self._until:
            self._fail(TimeoutTransferError(f"handshake not completed within {self.timeout:g} s"))
        return []

    def handle(self, ev: Event, now: float) -> list[Out]:
        """Take a frame from the client; a failure returns the REJECT to send."""
        if isinstance(ev, Damaged):
            return []
        self._heard(now)
        try:
            return self._hello_or_auth(ev)
        except TransferError as err:
            self._fail(err)
            return [reject_out(err, ev.ref, plain=True)]

    def _hello_or_auth(self, f: Frame) -> list[Out]:
        if f.type == FrameType.HELLO:
            if self._ack is not None:
                if f.payload == self._hello:
                    return [self._ack]  # the client did not get our answer
                raise ProtocolError("a second, different HELLO in one session")
            d = f.json()
            versions = d.get("versions")
            if not isinstance(versions, list) or VERSION not in versions:
                raise ProtocolError(
                    f"client offers MKT versions {versions!r}, this server speaks {VERSION}",
                    Status.BAD_VERSION,
                )
            auth = self._choose(d.get("auth"))
            nonce_c = _unhex(d.get("nonce"), NONCE_SIZE, "HELLO nonce")
            self.client = d
            self._hello = bytes(f.payload)
            ack = {
                "version": VERSION,
                "nonce": self.nonce.hex(),
                "auth": auth,
                "peer": self.peer,
                "software": SOFTWARE,
                **self.info,
            }
            ack_payload = dump_json(ack)
            self._ack = Out(FrameType.HELLO_ACK, ack_payload, ref=f.ref)
            self._th = hashlib.sha256(self._hello + ack_payload).digest()
            proof = ""
            self.auth = auth
            if auth != "none":
                assert self.secret is not None and self.channel.session is not None
                c2s, s2c = derive_keys(
                    self.secret, self.channel.session, nonce_c, self.nonce, self._th
                )
                self.channel.install_keys(c2s, s2c, auth)
                self._expect = _proof(c2s, b"MKT1 client proof", self._th)
                proof = _proof(s2c, b"MKT1 server proof", self._th)
            self._ok = Out(FrameType.AUTH_OK, dump_json({"proof": proof}))
            return [self._ack]
        if f.type == FrameType.AUTH and self._ack is not None:
            if self._expect:
                got = f.json().get("proof")
                if not (
                    f.authentic and isinstance(got, str) and hmac.compare_digest(got, self._expect)
                ):
                    raise AuthenticationError(
                        "the client's proof does not match: it uses another shared secret"
                    )
            assert self._ok is not None
            self._finish()
            return [self._ok]
        if f.type in (FrameType.REJECT, FrameType.CANCEL, FrameType.BYE):
            raise rejected_from(f, "client")
        raise ProtocolError(f"expected HELLO or AUTH, got {_type_name(f.type)}")

    def _choose(self, offered: Any) -> str:
        """The tag algorithm for a HELLO's ``auth`` (a list in preference order, or one string)."""
        if offered == "none":
            if not self.insecure:
                raise AuthenticationError(
                    "this server requires authentication: give the shared secret "
                    "(--secret-file or MAPKIT_SECRET)",
                    Status.AUTH_REQUIRED,
                )
            return "none"
        methods = [offered] if isinstance(offered, str) else offered
        if not (isinstance(methods, list) and methods and all(isinstance(m, str) for m in methods)):
            raise AuthenticationError(f"unknown auth method {offered!r}", Status.AUTH_REQUIRED)
        if self.secret is None:
            raise AuthenticationError(
                "this server has no shared secret (it runs with "
                "--insecure): connect with --insecure",
                Status.AUTH_REQUIRED,
            )
        for m in methods:
            if m in self.auth_methods:
                return str(m)
        raise AuthenticationError(
            f"no common auth method: the client offers {methods!r}, this "
            f"server accepts {list(self.auth_methods)!r}",
            Status.AUTH_REQUIRED,
        )

    def resend(self, f: Frame) -> list[Out]:
        """After the handshake: answer a repeated AUTH (the client missed AUTH_OK)."""
        if f.type == FrameType.AUTH and self._ok is not None:
            return [self._ok]
        return []
