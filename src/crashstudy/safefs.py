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
