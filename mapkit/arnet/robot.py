"""What mapkit does with an ARNL/ARAM robot over ArNetworking: maps, files, the active map.

:func:`connect` opens a :class:`Robot`::

    with connect("robot:7272", user="admin", password=pw) as robot:
        robot.map_name                     # the active map's file name
        m = robot.fetch_map()              # MapData, byte-exact where file access is allowed
        robot.send_map("new.map", load=True)
        for change in robot.watch(): ...

Fetching prefers the file service (``getFile``: the robot's exact bytes, checked against the MD5
in the robot's map id), and falls back to the map service (``getMap``: the lines ARIA writes
for the loaded map) when the user has no file access. Every map is parsed before it is
accepted. Loading a map goes through the robot's config (section ``Files``, parameter ``Map``),
as MobilePlanner does; a map the robot cannot load is undone: the previous file and active map
are put back.
"""

from __future__ import annotations

import hashlib
import logging
import mmap
import os
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from types import TracebackType
from typing import Any

from mapkit._atomic import atomic_open, atomic_write
from mapkit.arnet.client import DEFAULT_PORT, AriaClient, parse_host
from mapkit.arnet.errors import (
    AriaError,
    AriaMapRefusedError,
    AriaProtocolError,
    AriaRemoteError,
)
from mapkit.arnet.packet import Payload
from mapkit.arnet.services import (
    DirEntry,
    MapId,
    config_payload,
    delete_result,
    dir_listing,
    file_chunk,
    put_payloads,
    put_result,
)
from mapkit.formats.map import dumpb, loads
from mapkit.model import MapData

__all__ = ["SERVICES", "FetchedMap", "LoadResult", "MapChange", "Robot", "connect"]

log = logging.getLogger(__name__)

#: The commands mapkit uses, by service.
SERVICES = {
    "map": ("getMapName", "getMapId", "getMap", "mapUpdated"),
    "files": ("getDirListingMultiplePackets", "getFile", "putFile", "deleteFile"),
    "config": ("setConfigBySectionsV2", "setConfig", "configUpdated"),
}
#: `mapkit validate` codes for what stops ARIA loading a map: unreadable numbers (MK107), header
#: lines it rejects (MK110), coordinates beyond 32 bits (MK304), non-finite objects (MK405).
LOAD_STOPPERS = frozenset({107, 110, 304, 405})
#: Largest map held in memory, and largest file streamed to disk, by default.
MAX_MAP_BYTES = 512 << 20
MAX_FILE_BYTES = 4 << 30

Progress = Callable[[int, int], None]


@dataclass(frozen=True)
class FetchedMap:
    """A map fetched from a robot.

    Attributes:
        name: The robot's file name of the map.
        data: The bytes (the robot's file when ``source == "file"``, else ARIA's lines).
        map: The parsed map.
        source: ``"file"`` (getFile, byte-exact) or ``"map service"`` (rebuilt from getMap).
        md5: MD5 of ``data``.
        robot_md5: The MD5 the robot reports for its loaded map ("" when it sends none).
    """

    name: str
    data: bytes
    map: MapData
    source: str
    md5: str
    robot_md5: str = ""

    @property
    def verified(self) -> bool:
        """True when the bytes match the MD5 of the map the robot has loaded."""
        return bool(self.robot_md5) and self.md5 == self.robot_md5


@dataclass(frozen=True)
class LoadResult:
    """The outcome of making a map the robot's active map."""

    name: str
    previous: str
    broadcast: bool
    robot_md5: str = ""


@dataclass(frozen=True)
class MapChange:
    """One version of the robot's active map seen by :meth:`Robot.watch`."""

    name: str
    md5: str
    size: int
    source: str
    map: MapData
    data: bytes = field(default=b"", repr=False)
    initial: bool = False
    saved: str | None = None
    time: float = field(default_factory=time.time)


def _md5(data: bytes) -> str:
    return hashlib.md5(data).hexdigest()


