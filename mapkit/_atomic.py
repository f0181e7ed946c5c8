"""Atomic file replacement: temp file in the same folder, fsync, rename, fsync the folder.

A failed write never leaves a half-written file under the target name: the old file (if any)
stays as it was.
"""

from __future__ import annotations

import contextlib
import contextvars
import errno
import os
from collections.abc import Iterable, Iterator
from typing import BinaryIO

from mapkit._typing import PathLike

__all__ = [
    "ReadOnlyFileError",
    "WriteError",
    "atomic_open",
    "atomic_write",
    "check_writable",
    "fsync_dir",
    "is_read_only",
    "write_error",
    "replace_read_only",
]

#: When true, a read-only file may be replaced (``mapkit ... --force`` sets it for one command).
replace_read_only: contextvars.ContextVar[bool] = contextvars.ContextVar(
    "replace_read_only", default=False
)


class WriteError(OSError):
    """A file could not be written. ``filename`` is the file asked for (never a temp file) and
    ``strerror`` says why in words: ``folder is read-only``, ``folder ... does not exist``."""


#: Errors of writing the temp file or renaming it (not, say, a dropped connection in the body).
_WRITE_ERRNOS = frozenset(
    {errno.ENOSPC, errno.EDQUOT, errno.EROFS, errno.EACCES, errno.EPERM, errno.EFBIG, errno.EIO,
     errno.ENOENT, errno.EISDIR, errno.ENOTDIR, errno.EXDEV}
)


class ReadOnlyFileError(WriteError):
    """The file exists and is read-only; it is replaced only under :data:`replace_read_only`."""


def write_error(target: str, err: OSError | None, why: str | None = None) -> WriteError:
    """The :class:`WriteError` for ``target`` (the user's name for it) from the OS error ``err``,
    with the reason in words: ``folder out does not exist``, ``folder out is read-only``."""
    folder = os.path.dirname(target) or "."
    code = err.errno if err is not None else errno.EACCES
    if why is None:
        if code == errno.ENOENT:
            why = f"folder {folder} does not exist"
        elif code == errno.ENOTDIR:
            why = f"{folder} is not a folder"
        elif code in (errno.EACCES, errno.EPERM, errno.EROFS):
            why = f"folder {folder} is read-only"
        elif code == errno.EISDIR:
            why = "it is a folder"
        else:
            why = err.strerror if err is not None and err.strerror else str(err)
    return WriteError(code or errno.EIO, why, target)


def is_read_only(path: PathLike) -> bool:
    """True for an existing file nobody may write (``chmod a-w``), or that this user may not."""
    try:
        mode = os.stat(path).st_mode
    except OSError:
        return False
    return not mode & 0o222 or not os.access(path, os.W_OK)


def check_writable(path: PathLike, *, probe: bool = True) -> None:
    """Raise :class:`WriteError` now if ``path`` could not be written by :func:`atomic_open`.

    For work that takes long before it writes: say at once that the folder is missing or
    read-only, or that ``path`` is a read-only file (see :data:`replace_read_only`). With
    ``probe`` a temp file is made and removed in the folder, the only sure test (root, read-only
    mounts).
    """
    shown = os.fspath(path)
    target = os.path.realpath(shown)
    folder = os.path.dirname(target)
    if os.path.isdir(target):
        raise write_error(shown, None, "it is a folder")
    if not os.path.isdir(folder):
        missing = not os.path.exists(folder)
        raise write_error(shown, OSError(errno.ENOENT if missing else errno.ENOTDIR, ""))
    if is_read_only(target) and not replace_read_only.get():
        raise ReadOnlyFileError(errno.EACCES, "the file is read-only", shown)
    if probe:
        import tempfile  # here: it brings shutil, bz2, lzma, which most commands never need

        try:
            fd, tmp = tempfile.mkstemp(prefix=".mapkit-probe.", suffix=".tmp", dir=folder)
        except OSError as err:
            raise write_error(shown, err) from err
        os.close(fd)
        os.unlink(tmp)


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

    A symlink is followed (the file it points to is replaced, the link stays); the new file
    keeps the old one's permission bits. A read-only file is not replaced unless
    :data:`replace_read_only` is set.

    Raises:
        WriteError: When the file cannot be written (missing or read-only folder, read-only file,
            full disk, ...); it names ``path``, not the temp file.
    """
    shown = os.fspath(path)
    check_writable(shown, probe=False)
    target = os.path.realpath(shown)
    folder = os.path.dirname(target)
    import tempfile

    try:
        fd, tmp = tempfile.mkstemp(
            prefix="." + os.path.basename(target) + ".", suffix=".tmp", dir=folder
        )
    except OSError as err:
        raise write_error(shown, err) from err
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
    except BaseException as exc:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        if (
            isinstance(exc, OSError)
            and not isinstance(exc, WriteError)
            and exc.errno in _WRITE_ERRNOS
            and exc.filename in (None, tmp, target, folder)
        ):
            raise write_error(shown, exc) from exc
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
