"""The OFFER: one file's name, size, chunking and checksum."""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from typing import Any

from mapkit.transfer.protocol.constants import (
    DEFAULT_CHUNK_SIZE,
    MAX_CHUNK_SIZE,
    MAX_CHUNKS,
    Status,
)
from mapkit.transfer.protocol.errors import ProtocolError
from mapkit.transfer.protocol.keys import _unhex

__all__ = ["Offer", "kind_of"]


# -- offer -----------------------------------------------------------------------------------------


def kind_of(name: str) -> str:
    """``"map"`` for ``.map`` names, ``"2d"`` for ``.2d`` laser logs, else ``"file"``."""
    low = name.lower()
    return "map" if low.endswith(".map") else "2d" if low.endswith(".2d") else "file"


@dataclass(frozen=True, slots=True)
class Offer:
    """What a sender proposes to send: the file's identity and how it is cut into chunks.

    Attributes:
        name: Plain file name (checked by the receiver's application, not here).
        size: Bytes.
        sha256: Hex SHA-256 of the whole file: the file's identity and the final check.
        chunk_size: Bytes per chunk (the last chunk may be shorter).
        md5: Hex MD5 of the file for maps (ARIA's map id), else None.
        kind: ``"map"``, ``"2d"`` or ``"file"``.
        mtime: Modification time (UNIX seconds) or None.
    """

    name: str
    size: int
    sha256: str
    chunk_size: int = DEFAULT_CHUNK_SIZE
    md5: str | None = None
    kind: str = "file"
    mtime: float | None = None

    @property
    def chunks(self) -> int:
        """Number of chunks (0 for an empty file)."""
        return -(-self.size // self.chunk_size)

    def chunk_len(self, index: int) -> int:
        """Length of chunk ``index``."""
        return min(self.chunk_size, self.size - index * self.chunk_size)

    def json(self) -> dict[str, Any]:
        """The OFFER payload."""
        d: dict[str, Any] = {
            "name": self.name,
            "size": self.size,
            "sha256": self.sha256,
            "chunk_size": self.chunk_size,
            "chunks": self.chunks,
            "kind": self.kind,
        }
        if self.md5 is not None:
            d["md5"] = self.md5
        if self.mtime is not None:
            d["mtime"] = self.mtime
        return d

    @classmethod
    def from_json(cls, d: dict[str, Any], *, max_chunk: int = MAX_CHUNK_SIZE) -> Offer:
        """Check and read an OFFER payload.

        Raises:
            ProtocolError: When a field is missing, of the wrong type or inconsistent.
        """
        name, size, sha, cs = d.get("name"), d.get("size"), d.get("sha256"), d.get("chunk_size")
        if not isinstance(name, str):
            raise ProtocolError("OFFER has no name", Status.BAD_NAME)
        if not isinstance(size, int) or isinstance(size, bool) or size < 0:
            raise ProtocolError(f"OFFER size {size!r} is not a byte count")
        if not isinstance(cs, int) or isinstance(cs, bool) or not 1 <= cs <= max_chunk:
            raise ProtocolError(
                f"OFFER chunk size {cs!r} is outside 1..{max_chunk}", Status.TOO_LARGE
            )
        _unhex(sha, 32, "OFFER sha256")
        kind = d.get("kind", kind_of(name))
        if kind != kind_of(name):
            raise ProtocolError(
                f"OFFER kind {kind!r} does not match the name {name!r} "
                f"(a {kind_of(name)!r} by its suffix)"
            )
        md5 = d.get("md5")
        if md5 is not None:
            _unhex(md5, 16, "OFFER md5")
        elif kind == "map":
            raise ProtocolError(
                f"OFFER of the map {name!r} has no md5 (required for maps: ARIA's map id)"
            )
        mtime = d.get("mtime")
        offer = cls(
            name,
            size,
            str(sha).lower(),
            cs,
            str(md5).lower() if md5 else None,
            kind,
            mtime if isinstance(mtime, (int, float)) else None,
        )
        if d.get("chunks", offer.chunks) != offer.chunks:
            raise ProtocolError(
                f"OFFER says {d.get('chunks')} chunks, size/chunk_size gives {offer.chunks}"
            )
        if offer.chunks > MAX_CHUNKS:
            raise ProtocolError(
                f"OFFER has {offer.chunks} chunks, more than {MAX_CHUNKS}", Status.TOO_LARGE
            )
        return offer

    @classmethod
    def for_bytes(
        cls,
        name: str,
        data: bytes,
        *,
        chunk_size: int = DEFAULT_CHUNK_SIZE,
        mtime: float | None = None,
    ) -> Offer:
        """An offer for bytes in memory (MD5 included for maps).

        Examples:
            >>> Offer.for_bytes("a.map", b"2D-Map\\n").chunks
            1
        """
        kind = kind_of(name)
        md5 = hashlib.md5(data).hexdigest() if kind == "map" else None
        return cls(name, len(data), hashlib.sha256(data).hexdigest(), chunk_size, md5, kind, mtime)
