"""The folder of compiled kernels, private to the user who runs crashstudy.

numba's on-disk cache is a pickle: whoever can write into the cache folder can make the next run
execute their code. So a kernel cache is used only when it is *private*: a real folder (not a
symbolic link) owned by the current user and not writable by group or others. It is created with
mode 0700. A folder that fails the check is skipped with a :class:`KernelCacheWarning` naming what
is wrong, and the next candidate is tried:

1. ``$CRASHSTUDY_KERNEL_CACHE`` when set,
2. ``~/.cache/crashstudy/kernels``,
3. ``crashstudy-kernels-<uid>`` in the temp folder, the same private folder for every run of this user
   (so a run with an unusable HOME neither recompiles nor leaves a folder behind); when another user
   made that name first (or it fails the check), a fresh :func:`tempfile.mkdtemp` folder removed when
   the process exits.

There is never a fixed shared path such as ``/tmp/crashstudy-kernels``. A folder is private when it
and every folder above it pass :func:`why_not_private` (above it: owned by this user or root, and not
writable by group or others unless sticky, as ``/tmp`` is).

numba's own cache folder, ``NUMBA_CACHE_DIR``, holds the same pickles and numba loads them when a
compiled function is first called: :func:`secure_numba_cache` (run when crashstudy is imported,
before numba reads its configuration) applies the same rule to it and, when it fails, moves numba's
cache to ``numba`` inside the kernel folder with a one-line warning.
"""

from __future__ import annotations

import atexit
import functools
import hashlib
import os
import shutil
import stat
import sys
import tempfile
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

from crashstudy.errors import CrashstudyWarning


class KernelCacheWarning(CrashstudyWarning):
    """A kernel cache folder was skipped because it is not private to this user."""


_PENDING: list[str] = []  # warnings found before the command line could print them on one line


def cache_dir() -> Path:
    """The private folder for generated kernel sources and numba's compiled cache beside them."""
    warn_pending()
    return _cache_dir(os.environ.get("CRASHSTUDY_KERNEL_CACHE") or None, _home())


def _home() -> str:
    try:
        return str(Path.home())
    except (RuntimeError, KeyError):  # no HOME and no password entry
        return ""


def secure_numba_cache() -> None:
    """Move numba's cache (``NUMBA_CACHE_DIR``) into the kernel folder when it is not private: numba
    unpickles the index files it finds there, so whoever can write into it runs code as this user.
    Called when crashstudy is imported, before numba reads its configuration (and also sets numba's
    configuration when numba was imported first). The warning waits for :func:`warn_pending`."""
    given = os.environ.get("NUMBA_CACHE_DIR", "")
    if not given:
        return
    folder = Path(given)
    try:
        folder.mkdir(
            mode=0o700, parents=True, exist_ok=True
        )  # numba would create it; not chmod-ed when it exists
    except OSError:
        pass
    why = why_not_private(folder)
    if why is None:
        return
    safe = cache_dir() / "numba"
    if _make_private(safe) is not None:
        safe = _fallback() / "numba"
        safe.mkdir(mode=0o700, exist_ok=True)
    os.environ["NUMBA_CACHE_DIR"] = str(safe)
    config = sys.modules.get("numba.core.config")
    if config is not None:
        setattr(config, "CACHE_DIR", str(safe))  # noqa: B010 (numba read it at import)
    _PENDING.append(
        f"numba cache {given} (NUMBA_CACHE_DIR) not used: {why}; numba's compiled code goes to {safe}"
    )


def warn_pending() -> None:
    """Issue the warnings :func:`secure_numba_cache` found (once each)."""
    while _PENDING:
        warnings.warn(_PENDING.pop(0), KernelCacheWarning, stacklevel=3)


def checked_dir() -> Path:
    """:func:`cache_dir`, checked again just before use (it may have been removed or replaced since)."""
    folder = cache_dir()
    why = _make_private(folder)
    if why is None:
        return folder
    warnings.warn(f"kernel cache {folder} not used any more: {why}", KernelCacheWarning, stacklevel=2)
    return _fallback()


def why_not_private(folder: Path) -> str | None:
    """Why ``folder`` must not hold compiled code (None when it is a private folder of this user, in
    folders that no other user can rename it out of)."""
    return _why_not_own(folder) or _why_not_safe_above(Path(os.path.abspath(folder)).parent)


