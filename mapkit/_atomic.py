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
import contextvars
import errno
import os
import re
import time
from collections.abc import Iterable, Iterator
from typing import BinaryIO

from mapkit._typing import PathLike

__all__ = [
    "STALE_AGE",
    "ReadOnlyFileError",
    "WriteError",
    "atomic_open",
    "atomic_write",
    "check_writable",
    "fsync_dir",
    "is_read_only",
    "remove_stale_temps",
    "replace_read_only",
    "write_error",
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
    {
        errno.ENOSPC,
        errno.EDQUOT,
        errno.EROFS,
        errno.EACCES,
        errno.EPERM,
        errno.EFBIG,
        errno.EIO,
        errno.ENOENT,
        errno.EISDIR,
        errno.ENOTDIR,
        errno.EXDEV,
    }
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
    with contextlib.suppress(OSError):  # best effort: a write never fails for want of a cleanup
        remove_stale_temps(target)
    import tempfile

    try:
        fd, tmp = tempfile.mkstemp(
            prefix=f".{os.path.basename(target)}.{os.getpid()}-", suffix=".tmp", dir=folder
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


def remove_stale_temps(
    path: PathLike, *, max_age: float = STALE_AGE, now: float | None = None
) -> list[str]:
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
