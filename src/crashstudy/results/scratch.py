"""Scratch folders of the readers that spill to disk (``compare``'s hash parts, the correlation's rank
buckets: GBs at 10^8 variants): ``TMPDIR/crashstudy-scratch-<pid>-<host>-<what>-<random>``. A folder is
removed when its reader ends, and, when the process was killed (SIGKILL, out of memory) before it could
remove it, by the next reader that makes one: every scratch folder of this user and this host (``<host>``:
a short hash of the host name, so that a TMPDIR shared between machines or containers never loses a
running reader's folder) whose process no longer runs is removed then (:func:`sweep`)."""

from __future__ import annotations

import hashlib
import os
import shutil
import socket
import stat
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

PREFIX = "crashstudy-scratch-"


def _host() -> str:
    return hashlib.sha256(socket.gethostname().encode()).hexdigest()[:8]


@contextmanager
def scratch_folder(what: str) -> Iterator[Path]:
    """A fresh folder ``TMPDIR/crashstudy-scratch-<pid>-<host>-<what>-...`` removed on leaving (also on an
    exception); the folders that killed readers left behind are removed first."""
    sweep()
    tmp = Path(tempfile.mkdtemp(prefix=f"{PREFIX}{os.getpid()}-{_host()}-{what}-"))
    try:
        yield tmp
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def sweep(root: str | os.PathLike[str] | None = None) -> list[Path]:
    """Remove the scratch folders in ``root`` (default ``TMPDIR``) whose process is no longer running and
    that this user owns (a link or a file of that name is left alone); return the folders removed."""
    root = Path(root if root is not None else tempfile.gettempdir())
    removed: list[Path] = []
    try:
        entries = list(os.scandir(root))
    except OSError:
        return removed
    uid = os.getuid() if hasattr(os, "getuid") else None
    for entry in entries:
        pid = owner_pid(entry.name)
        if pid is None or pid == os.getpid() or _running(pid):
            continue
        try:
            st = entry.stat(follow_symlinks=False)
        except OSError:
            continue
        if not stat.S_ISDIR(st.st_mode) or (uid is not None and st.st_uid != uid):
            continue
        shutil.rmtree(entry.path, ignore_errors=True)
        if not os.path.lexists(entry.path):
            removed.append(Path(entry.path))
    return removed


def owner_pid(name: str) -> int | None:
    """The process id in the name of a scratch folder of this host (None: not one)."""
    if not name.startswith(PREFIX):
        return None
    head, _, rest = name[len(PREFIX) :].partition("-")
    return int(head) if head.isdigit() and rest.startswith(_host() + "-") else None


def _running(pid: int) -> bool:
    """Whether process ``pid`` exists (another user's process counts as running)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:  # PermissionError: it runs, as another user
        return True
    return True
