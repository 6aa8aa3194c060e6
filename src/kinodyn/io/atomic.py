"""Atomic file output: write to a temporary file beside the target, flush it to disk, rename it over.

Every file kinodyn writes (motions, viewer pages, glTF, plots, videos, benchmark results) goes through
:func:`atomic_path`, so a crash or an error while writing never leaves a half-written or truncated file
where the user expects a result, and never destroys the previous version of the file. The data is
flushed to disk (``fsync``) before the rename and the rename is flushed with its folder, so after a
power cut the path holds either the old file or the whole new one.

Errors name the user's path, never the temporary file: an unwritable folder reads
``out/c.bvh: Permission denied``, a folder that is a regular file ``out/c.bvh: cannot create the
folder 'out': a file of that name is in the way``.
"""

from __future__ import annotations

import contextlib
import errno
import os
import tempfile
from pathlib import Path

__all__ = ["FILE_MODE", "atomic_path", "atomic_write_bytes"]

#: permissions of every file written, less the process umask (what a plain ``open(path, "w")`` gives)
FILE_MODE = 0o666


def _make_parent(target: Path) -> None:
    """Create ``target``'s folder, or raise an ``OSError`` naming ``target`` when something is in the way."""
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
    except (FileExistsError, NotADirectoryError):
        blocker = next((p for p in [target.parent, *target.parent.parents] if p.exists() and not p.is_dir()),
                       target.parent)
        raise NotADirectoryError(errno.ENOTDIR, f"cannot create the folder '{target.parent}': "
                                 f"'{blocker}' is a file, not a folder", str(target)) from None
    except OSError as e:
        raise _renamed(e, target) from None


def _renamed(e: OSError, target: Path) -> OSError:
    """``e`` re-pointed at the user's ``target`` (a temporary file's name means nothing to them)."""
    return type(e)(e.errno, e.strerror, str(target)) if e.errno is not None else e


def _fsync(path, directory: bool = False) -> None:
    fd = os.open(path, os.O_RDONLY | (getattr(os, "O_DIRECTORY", 0) if directory else 0))
    try:
        os.fsync(fd)
    except OSError:
        if not directory:  # some file systems cannot sync folders; the data itself is synced
            raise
    finally:
        os.close(fd)


def _open_mode(fd: int) -> None:
    """Give the file behind ``fd`` the permissions ``open()`` would: :data:`FILE_MODE` less the umask.

    ``mkstemp`` creates files readable by their owner only. The umask is read from ``/proc`` where it is
    available: setting it to read it back (``os.umask``) would change it for every thread of the process.
    """
    umask = _current_umask()
    os.fchmod(fd, FILE_MODE & ~umask)


def _current_umask() -> int:
    try:
        with open("/proc/self/status", "rb") as fh:
            for line in fh:
                if line.startswith(b"Umask:"):
                    return int(line.split()[1], 8)
    except OSError:
        pass
    # No /proc: see what the umask takes from a file created with every permission (no process-wide change).
    with tempfile.TemporaryDirectory() as d:
        probe = os.path.join(d, "probe")
        os.close(os.open(probe, os.O_CREAT | os.O_WRONLY, 0o777))
        return 0o777 & ~os.stat(probe).st_mode


@contextlib.contextmanager
def atomic_path(path, suffix: str | None = None):
    """Yield a temporary path beside ``path`` for the caller to write; on success its data is flushed to
    disk and it is renamed to ``path``, on any error it is deleted and ``path`` is left as it was."""
    target = Path(path)
    _make_parent(target)
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=suffix or ".tmp", dir=target.parent)
    except OSError as e:
        raise _renamed(e, target) from None
    try:
        try:
            _open_mode(fd)
        finally:
            os.close(fd)
        yield Path(tmp)
        _fsync(tmp)
        os.replace(tmp, target)
        _fsync(target.parent, directory=True)
    except BaseException as e:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        if isinstance(e, OSError) and e.filename is not None and str(e.filename) == str(tmp):
            raise _renamed(e, target) from None
        raise


def atomic_write_bytes(path, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically (flushed to disk before the rename)."""
    with atomic_path(path) as tmp, open(tmp, "wb") as fh:
        fh.write(data)
