"""Atomic file replacement: temp file in the same folder, fsync, rename, fsync the folder.

A failed write never leaves a half-written file under the target name: the old file (if any)
stays as it was.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Iterable, Iterator
from typing import BinaryIO

from mapkit._typing import PathLike

__all__ = ["atomic_open", "atomic_write", "fsync_dir"]


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
    fd, tmp = tempfile.mkstemp(prefix="." + os.path.basename(target) + ".", suffix=".tmp", dir=folder)
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
