"""Atomic file replacement: temp file in the same folder, fsync, rename, fsync the folder.

A failed write never leaves a half-written file under the target name: the old file (if any)
stays as it was.

A writer killed with SIGKILL (or by a power cut) cannot remove its temp file. Temp files are
named ``.NAME.PID-XXXXXXXX.tmp`` (the writer's process id and 8 random characters), and each
later write to ``NAME`` first removes the stale ones of that same target (see
:func:`remove_stale_temps`): those whose writer process is gone, and any of our pattern older
than :data:`STALE_AGE` (which also covers the older ``.NAME.XXXXXXXX.tmp`` names without a pid).
Nothing else is touched: not other targets' temp files, not files of another pattern.
"""

from __future__ import annotations

import contextlib
import os
import re
import tempfile
import time
from collections.abc import Iterable, Iterator
from typing import BinaryIO

from mapkit._typing import PathLike

__all__ = ["STALE_AGE", "atomic_open", "atomic_write", "fsync_dir", "remove_stale_temps"]

#: Seconds after which a temp file of our pattern is stale even if its writer's pid is in use
#: (pids are reused); no atomic write of mapkit takes that long.
STALE_AGE = 3600.0


def fsync_dir(folder: PathLike) -> None:
    """Flush a folder's entries to disk (best effort where the OS does not allow it)."""
    try:
        fd = os.open(os.fspath(folder), os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


@contextlib.contextmanager
def atomic_open(path: PathLike, *, backup: bool = False) -> Iterator[BinaryIO]:
    """Open a temp file beside ``path`` for binary writing; on success it replaces ``path``.

    The temp file is flushed and fsynced before the rename, and the folder after it. On any
    exception the temp file is removed and ``path`` is untouched.

    Args:
        path: The final file.
        backup: Keep the previous file as ``path + ".bak"`` (hard link, or copy where links fail).

    Yields:
        A binary file object.

    Raises:
        OSError: When the folder cannot be written (full disk, permissions, ...).
    """
    target = os.fspath(path)
    folder = os.path.dirname(os.path.abspath(target))
    with contextlib.suppress(OSError):  # best effort: a write never fails for want of a cleanup
        remove_stale_temps(target)
    fd, tmp = tempfile.mkstemp(prefix=f".{os.path.basename(target)}.{os.getpid()}-", suffix=".tmp",
                               dir=folder)
    try:
        with os.fdopen(fd, "wb") as fh:
            yield fh
            fh.flush()
            os.fsync(fh.fileno())
        if os.path.exists(target):
            with contextlib.suppress(OSError):
                os.chmod(tmp, os.stat(target).st_mode & 0o7777)
            if backup:
                bak = target + ".bak"
                with contextlib.suppress(FileNotFoundError):
                    os.unlink(bak)
                try:
                    os.link(target, bak)
                except OSError:
                    import shutil

                    shutil.copy2(target, bak)
        else:
            os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, target)
        fsync_dir(folder)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise


def _pid_alive(pid: int) -> bool:
    if pid == os.getpid():
        return True  # another thread of this process may be writing
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OverflowError):
        return pid > 0  # exists, owned by someone else (or not a real pid: let age decide)
    return True


def remove_stale_temps(path: PathLike, *, max_age: float = STALE_AGE,
                       now: float | None = None) -> list[str]:
    """Remove the stale temp files that interrupted atomic writes of ``path`` left beside it.

    A temp file of ``path`` is ``.NAME.PID-XXXXXXXX.tmp`` (or ``.NAME.XXXXXXXX.tmp`` from
    earlier mapkit versions), ``XXXXXXXX`` being 8 of :func:`tempfile.mkstemp`'s characters.
    It is removed when it is a regular file and its writer process is gone, or it is older
    than ``max_age`` seconds.

    Returns:
        The paths removed.

    Examples:
        >>> import tempfile, pathlib
        >>> d = pathlib.Path(tempfile.mkdtemp())
        >>> _ = (d / ".a.map.999999999-abcd_123.tmp").write_bytes(b"killed")  # no such pid
        >>> _ = (d / ".a.map.notours.tmp").write_bytes(b"kept")
        >>> [os.path.basename(p) for p in remove_stale_temps(d / "a.map")]
        ['.a.map.999999999-abcd_123.tmp']
        >>> sorted(p.name for p in d.iterdir())
        ['.a.map.notours.tmp']
    """
    target = os.fspath(path)
    folder = os.path.dirname(os.path.abspath(target))
    base = os.path.basename(target)
    pattern = re.compile(r"\." + re.escape(base) + r"\.(?:(\d{1,10})-)?[a-z0-9_]{8}\.tmp\Z")
    now = time.time() if now is None else now
    removed = []
    with os.scandir(folder) as it:
        for entry in it:
            m = pattern.match(entry.name)
            if m is None or not entry.is_file(follow_symlinks=False):
                continue
            try:
                age = now - entry.stat(follow_symlinks=False).st_mtime
            except FileNotFoundError:
                continue
            pid = m.group(1)
            if age >= max_age or (pid is not None and not _pid_alive(int(pid))):
                with contextlib.suppress(FileNotFoundError):
                    os.unlink(entry.path)
                    removed.append(entry.path)
    return removed


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def atomic_write(path: PathLike, data: bytes | Iterable[bytes], *, backup: bool = False) -> None:
    """Write bytes (or an iterable of byte chunks) to ``path`` atomically.

    Args:
        path: The final file.
        data: The content.
        backup: Keep the previous file as ``path + ".bak"``.

    Raises:
        OSError: When the write fails; ``path`` is then unchanged.

    Examples:
        >>> import tempfile, pathlib
        >>> p = pathlib.Path(tempfile.mkdtemp()) / "a.txt"
        >>> atomic_write(p, b"hello")
        >>> p.read_bytes()
        b'hello'
    """
    with atomic_open(path, backup=backup) as fh:
        if isinstance(data, (bytes, bytearray, memoryview)):
            fh.write(data)
        else:
            for chunk in data:
                fh.write(chunk)