def _why_not_safe_above(parent: Path) -> str | None:
    """Why a folder inside ``parent`` could be swapped by another user: a folder above it owned by
    another user than this one or root, or writable by group or others without the sticky bit."""
    me = os.geteuid() if hasattr(os, "geteuid") else None
    for above in (parent, *parent.parents):
        try:
            st = os.stat(above)
        except OSError as exc:
            return f"cannot inspect {above} ({exc.strerror})"
        if me is not None and st.st_uid not in (0, me):
            return f"the folder {above} above it belongs to user id {st.st_uid}"
        if st.st_mode & (stat.S_IWGRP | stat.S_IWOTH) and not st.st_mode & stat.S_ISVTX:
            return f"group or others may write into the folder {above} above it (mode {stat.S_IMODE(st.st_mode):04o})"
    return None


def _why_not_own(folder: Path) -> str | None:
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
    candidates = ([Path(env)] if env else []) + (
        [Path(home) / ".cache" / "crashstudy" / "kernels"] if home else []
    )
    for cand in candidates:
        why = _make_private(cand)
        if why is None:
            return cand
        warnings.warn(
            f"kernel cache {cand} not used: {why}; compiled kernels must be in a folder only you can "
            "write to",
            KernelCacheWarning,
            stacklevel=3,
        )
    return _fallback()


@functools.lru_cache(maxsize=1)
def _fallback() -> Path:
    """This user's private folder in the temp folder, the same for every run (``crashstudy-kernels-<uid>``);
    when that name is taken by someone else, a fresh folder removed at exit (never left behind)."""
    uid = os.geteuid() if hasattr(os, "geteuid") else os.getpid()
    mine = Path(tempfile.gettempdir()) / f"crashstudy-kernels-{uid}"
    why = _make_private(mine)
    if why is None:
        return mine
    warnings.warn(
        f"kernel cache {mine} not used: {why}; this run compiles into a folder removed when it ends",
        KernelCacheWarning,
        stacklevel=4,
    )
    fresh = Path(tempfile.mkdtemp(prefix="crashstudy-kernels-"))
    atexit.register(shutil.rmtree, fresh, True)
    return fresh


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


#: the stamp, in a numba cache folder, of the crashstudy sources its compiled code was built from
STAMP_NAME = "crashstudy-sources.sha256"
#: the packages whose compiled functions numba caches, calling each other across files (kernel, metrics), and
#: the package whose constants they freeze into their machine code (vocabulary)
COMPILED_SOURCES = ("kernel", "metrics", "vocabulary")
_CHECKED: set[str] = set()


def cached_njit(**options: Any) -> Callable[[Any], Any]:
    """``numba.njit(cache=True, **options)`` for crashstudy's compiled functions: each function's numba cache
    folder is checked by :func:`fresh_numba_cache` when the function is defined (at import, before any call)."""
    import numba as nb

    jit = nb.njit(cache=True, **options)
    return lambda func: fresh_numba_cache(jit(func))


def fresh_numba_cache(dispatcher: Any) -> Any:
    """Remove a numba cache folder's compiled code built from other crashstudy sources than these.

    numba keys a cached function on its own file's time stamp and its own bytecode: not on the compiled
    functions it calls in other files, nor on the constants it imports. After an edit of ``laws.py`` alone
    (a ``git pull``, a branch switch, an editable install), numba would load a generic kernel
    (``compiled.py``, unchanged) that still runs the old law. So, once per process and folder, the folder's
    stamp (:data:`STAMP_NAME`: a hash of every source file of :data:`COMPILED_SOURCES`) is compared with
    these sources; when it differs, the folder's numba files (indexes ``.nbi``, data ``.nbc``) are removed,
    numba compiles again and writes new ones, and the stamp is rewritten. Returns ``dispatcher``."""
    try:
        folder = Path(dispatcher._cache._cache_path)
    except AttributeError:  # not cached, or numba internals moved: nothing to check
        return dispatcher
    if str(folder) in _CHECKED:
        return dispatcher
    _CHECKED.add(str(folder))
    now = sources_hash()
    stamp = folder / STAMP_NAME
    try:
        if stamp.read_text() == now:
            return dispatcher
    except OSError:
        pass
    for old in [*folder.glob("*.nbi"), *folder.glob("*.nbc")]:
        try:
            old.unlink()
        except OSError:  # removed by another process at the same time
            pass
    from crashstudy.safefs import write_text

    try:
        write_text(stamp, now)
    except OSError:  # a read-only folder: numba does not write there either
        pass
    return dispatcher


@functools.lru_cache(maxsize=1)
def sources_hash() -> str:
    """sha256 of the names and contents of the source files of :data:`COMPILED_SOURCES`."""
    root = Path(__file__).resolve().parent.parent
    h = hashlib.sha256()
    for package in COMPILED_SOURCES:
        for src in sorted((root / package).glob("*.py")):
            h.update(f"{package}/{src.name}\0".encode())
            h.update(src.read_bytes())
    return h.hexdigest()
