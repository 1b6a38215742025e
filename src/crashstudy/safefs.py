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
        try:
            fd = os.open(
                path, os.O_RDWR | os.O_CREAT | _NOFOLLOW | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0), 0o644
            )
        except OSError as exc:  # a folder there (EISDIR), a link planted since (ELOOP)
            raise PlantedEntryError(_lock_problem(path, exc)) from None
        if not stat.S_ISREG(os.fstat(fd).st_mode):  # a FIFO or device planted there: flock says only EINVAL
            os.close(fd)
            _remove_if_created(folder, created)
            raise PlantedEntryError(_lock_problem(path, None))
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


def _lock_problem(path: Path, exc: OSError | None) -> str:
    what = "it is not a regular file" if exc is None else (exc.strerror or "it cannot be opened")
    return (
        f"the lock file {path} cannot be used: {what}; crashstudy expects a regular file there (or nothing) "
        "that it creates itself: remove it and run again"
    )


def _remove_if_created(folder: Path, created: bool) -> None:
    if created:
        try:
            folder.rmdir()  # only if empty: a run refused before writing leaves nothing behind
        except OSError:
            pass


# --- the one writer: every file a command writes goes through these -------------------------------


def staging(path: Path) -> Path:
    """The temporary name a file is written under before it replaces ``path``."""
    return path.with_name(path.name + ".partial")


def commit(tmp: Path, path: Path) -> None:
    """Rename the staged ``tmp`` over ``path``: a link there is replaced (never followed); a folder,
    FIFO or device there is refused (:class:`PlantedEntryError`) and ``tmp`` removed."""
    try:
        st = os.lstat(path)
    except FileNotFoundError:
        st = None
    if st is not None and not (stat.S_ISLNK(st.st_mode) or stat.S_ISREG(st.st_mode)):
        discard(tmp)
        raise PlantedEntryError(f"{path} is in the way: it is not a regular file (remove it and run again)")
    os.replace(tmp, path)


def discard(tmp: Path) -> None:
    try:
        clear_entry(tmp)
    except OSError:
        pass


@contextmanager
def replacing(path: Path, mode: str = "w", newline: str | None = None) -> Iterator[IO[Any]]:
    """A new file written as a whole: opened at :func:`staging` (created exclusively, no link followed),
    flushed and renamed over ``path`` when the block ends (:func:`commit`); removed if the block raises.
    A reader never sees half a file, and a kill leaves the earlier file (or none) at ``path``."""
    tmp = staging(Path(path))
    fh = open_new(tmp, newline, mode)
    try:
        with fh:
            yield fh
            fh.flush()
            os.fsync(fh.fileno())
    except BaseException:
        discard(tmp)
        raise
    commit(tmp, Path(path))


@contextmanager
def replacing_path(path: Path) -> Iterator[Path]:
    """Like :func:`replacing` for libraries that open a file by name (netCDF): yields the staging name,
    created empty and exclusively just before, to be overwritten by the library."""
    tmp = staging(Path(path))
    create_new(tmp)
    try:
        yield tmp
    except BaseException:
        discard(tmp)
        raise
    commit(tmp, Path(path))


def write_text(path: Path, text: str) -> None:
    with replacing(path) as fh:
        fh.write(text)


def write_all(items: list[tuple[Path, Any]]) -> None:
    """Write several files as one set: each ``(path, fill)`` is staged (``fill(binary handle)``), and
    only when every one is complete are they renamed into place, one after another."""
    staged: list[tuple[Path, Path]] = []
    try:
        for path, fill in items:
            tmp = staging(Path(path))
            with open_new(tmp, mode="wb") as fh:
                staged.append((tmp, Path(path)))
                fill(fh)
                fh.flush()
                os.fsync(fh.fileno())
    except BaseException:
        for tmp, _ in staged:
            discard(tmp)
        raise
    for tmp, path in staged:
        commit(tmp, path)


# --- reading a file someone else may have planted --------------------------------------------------


def file_kind(mode: int) -> str:
    """What a file of ``mode`` (``os.stat``) is when it is not a regular file ("a named pipe (FIFO)",
    ...), or "" for a regular file: the one wording of every message that refuses such a file."""
    if stat.S_ISREG(mode):
        return ""
    kinds = (
        (stat.S_ISDIR, "a folder"),
        (stat.S_ISFIFO, "a named pipe (FIFO)"),
        (stat.S_ISCHR, "a character device"),
        (stat.S_ISBLK, "a block device"),
        (stat.S_ISSOCK, "a socket"),
    )
    return next((name for test, name in kinds if test(mode)), "a special file")


def open_regular(path: Path, limit: int | None = None, what: str = "", follow: bool = False) -> IO[bytes]:
    """``path`` opened for reading if it is a regular file itself, of at most ``limit`` bytes.

    Opened without following a link (unless ``follow``: an input file the user named may be a link;
    what it points to is checked) and without blocking (``O_NOFOLLOW | O_NONBLOCK``), then checked
    on the open handle (``fstat``): a FIFO would hang the reader, a link to ``/dev/zero`` would fill
    memory. Raises :class:`PlantedEntryError` naming the file (``what``: how a message calls it)
    and what was expected; never quotes its content. :class:`FileNotFoundError` when it is missing."""
    name = what or str(path)
    flags = (
        os.O_RDONLY
        | (0 if follow else _NOFOLLOW)
        | getattr(os, "O_NONBLOCK", 0)
        | getattr(os, "O_CLOEXEC", 0)
    )
    try:
        fd = os.open(path, flags)
    except FileNotFoundError:
        raise
    except OSError as exc:
        why = "it is a symbolic link" if os.path.islink(path) else (exc.strerror or "it cannot be opened")
        raise PlantedEntryError(f"{name} cannot be read: {why}; expected a regular file") from None
    try:
        st = os.fstat(fd)
        kind = file_kind(st.st_mode)
        if kind:
            raise PlantedEntryError(f"{name} cannot be read: it is {kind}; expected a regular file")
        if limit is not None and st.st_size > limit:
            raise PlantedEntryError(
                f"{name} cannot be read: it has {st.st_size} bytes; expected at most {limit}"
            )
    except BaseException:
        os.close(fd)
        raise
    return os.fdopen(fd, "rb")
