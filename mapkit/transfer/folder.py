"""The robot's folder of maps, without any transport: names, listings with digests, safe writes
through :class:`~mapkit.transfer.store.PartialFile`, reads for pulls, and activating a map with
rollback, for :class:`~mapkit.transfer.server.MapServer` and the ROS binding alike."""

from __future__ import annotations

import contextlib
import hashlib
import json
import logging
import os
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from mapkit._atomic import atomic_write, fsync_dir
from mapkit.errors import MapFormatError
from mapkit.formats.map import parse_map
from mapkit.transfer.protocol import (
    DEFAULT_CHUNK_SIZE,
    Offer,
    Status,
    kind_of,
)
from mapkit.transfer.store import (
    PartialFile,
    StoreError,
    check_name,
    expire_partials,
    file_digests,
)

__all__ = ["ACTIVE_NAME", "PREVIOUS_NAME", "MapFolder", "same_transfer", "validate_map_file"]


log = logging.getLogger("mapkit.transfer.server")  # the robot side logs as one

ACTIVE_NAME = "active.map"
PREVIOUS_NAME = "previous.map"
STATE_NAME = ".mapkit-active.json"
DEFAULT_MAX_SIZE = 1 << 30
DEFAULT_PARTIAL_TTL = 24 * 3600.0  # an interrupted transfer not resumed for a day is abandoned


def validate_map_file(path: str) -> dict[str, Any]:
    """Parse a received ``.map`` file with mapkit; returns ``{"md5": ...}``.

    Raises:
        StoreError: ``PARSE_ERROR`` with the parser's message (file and line).
    """
    with open(path, "rb") as fh:
        data = fh.read()
    name = os.path.basename(path)
    if name.startswith(".") and name.endswith(".mkpart"):
        name = name[1 : -len(".mkpart")]
    try:
        parse_map(data, source=name)
    except MapFormatError as err:
        raise StoreError(f"not a valid map: {err}", Status.PARSE_ERROR) from err
    return {"md5": hashlib.md5(data).hexdigest(), "kind": "map"}


def same_transfer(a: Offer, b: Offer) -> bool:
    """True when two offers are the same transfer: same name, SHA-256, size and chunk size
    (the resume journal and every chunk offset then mean the same bytes)."""
    return (a.name, a.sha256, a.size, a.chunk_size) == (b.name, b.sha256, b.size, b.chunk_size)


def _validator(name: str) -> Callable[[str], dict[str, Any]] | None:
    return validate_map_file if kind_of(name) == "map" else None


@dataclass
class _Digest:
    key: tuple[int, int, int, int]
    sha256: str
    md5: str


