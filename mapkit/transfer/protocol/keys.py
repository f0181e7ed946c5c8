"""Pre-shared secrets and the per-session keys derived from them."""

from __future__ import annotations

import binascii
import hashlib
import hmac
import os
from collections.abc import Mapping
from typing import Any

from mapkit.errors import LocalTransferError
from mapkit.transfer.protocol.constants import MIN_SECRET
from mapkit.transfer.protocol.errors import ProtocolError

__all__ = ["derive_keys", "load_secret"]


# -- keys and secrets ----------------------------------------------------------------------------


def load_secret(
    *, path: str | os.PathLike[str] | None = None, env: Mapping[str, str] | None = None
) -> bytes | None:
    """Read the pre-shared secret from a file, or else the ``MAPKIT_SECRET`` environment variable.

    Surrounding whitespace (the trailing newline of a file) is removed. The secret is never taken
    from the command line, where other users can read it.

    Args:
        path: A file holding the secret, or None.
        env: The environment to read (default ``os.environ``); ``MAPKIT_SECRET_FILE`` names a
            file when ``path`` is None.

    Returns:
        The secret, or None when none is configured.

    Raises:
        LocalTransferError: When the file cannot be read or the secret is shorter than 16 bytes.

    Examples:
        >>> load_secret(env={"MAPKIT_SECRET": "correct horse battery staple"})
        b'correct horse battery staple'
        >>> load_secret(env={}) is None
        True
    """
    environ: Mapping[str, str] = os.environ if env is None else env
    where = ""
    if path is None and environ.get("MAPKIT_SECRET_FILE"):
        path = environ["MAPKIT_SECRET_FILE"]
    if path is not None:
        where = os.fspath(path)
        try:
            with open(path, "rb") as fh:
                secret = fh.read(65536).strip()
        except OSError as err:
            raise LocalTransferError(f"{where}: cannot read the secret: {err.strerror}") from err
    elif environ.get("MAPKIT_SECRET"):
        where = "MAPKIT_SECRET"
        secret = environ["MAPKIT_SECRET"].strip().encode("utf-8")
    else:
        return None
    if len(secret) < MIN_SECRET:
        raise LocalTransferError(
            f"{where}: the secret has {len(secret)} bytes; use at least "
            f"{MIN_SECRET} (e.g. `head -c 32 /dev/urandom | base64`)"
        )
    return secret


def _hkdf(secret: bytes, salt: bytes, info: bytes, length: int) -> bytes:
    prk = hmac.new(salt, secret, hashlib.sha256).digest()
    out, block, i = b"", b"", 1
    while len(out) < length:
        block = hmac.new(prk, block + info + bytes([i]), hashlib.sha256).digest()
        out += block
        i += 1
    return out[:length]


def derive_keys(
    secret: bytes, session: int, nonce_c: bytes, nonce_s: bytes, transcript: bytes
) -> tuple[bytes, bytes]:
    """The two session keys ``(c2s, s2c)``: HKDF-SHA256 of the secret, salted with both nonces.

    Args:
        secret: The pre-shared secret.
        session: The session id.
        nonce_c: The client's 32-byte nonce (HELLO).
        nonce_s: The server's 32-byte nonce (HELLO_ACK).
        transcript: SHA-256 of the HELLO payload followed by the HELLO_ACK payload.

    Returns:
        Two 32-byte keys.
    """
    okm = _hkdf(
        secret, nonce_c + nonce_s, b"MKT1 keys" + session.to_bytes(8, "big") + transcript, 64
    )
    return okm[:32], okm[32:]


def _proof(key: bytes, label: bytes, transcript: bytes) -> str:
    return hmac.new(key, label + transcript, hashlib.sha256).hexdigest()


def _unhex(value: Any, size: int, what: str) -> bytes:
    try:
        raw = binascii.unhexlify(value) if isinstance(value, str) else b""
    except (binascii.Error, ValueError):
        raw = b""
    if len(raw) != size:
        raise ProtocolError(f"{what} must be {size} bytes in hex")
    return raw
