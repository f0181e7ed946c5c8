"""The map, file and config services of an ARIA server: request payloads and reply parsers.

Sans-I/O like the rest of :mod:`mapkit.arnet`: these functions build the argument bytes of a
request and decode reply packets; :mod:`mapkit.arnet.client` sends and receives them. The
layouts are those of ARIA 2.9's ``ArServerHandlerMap``, ``ArServerFileUtils`` and
``ArServerHandlerConfig`` (the same on ARNL and ARAM robots).
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from typing import TYPE_CHECKING

from mapkit.arnet.errors import AriaProtocolError, AriaRemoteError
from mapkit.arnet.packet import MAX_DATA, Fields, Payload

if TYPE_CHECKING:
    import mmap

__all__ = [
    "DELETE_CODES",
    "DIR_CODES",
    "GET_CODES",
    "PUT_CODES",
    "DirEntry",
    "FileChunk",
    "MapId",
    "config_payload",
    "delete_result",
    "dir_listing",
    "file_chunk",
    "put_payloads",
    "put_result",
]

#: getDirListing return codes.
DIR_CODES = {1: "is outside the folders the server shares", 2: "is not a folder on the robot"}
#: getFile return codes.
GET_CODES = {
    1: "is outside the folders the server shares",
    2: "does not exist on the robot",
    3: "is an empty file name",
    4: "could not be read on the robot",
}
#: putFile return codes (0 stored, 1 still receiving).
PUT_CODES = {
    2: "is outside the folders the server shares",
    3: "names a folder that does not exist",
    4: "is not a valid file name",
    5: "could not be written on the robot (temporary file)",
    6: "could not be moved into place on the robot",
    7: "is being uploaded by another client",
    8: "was taken over by another client",
    9: "is not being uploaded (the server lost the upload)",
    11: "upload was cancelled",
}
#: deleteFile return codes.
DELETE_CODES = {
    1: "is outside the folders the server shares",
    2: "does not exist on the robot",
    3: "is an empty file name",
}

#: Data bytes per putFile packet (what ARIA's own client sends at most).
PUT_CHUNK = 30000


@dataclass(frozen=True)
class MapId:
    """The identity of the map a robot has loaded (``ArMapId``): file name, MD5, size, time."""

    source: str
    file_name: str
    checksum: bytes
    size: int
    timestamp: int

    @property
    def md5(self) -> str:
        """The checksum as hex ("" when the robot sent none)."""
        return self.checksum.hex()

    @classmethod
    def parse(cls, f: Fields) -> MapId:
        """Decode a getMapId reply."""
        source = f.string()
        name = f.string()
        n = f.ubyte4()
        if n > 64:
            raise AriaProtocolError(f"{f.what}: a {n}-byte map checksum (an MD5 has 16)")
        digest = f.raw(n)
        size = f.ubyte4()
        stamp = f.byte4()
        return cls(source, name, digest, size, stamp)


@dataclass(frozen=True)
class DirEntry:
    """One entry of a robot folder listing (times are seconds since 1970, UTC)."""

    name: str
    is_dir: bool
    size: int
    mtime: int
    atime: int


def dir_listing(f: Fields, folder: str) -> tuple[str, list[DirEntry]]:
    """Decode one getDirListingMultiplePackets reply packet: (folder listed, its entries).

    Raises:
        AriaRemoteError: When the server answered with an error code.
    """
    ret = f.ubyte2()
    listed = f.string()
    if ret != 0:
        why = DIR_CODES.get(ret, f"was refused (code {ret})")
        raise AriaRemoteError(f"robot folder '{folder or '.'}' {why}", ret)
    n = f.ubyte2()
    out = []
    for _ in range(n):
        kind = f.ubyte()
        name = f.string()
        atime, mtime, size = f.ubyte4(), f.ubyte4(), f.ubyte4()
        out.append(DirEntry(name, kind == 1, size, mtime, atime))
    return listed, out


@dataclass(frozen=True)
class FileChunk:
    """One getFile reply packet: ``data`` empty means the file is complete."""

    path: str
    data: bytes


def file_chunk(f: Fields, remote: str, max_chunk: int = MAX_DATA) -> FileChunk:
    """Decode one getFile reply packet.

    Raises:
        AriaRemoteError: For an error code (missing file, outside the shared folder ...).
        AriaProtocolError: When the byte count does not match the packet.
    """
    ret = f.ubyte2()
    path = f.string()
    if ret != 0:
        raise AriaRemoteError(
            f"robot file '{remote}' {GET_CODES.get(ret, f'was refused (code {ret})')}", ret
        )
    n = f.ubyte4()
    if n > max_chunk or n != f.remaining:
        raise AriaProtocolError(
            f"{f.what}: the packet says it carries {n} bytes of '{remote}' but holds {f.remaining}"
        )
    return FileChunk(path, f.rest())


def put_payloads(remote: str, data: bytes | bytearray | memoryview | mmap.mmap) -> Iterator[bytes]:
    """The putFile packets' data for uploading ``data`` as ``remote``: start, chunks, done."""
    name = Payload().string(remote).bytes()
    room = min(PUT_CHUNK, MAX_DATA - 2 - len(name) - 4)
    if room < 1024:
        raise AriaRemoteError(f"robot file name '{remote}' is too long to upload")
    yield Payload().ubyte2(0).raw(name).bytes()
    view = memoryview(data)
    for start in range(0, len(view), room):
        part = view[start : start + room]
        yield b"".join((b"\x01\x00", name, len(part).to_bytes(4, "little"), part))
    yield Payload().ubyte2(2).raw(name).bytes()


def put_result(f: Fields, remote: str) -> int:
    """Decode a putFile reply; return its code (0 stored, 10 chunk received, 1 receiving).

    Raises:
        AriaRemoteError: For an error code.
    """
    ret = f.ubyte2()
    if ret in (0, 1, 10):
        return ret
    raise AriaRemoteError(
        f"robot file '{remote}' {PUT_CODES.get(ret, f'was refused (code {ret})')}", ret
    )


def delete_result(f: Fields, remote: str) -> None:
    """Decode a deleteFile reply.

    Raises:
        AriaRemoteError: For an error code.
    """
    ret = f.ubyte2()
    if ret != 0:
        raise AriaRemoteError(
            f"robot file '{remote}' {DELETE_CODES.get(ret, f'could not be deleted (code {ret})')}",
            ret,
        )


def config_payload(section: str, values: dict[str, str]) -> bytes:
    """The data of a setConfig/setConfigBySectionsV2 packet: ``Section NAME`` then name/value
    pairs."""
    p = Payload().string("Section").string(section)
    for k, v in values.items():
        p.string(k).string(v)
    return p.bytes()