class MapFolder:
    """A folder of maps: the file-system side of the server, without any networking.

    Args:
        root: The folder (created if missing).
        max_size: Largest file accepted, in bytes.
        suffixes: Accepted file suffixes.
        reserve: Bytes to keep free on the device.
        on_load: Called with ``(name, active_path)`` after a map became active.
    """

    def __init__(
        self,
        root: str | os.PathLike[str],
        *,
        max_size: int = DEFAULT_MAX_SIZE,
        suffixes: tuple[str, ...] = (".map", ".2d"),
        reserve: int = 1 << 20,
        on_load: Callable[[str, str], None] | None = None,
    ) -> None:
        self.root = os.path.abspath(os.fspath(root))
        os.makedirs(self.root, exist_ok=True)
        self.max_size = max_size
        self.suffixes = suffixes
        self.reserve = reserve
        self.on_load = on_load
        self._digests: dict[str, _Digest] = {}
        self._valid: dict[str, None] = {}  # SHA-256 of map contents that parsed (recent first)
        self._lock = threading.Lock()
        self._load_lock = threading.Lock()
        self._partials: list[PartialFile] = []  # destinations being written (disk ledger)

    # names and digests ----------------------------------------------------------------------------
    def check_name(self, name: object) -> str:
        """:func:`~mapkit.transfer.store.check_name` with this folder's suffixes and reserved
        names."""
        return check_name(name, suffixes=self.suffixes, reserved=(ACTIVE_NAME, PREVIOUS_NAME))

    def path(self, name: str) -> str:
        """The path of a (checked) name."""
        return os.path.join(self.root, name)

    def _open(self, name: str) -> int:
        try:
            return os.open(self.path(name), os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0))
        except FileNotFoundError as err:
            raise StoreError(f"{name}: no such map on this robot", Status.NOT_FOUND) from err
        except OSError as err:
            raise StoreError(f"{name}: {err.strerror}", Status.IO_ERROR) from err

    def digests(self, name: str, fd: int | None = None) -> tuple[str, str, os.stat_result]:
        """``(sha256, md5, stat)`` of a file in the folder, cached by inode, size and mtime."""
        own = fd is None
        if fd is None:
            fd = self._open(name)
        try:
            st = os.fstat(fd)
            key = (st.st_ino, st.st_size, st.st_mtime_ns, st.st_ctime_ns)
            with self._lock:
                d = self._digests.get(name)
            if d is None or d.key != key:
                sha, md5 = file_digests(fd, st.st_size)
                assert md5 is not None
                d = _Digest(key, sha, md5)
                with self._lock:
                    self._digests[name] = d
            return d.sha256, d.md5, st
        finally:
            if own:
                os.close(fd)

    def state(self) -> dict[str, Any]:
        """The active-map record (``{}`` when no map was loaded)."""
        try:
            with open(os.path.join(self.root, STATE_NAME), encoding="utf-8") as fh:
                d = json.load(fh)
            return d if isinstance(d, dict) else {}
        except (OSError, ValueError):
            return {}

    def listing(self) -> dict[str, Any]:
        """Every map in the folder with size, MD5, SHA-256, mtime and whether it is active."""
        state = self.state()
        maps = []
        for entry in sorted(os.scandir(self.root), key=lambda e: e.name):
            try:
                self.check_name(entry.name)
            except StoreError:
                continue
            if not entry.is_file(follow_symlinks=False):
                continue
            try:
                sha, md5, st = self.digests(entry.name)
            except (StoreError, OSError):
                continue
            maps.append(
                {
                    "name": entry.name,
                    "size": st.st_size,
                    "md5": md5,
                    "sha256": sha,
                    "mtime": round(st.st_mtime, 3),
                    "kind": kind_of(entry.name),
                    "active": entry.name == state.get("name") and sha == state.get("sha256"),
                }
            )
        return {
            "maps": maps,
            "active": state.get("name"),
            "active_md5": state.get("md5"),
            "previous": (state.get("previous") or {}).get("name"),
        }

    # transfers ------------------------------------------------------------------------------------
    def begin_write(self, offer: Offer, *, checkpoint_interval: float = 0.5) -> PartialFile:
        """Check an incoming offer and open its destination (resuming a partial one).

        Raises:
            StoreError: ``BAD_NAME``, ``TOO_LARGE``, ``NO_SPACE``, ``BUSY`` or ``IO_ERROR``.
        """
        name = self.check_name(offer.name)
        if offer.size > self.max_size:
            raise StoreError(
                f"{name} has {offer.size} bytes, this robot accepts at most {self.max_size}",
                Status.TOO_LARGE,
            )
        check = _validator(name)

        def validate(path: str) -> dict[str, Any]:
            assert check is not None
            info = check(path)  # called after the SHA-256 check: the content is offer.sha256
            self._parsed(offer.sha256)
            return info

        with self._lock:  # the disk other transfers in progress may still take
            self._partials = [p for p in self._partials if p.is_open]
            pending = sum(p.outstanding for p in self._partials if p.name != name)
        dest = PartialFile.open(
            self.root,
            name,
            offer,
            checkpoint_interval=checkpoint_interval,
            validate=validate if check else None,
            reserve=self.reserve + pending,
        )
        with self._lock:
            self._partials.append(dest)
        return dest

    def expire_partials(self, max_age: float) -> list[str]:
        """Delete partial files no session holds and nothing touched for ``max_age`` seconds
        (see :func:`~mapkit.transfer.store.expire_partials`); returns their names."""
        return expire_partials(self.root, max_age)

    def _parsed(self, sha256: str) -> None:
        with self._lock:
            self._valid.pop(sha256, None)
            self._valid[sha256] = None
            while len(self._valid) > 256:
                del self._valid[next(iter(self._valid))]

    def open_read(self, name: str, *, chunk_size: int = DEFAULT_CHUNK_SIZE) -> tuple[int, Offer]:
        """Open a map for a pull: ``(fd, offer)``; the fd is a snapshot even if the file is
        replaced.

        Raises:
            StoreError: ``BAD_NAME``, ``NOT_FOUND``, ``IO_ERROR``.
        """
        if name in (ACTIVE_NAME, PREVIOUS_NAME):
            check_name(name, suffixes=self.suffixes)
        else:
            self.check_name(name)
        fd = self._open(name)
        try:
            sha, md5, st = self.digests(name, fd)
        except BaseException:
            os.close(fd)
            raise
        kind = kind_of(name)
        return fd, Offer(
            name,
            st.st_size,
            sha,
            chunk_size,
            md5 if kind == "map" else None,
            kind,
            round(st.st_mtime, 3),
        )

    # activation -----------------------------------------------------------------------------------
    def load(
        self, name: str | None, md5: str | None = None, *, rollback: bool = False
    ) -> dict[str, Any]:
        """Make a map the active one (or go back to the previous one).

        The file is read once; those bytes are checked (MD5, then parsed by mapkit) and written
        atomically to ``active.map`` after the current ``active.map`` was kept as ``previous.map``.

        Args:
            name: The map to activate (ignored with ``rollback``).
            md5: Expected MD5 (hex); the load is refused if the file differs.
            rollback: Re-activate ``previous.map``.

        Returns:
            The new state: ``{"name", "md5", "sha256", "loaded_at", "previous"}``.

        Raises:
            StoreError: ``BAD_NAME``, ``NOT_FOUND``, ``MD5_MISMATCH``, ``PARSE_ERROR``,
                ``IO_ERROR``.
        """
        with self._load_lock:
            state = self.state()
            if rollback:
                prev = state.get("previous")
                if not prev or not os.path.exists(self.path(PREVIOUS_NAME)):
                    raise StoreError("no previous map to roll back to", Status.NOT_FOUND)
                src, src_name = self.path(PREVIOUS_NAME), str(prev.get("name"))
            else:
                src_name = self.check_name(name)
                src = self.path(src_name)
            try:
                fd = os.open(src, os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0))
                with os.fdopen(fd, "rb") as fh:
                    data = fh.read()
            except FileNotFoundError as err:
                raise StoreError(
                    f"{src_name}: no such map on this robot", Status.NOT_FOUND
                ) from err
            except OSError as err:
                raise StoreError(
                    f"{src_name}: cannot read it: {err.strerror or err}", Status.IO_ERROR
                ) from err
            got = hashlib.md5(data).hexdigest()
            if md5 and got != md5.lower():
                raise StoreError(
                    f"{src_name} on the robot has MD5 {got}, expected {md5.lower()}",
                    Status.MD5_MISMATCH,
                )
            sha = hashlib.sha256(data).hexdigest()
            with self._lock:
                known = sha in self._valid
            if not known:  # content that parsed when it arrived parses now: mapkit is deterministic
                try:
                    parse_map(data, source=src_name)
                except MapFormatError as err:
                    raise StoreError(f"not a valid map: {err}", Status.PARSE_ERROR) from err
                self._parsed(sha)
            active = self.path(ACTIVE_NAME)
            try:
                if os.path.exists(active):
                    tmp = self.path(f".{PREVIOUS_NAME}.tmp")
                    with contextlib.suppress(FileNotFoundError):
                        os.unlink(tmp)
                    try:
                        os.link(active, tmp)
                    except OSError:
                        import shutil

                        shutil.copyfile(active, tmp)
                    os.replace(tmp, self.path(PREVIOUS_NAME))
                atomic_write(active, data)
                new = {
                    "name": src_name,
                    "md5": got,
                    "sha256": sha,
                    "size": len(data),
                    "loaded_at": round(time.time(), 3),
                    "previous": {k: state[k] for k in ("name", "md5", "sha256") if k in state}
                    or None,
                }
                atomic_write(
                    os.path.join(self.root, STATE_NAME), json.dumps(new, indent=1).encode()
                )
                fsync_dir(self.root)
            except OSError as err:
                raise StoreError(
                    f"cannot activate {src_name}: {err.strerror or err}",
                    Status.NO_SPACE if err.errno == 28 else Status.IO_ERROR,
                ) from err
        log.info("active map is now %s (MD5 %s)", src_name, got)
        if self.on_load is not None:
            self.on_load(src_name, active)
        return new