class Robot:
    """A logged-in robot (see the module docstring); close it, or use it in ``with``."""

    def __init__(self, client: AriaClient) -> None:
        self.client = client

    @property
    def address(self) -> str:
        return self.client.address

    def close(self) -> None:
        self.client.close()

    def __enter__(self) -> Robot:
        return self

    def __exit__(
        self, et: type[BaseException] | None, ev: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()

    # -- the map service ------------------------------------------------------------------------

    @property
    def map_name(self) -> str:
        """The active map's file name ("" when the robot has none)."""
        return self.client.call("getMapName").fields().string()

    def map_id(self) -> MapId | None:
        """The robot's id of its loaded map (None when the robot does not offer getMapId)."""
        if not self.client.offers("getMapId"):
            return None
        return MapId.parse(self.client.call("getMapId").fields())

    def services(self) -> dict[str, dict[str, bool]]:
        """For each service mapkit uses, which of its commands this user may use."""
        return {
            svc: {name: self.client.offers(name) for name in names}
            for svc, names in SERVICES.items()
        }

    def info(self) -> dict[str, Any]:
        """The robot, its active map and what this user may do (JSON-ready)."""
        mid = self.map_id()
        name = self.map_name if self.client.offers("getMapName") else None
        svc = self.services()
        return {
            "address": self.address,
            "user": self.client.user,
            "map": name,
            "map_id": None
            if mid is None
            else {
                "file": mid.file_name,
                "md5": mid.md5,
                "size": mid.size,
                "timestamp": mid.timestamp,
            },
            "services": svc,
            "can": {
                "fetch_map": svc["map"]["getMap"] or svc["files"]["getFile"],
                "fetch_exact": svc["files"]["getFile"],
                "list_files": svc["files"]["getDirListingMultiplePackets"],
                "upload": svc["files"]["putFile"],
                "delete": svc["files"]["deleteFile"],
                "load_map": svc["config"]["setConfigBySectionsV2"] or svc["config"]["setConfig"],
                "watch": svc["map"]["mapUpdated"],
            },
            "commands": len(self.client.commands),
        }

    def _map_lines(self, max_size: int) -> bytes:
        parts: list[bytes] = []
        total = 0
        for reply in self.client.call_until_empty("getMap"):
            line = reply.fields().str_bytes()
            total += len(line) + 1
            if total > max_size:
                raise AriaProtocolError(
                    f"{self.address}: the map service sent more than {max_size} bytes of map"
                )
            parts.append(line)
        if parts and parts[-1] == b"":
            parts.pop()
        return b"".join(p + b"\n" for p in parts)

    def fetch(
        self,
        name: str | None = None,
        *,
        via: str = "auto",
        max_size: int = MAX_MAP_BYTES,
        progress: Progress | None = None,
    ) -> FetchedMap:
        """Fetch and parse the active map, or map file ``name`` from the robot's folder.

        Args:
            name: A map file on the robot (default: the active map).
            via: ``"auto"`` (file service when allowed, else map service), ``"file"`` or
                ``"map"``.
            max_size: Refuse maps larger than this many bytes.
            progress: Called with (bytes so far, 0) while the file arrives.

        Raises:
            AriaRemoteError: No active map, a missing file, or bytes that do not match the
                robot's map id.
            AriaPermissionError: When this user may use neither service.
            MapFormatError: When what arrived is not a map.
        """
        active = self.map_name if self.client.offers("getMapName") else ""
        target = name or active
        if not target:
            raise AriaRemoteError(f"the robot at {self.address} has no active map")
        is_active = target == active
        mid = self.map_id() if is_active else None
        robot_md5 = mid.md5 if mid is not None else ""
        use_file = via == "file" or (
            via == "auto" and (self.client.offers("getFile") or not is_active)
        )
        if use_file:
            digest = hashlib.md5()
            parts = []
            for part in self._file_chunks(target, max_size, progress):
                digest.update(part)  # while the robot sends the next chunk
                parts.append(part)
            data = b"".join(parts)
            md5, source = digest.hexdigest(), "file"
            if robot_md5 and md5 != robot_md5:
                if via == "file" or not self.client.offers("getMap"):
                    raise AriaRemoteError(
                        f"robot file '{target}' (MD5 {md5}) is not the map the robot has loaded "
                        f"(MD5 {robot_md5}): it changed on the robot since it was loaded"
                    )
                log.warning(
                    "robot file %s (MD5 %s) differs from the loaded map (MD5 %s); "
                    "taking the loaded map from the map service",
                    target,
                    md5,
                    robot_md5,
                )
                use_file = False
        if not use_file:
            if not is_active:
                raise AriaRemoteError(
                    f"the map service sends only the active map ('{active}'), not '{target}'"
                )
            self.client.command_check("getMap")
            data = self._map_lines(max_size)
            md5, source = _md5(data), "map service"
        m = loads(data, source=f"{self.address}/{target}")
        return FetchedMap(target, data, m, source, md5, robot_md5)

    def fetch_map(self, name: str | None = None) -> MapData:
        """The active map (or map file ``name``) as :class:`MapData`."""
        return self.fetch(name).map

    def save_map(
        self, path: str | os.PathLike[str], name: str | None = None, **kw: Any
    ) -> FetchedMap:
        """Fetch (see :meth:`fetch`) and write the bytes atomically to ``path``."""
        got = self.fetch(name, **kw)
        atomic_write(path, got.data)
        return got

    # -- files ----------------------------------------------------------------------------------

    def files(self, folder: str = "") -> list[DirEntry]:
        """The entries of a robot folder ("" is the top of what the robot shares)."""
        out: list[DirEntry] = []
        data = Payload().string(folder).bytes()
        for reply in self.client.call_until_empty("getDirListingMultiplePackets", data):
            out.extend(dir_listing(reply.fields(), folder)[1])
        return sorted(out, key=lambda e: (not e.is_dir, e.name))

    def _file_chunks(
        self, remote: str, max_size: int, progress: Progress | None
    ) -> Iterator[bytes]:
        arg = Payload().string(remote).ubyte2(0).bytes()
        total = 0
        ended = False
        for reply in self.client.call_until_empty("getFile", arg):
            if ended:
                raise AriaProtocolError(f"{self.address}: data for '{remote}' after its end")
            chunk = file_chunk(reply.fields(), remote)
            if not chunk.data:
                ended = True
                continue
            total += len(chunk.data)
            if total > max_size:
                raise AriaProtocolError(
                    f"{self.address}: robot file '{remote}' is larger than {max_size} bytes"
                )
            if progress is not None:
                progress(total, 0)
            yield chunk.data
        if not ended:
            raise AriaProtocolError(
                f"{self.address}: the reply for '{remote}' ended without its end-of-file packet"
            )

    def read_file(
        self, remote: str, *, max_size: int = MAX_MAP_BYTES, progress: Progress | None = None
    ) -> bytes:
        """A robot file's bytes (in memory; see :meth:`get_file` for large files)."""
        return b"".join(self._file_chunks(remote, max_size, progress))

    def get_file(
        self,
        remote: str,
        local: str | os.PathLike[str],
        *,
        max_size: int = MAX_FILE_BYTES,
        progress: Progress | None = None,
    ) -> int:
        """Download a robot file to ``local`` (atomically: all of it or nothing); its size."""
        n = 0
        with atomic_open(local) as fh:
            for part in self._file_chunks(remote, max_size, progress):
                fh.write(part)
                n += len(part)
        return n

    def put_file(
        self, data: bytes | mmap.mmap | memoryview, remote: str, *, progress: Progress | None = None
    ) -> None:
        """Upload ``data`` (bytes, or any buffer such as a mapped file) as robot file ``remote``
        (the robot stages it and renames it)."""
        self.client.command_check("putFile")
        sent = 0
        for payload in put_payloads(remote, data):
            self.client.send("putFile", payload)
            sent += max(0, len(payload) - len(remote) - 7)
            if progress is not None:
                progress(min(sent, len(data)), len(data))
        while True:
            reply = self.client.expect("putFile", f"uploading '{remote}'")
            try:
                code = put_result(reply.fields(), remote)
            except AriaError:
                self.client.close()  # the server answers each later chunk too: start afresh
                raise
            if code == 0:
                return

    def delete_file(self, remote: str) -> None:
        """Delete a robot file."""
        arg = Payload().string(remote).bytes()
        delete_result(self.client.call("deleteFile", arg).fields(), remote)

    def _exists(self, remote: str) -> bool:
        folder, _, base = remote.rpartition("/")
        if not self.client.offers("getDirListingMultiplePackets"):
            return False
        try:
            return any(e.name == base and not e.is_dir for e in self.files(folder))
        except AriaRemoteError:
            return False

    # -- the active map -------------------------------------------------------------------------

    def _set_config(self, section: str, values: dict[str, str]) -> str:
        payload = config_payload(section, values)
        if self.client.offers("setConfigBySectionsV2"):
            self.client.send("setConfigBySectionsV2", payload)
            first = self.client.expect("setConfigBySectionsV2").fields()
            first.string()
            error = first.string() if first.remaining else ""
            self.client.send("setConfigBySectionsV2", b"")
            last = self.client.expect("setConfigBySectionsV2").fields()
            last.string()
            final = last.string() if last.remaining else ""
            return error or final
        self.client.command_check("setConfig")
        return self.client.call("setConfig", payload).fields().string()

    def load_map(self, name: str, *, wait: float = 10.0, expect_md5: str = "") -> LoadResult:
        """Make robot file ``name`` the active map (config ``Files``/``Map``) and confirm it.

        Raises:
            AriaRemoteError: When the robot cannot load it (its previous map stays active).
        """
        previous = self.map_name
        watching = self.client.offers("mapUpdated")
        if watching:
            self.client.subscribe("mapUpdated")
            self.client.drain_broadcasts("mapUpdated")
        error = self._set_config("Files", {"Map": name})
        broadcast = False
        if not error and watching:
            # a new file of the active map's name is reloaded too, if it changed: wait less
            broadcast = self.client.next_broadcast(wait if name != previous else 1.0) is not None
        now = self.map_name
        mid = self.map_id()
        robot_md5 = mid.md5 if mid is not None else ""
        if not error and now != name:
            error = f"the robot still reports '{now}'"
        if not error and expect_md5 and robot_md5 and robot_md5 != expect_md5:
            error = f"the robot's map id has MD5 {robot_md5}, not {expect_md5}"
        if watching:
            self.client.unsubscribe("mapUpdated")
        if error:
            put_back = ""
            if previous and self.map_name != previous:
                again = self._set_config("Files", {"Map": previous})
                put_back = (
                    f"; put '{previous}' back"
                    if not again
                    else f"; putting '{previous}' back failed too: {again}"
                )
            raise AriaRemoteError(
                f"the robot could not load '{name}': {error}"
                + (put_back or f"; it still uses '{previous}'")
            )
        return LoadResult(name, previous, broadcast, robot_md5)

    def send_map(
        self,
        map_or_path: MapData | str | os.PathLike[str] | bytes,
        name: str | None = None,
        *,
        load: bool = False,
        check: bool = True,
        progress: Progress | None = None,
    ) -> dict[str, Any]:
        """Upload a map (checked first), and with ``load`` make it the robot's active map.

        Args:
            map_or_path: A map file, its bytes, or a :class:`MapData` (written as ARIA does).
            name: The robot file name (default: the local file's name).
            load: Switch the robot to it; on failure the robot's previous file and map return.
            check: Refuse maps with errors that would stop ARIA loading them.

        Raises:
            AriaMapRefusedError: When the map has such errors (nothing was sent).
            AriaRemoteError: When the robot refuses the file or cannot load it.
        """
        if isinstance(map_or_path, MapData):
            data = dumpb(map_or_path)
            src = name or "map"
        elif isinstance(map_or_path, bytes):
            data, src = map_or_path, name or "map"
        else:
            data, src = Path(map_or_path).read_bytes(), os.fspath(map_or_path)
        name = name or os.path.basename(src)
        if not name or name.endswith("/"):
            raise AriaRemoteError("a robot file name is needed to send a map")
        if check:
            self._check(data, src)
        md5 = _md5(data)
        old: bytes | None = None
        if load and self._exists(name):
            old = self.read_file(name)
        self.put_file(data, name, progress=progress)
        result: dict[str, Any] = {"name": name, "size": len(data), "md5": md5, "loaded": False}
        if load:
            try:
                res = self.load_map(name, expect_md5=md5)
            except AriaRemoteError as e:
                self._undo_upload(name, old)
                raise AriaRemoteError(
                    f"{e}; {'restored' if old is not None else 'removed'} robot file '{name}'",
                    e.code,
                ) from e
            result.update(
                loaded=True, previous=res.previous, broadcast=res.broadcast, robot_md5=res.robot_md5
            )
        return result

    def _undo_upload(self, name: str, old: bytes | None) -> None:
        try:
            if old is not None:
                self.put_file(old, name)
            elif self.client.offers("deleteFile"):
                self.delete_file(name)
        except AriaError as e:
            log.warning("could not undo the upload of %s: %s", name, e)

    @staticmethod
    def _check(data: bytes, src: str) -> None:
        from mapkit.validate import validate

        report = validate(data, navigation=False, source=src)
        stoppers = [i for i in report.errors if int(i.code) in LOAD_STOPPERS]
        if stoppers:
            more = f" (and {len(stoppers) - 1} more)" if len(stoppers) > 1 else ""
            raise AriaMapRefusedError(f"not sent, ARIA would not load it: {stoppers[0]}{more}")
        loads(data, source=src)  # a map at all (raises MapFormatError with file:line)

    # -- watching -------------------------------------------------------------------------------

    def watch(
        self,
        *,
        save_dir: str | os.PathLike[str] | None = None,
        initial: bool = True,
        stop: Callable[[], bool] | None = None,
        tick: float = 1.0,
    ) -> Iterator[MapChange]:
        """Yield the active map now (``initial``) and again each time the robot changes it.

        Args:
            save_dir: Also keep each version there as ``NAME-YYYYmmdd-HHMMSS-MD5.map``.
            stop: Checked every ``tick`` seconds; the watch ends when it returns True.
        """
        self.client.command_check("mapUpdated")
        self.client.subscribe("mapUpdated")
        last_md5 = ""
        first = True
        last_ping = time.monotonic()
        while True:
            if not first:
                self.client.keepalive()
                b = self.client.next_broadcast(tick)
                if b is None:
                    if stop is not None and stop():
                        return
                    if time.monotonic() - last_ping > max(5.0, self.client.timeout / 3):
                        self.map_name  # noqa: B018  (a ping: fails fast on a dead robot)
                        last_ping = time.monotonic()
                    continue
                self.client.drain_broadcasts("mapUpdated")
            got = self.fetch()
            last_ping = time.monotonic()
            was_first, first = first, False
            if got.md5 == last_md5 or (was_first and not initial):
                last_md5 = got.md5
                continue
            last_md5 = got.md5
            saved = None
            if save_dir is not None:
                stem = Path(got.name).stem or "map"
                when = time.strftime("%Y%m%d-%H%M%S")
                saved = os.path.join(save_dir, f"{stem}-{when}-{got.md5[:8]}.map")
                os.makedirs(save_dir, exist_ok=True)
                atomic_write(saved, got.data)
            yield MapChange(
                got.name, got.md5, len(got.data), got.source, got.map, got.data, was_first, saved
            )
            if stop is not None and stop():
                return


def connect(
    address: str,
    *,
    user: str = "",
    password: str | bytes = "",
    port: int | None = None,
    timeout: float = 15.0,
) -> Robot:
    """Connect and log in to a robot's ArNetworking server (``host[:port]``, port 7272).

    Raises:
        AriaConnectionError, AriaLoginError, AriaTimeoutError, AriaProtocolError.
    """
    host, p = parse_host(address, DEFAULT_PORT if port is None else port)
    client = AriaClient(host, p, user=user, password=password, timeout=timeout)
    return Robot(client.open())
