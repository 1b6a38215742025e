"""Files that crashstudy creates inside a result folder, created without following symbolic links.

A result folder may hold entries that someone else planted: a symbolic link at
``summary.csv.partial`` pointing at a file elsewhere, or a dangling one at ``results.nc.partial``.
Writing "through" such a link would write outside the folder the user chose. So every file that a
run creates is first freed of whatever entry stands at its name (a link is removed, never followed)
and then created exclusively (``O_CREAT | O_EXCL | O_NOFOLLOW``); the final names are reached by
:func:`os.replace`, which replaces a link instead of writing through it.
"""

from __future__ import annotations

import os
import stat
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import IO, Any

_NOFOLLOW = getattr(os, "O_NOFOLLOW", 0)


class PlantedEntryError(OSError):
    """An entry where crashstudy creates a file is not a regular file (a link, a folder, a device)."""


def clear_entry(path: Path) -> None:
    """Remove a symbolic link or regular file at ``path`` (never what a link points to).

    Raises :class:`PlantedEntryError` for a folder, device, FIFO or socket at that name."""
    try:
        st = os.lstat(path)
    except FileNotFoundError:
        return
    if not (stat.S_ISLNK(st.st_mode) or stat.S_ISREG(st.st_mode)):
        raise PlantedEntryError(f"{path} is in the way: it is not a regular file (remove it and run again)")
    os.unlink(path)


def is_regular(path: Path) -> bool:
    """Whether ``path`` is a regular file itself (a symbolic link, even to a regular file, is not)."""
    try:
        return stat.S_ISREG(os.lstat(path).st_mode)
    except OSError:
        return False


def create_new(path: Path) -> None:
    """Create ``path`` as a new empty regular file (whatever stood there is removed, links not followed)."""
    clear_entry(path)
    os.close(os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL | _NOFOLLOW, 0o644))


def open_new(path: Path, newline: str | None = None, mode: str = "w") -> IO[Any]:
    """A new file at ``path`` opened for writing (``mode`` "w" text, "wb" binary; see :func:`create_new`)."""
    clear_entry(path)
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL | _NOFOLLOW, 0o644)
    return os.fdopen(fd, mode, newline=newline) if "b" not in mode else os.fdopen(fd, mode)


LOCK = ".crashstudy.lock"


class FolderBusy(OSError):
    """Another live process holds the lock of a result folder (``pid``: its process id, 0 if unknown)."""

    def __init__(self, folder: Path, pid: int) -> None:
        super().__init__(f"another crashstudy run is writing {folder}" + (f" (pid {pid})" if pid else ""))
        self.folder, self.pid = folder, pid


@contextmanager
def folder_lock(folder: Path) -> Iterator[None]:
    """Hold an exclusive lock on ``folder`` (created if missing) while the block runs.

    ``fcntl.flock`` on ``folder/.crashstudy.lock``, which holds the owner's pid; a second holder gets
    :class:`FolderBusy` at once. The lock dies with its process (SIGKILL included: the kernel releases
    it), so a file left behind by a killed run locks nothing. The owner removes the file before
    releasing it; a process that locked a file just removed (its inode no longer at the name) tries
    again. A folder this call created is removed again if it is left empty.
    """
    import fcntl

    created = not os.path.lexists(folder)
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / LOCK
    if os.path.islink(path):
        os.unlink(path)  # planted: a lock file is never a link
    for _ in range(100):
        fd = os.open(path, os.O_RDWR | os.O_CREAT | _NOFOLLOW | getattr(os, "O_CLOEXEC", 0), 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raw = os.pread(fd, 32, 0)
            os.close(fd)
            _remove_if_created(folder, created)
            raise FolderBusy(folder, int(raw) if raw.strip().isdigit() else 0) from None
        except BaseException:
            os.close(fd)
            raise
        try:
            same = os.fstat(fd).st_ino == os.lstat(path).st_ino
        except FileNotFoundError:
            same = False
        if same:
            break
        os.close(fd)  # the previous owner removed it after we opened it: lock the new one
    else:  # pragma: no cover - a lock file replaced 100 times in a row
        raise FolderBusy(folder, 0)
    try:
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)
        yield
    finally:
        try:
            os.unlink(path)
        except FileNotFoundError:
            pass
        os.close(fd)  # releases the lock
        _remove_if_created(folder, created)


def _remove_if_created(folder: Path, created: bool) -> None:
    if created:
        try:
            folder.rmdir()  # only if empty: a run refused before writing leaves nothing behind
        except OSError:
            pass
