"""The folder of compiled kernels, private to the user who runs crashstudy.

numba's on-disk cache is a pickle: whoever can write into the cache folder can make the next run
execute their code. So a kernel cache is used only when it is *private*: a real folder (not a
symbolic link) owned by the current user and not writable by group or others. It is created with
mode 0700. A folder that fails the check is skipped with a :class:`KernelCacheWarning` naming what
is wrong, and the next candidate is tried:

1. ``$CRASHSTUDY_KERNEL_CACHE`` when set,
2. ``~/.cache/crashstudy/kernels``,
3. a fresh private folder made by :func:`tempfile.mkdtemp` (an unpredictable name, mode 0700, used
   by this process only: kernels compiled there are not reused by the next run).

There is never a fixed shared path such as ``/tmp/crashstudy-kernels``.
"""

from __future__ import annotations

import functools
import os
import stat
import tempfile
import warnings
from pathlib import Path
from typing import Any

from crashstudy.errors import CrashstudyWarning


class KernelCacheWarning(CrashstudyWarning):
    """A kernel cache folder was skipped because it is not private to this user."""


def cache_dir() -> Path:
    """The private folder for generated kernel sources and numba's compiled cache beside them."""
    return _cache_dir(os.environ.get("CRASHSTUDY_KERNEL_CACHE") or None, str(Path.home()))


def checked_dir() -> Path:
    """:func:`cache_dir`, checked again just before use (it may have been removed or replaced since)."""
    folder = cache_dir()
    why = _make_private(folder)
    if why is None:
        return folder
    warnings.warn(f"kernel cache {folder} not used any more: {why}", KernelCacheWarning, stacklevel=2)
    return Path(tempfile.mkdtemp(prefix="crashstudy-kernels-"))


def why_not_private(folder: Path) -> str | None:
    """Why ``folder`` must not hold compiled code (None when it is a private folder of this user)."""
    try:
        st = os.lstat(folder)
    except OSError as exc:
        return f"cannot inspect it ({exc.strerror})"
    if stat.S_ISLNK(st.st_mode):
        return "it is a symbolic link"
    if not stat.S_ISDIR(st.st_mode):
        return "it is not a folder"
    if hasattr(os, "geteuid") and st.st_uid != os.geteuid():
        return f"it belongs to user id {st.st_uid}, not to this user ({os.geteuid()})"
    if st.st_mode & (stat.S_IWGRP | stat.S_IWOTH):
        return f"group or others may write into it (mode {stat.S_IMODE(st.st_mode):04o})"
    return None


def _make_private(folder: Path) -> str | None:
    """Create ``folder`` (mode 0700) if missing, tighten an own folder to 0700; why it is unusable, or None."""
    try:
        folder.parent.mkdir(parents=True, exist_ok=True)
        try:
            folder.mkdir(mode=0o700)
        except FileExistsError:
            pass
    except OSError as exc:
        return f"cannot create it ({exc.strerror})"
    why = why_not_private(folder)
    if why is not None:
        return why
    try:
        os.chmod(folder, 0o700, follow_symlinks=False)  # ours and not writable by others: drop read bits too
    except (OSError, NotImplementedError):
        pass
    if not os.access(folder, os.W_OK | os.X_OK):
        return "it is not writable"
    return None


@functools.lru_cache(maxsize=8)
def _cache_dir(env: str | None, home: str) -> Path:
    """:func:`cache_dir`, decided once per setting (it is asked for every chunk)."""
    candidates = ([Path(env)] if env else []) + [Path(home) / ".cache" / "crashstudy" / "kernels"]
    for cand in candidates:
        why = _make_private(cand)
        if why is None:
            return cand
        warnings.warn(f"kernel cache {cand} not used: {why}; compiled kernels must be in a folder only you can "
                      "write to", KernelCacheWarning, stacklevel=3)  # fmt: skip
    return Path(tempfile.mkdtemp(prefix="crashstudy-kernels-"))


def compiled_or_cached(run: Any) -> bool:
    """Whether numba dispatcher ``run`` is compiled in this process or has an index in numba's disk cache
    (the index is written after the compiled code)."""
    sigs = getattr(run, "signatures", None)
    if sigs is None:  # not a numba dispatcher (a test double): nothing to compile
        return True
    if sigs:
        return True
    try:
        return os.path.exists(run._cache._cache_file._index_path)
    except AttributeError:  # numba internals moved: assume it must be compiled
        return False
