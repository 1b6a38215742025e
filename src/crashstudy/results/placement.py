"""Where a result store lives on disk: a finished store put in place over an older one (:func:`swap_store`,
atomic where the OS can swap two names), a store removed (:func:`remove_store`, links never followed), and
whether a partial store still opens (:func:`partial_opens`, before a resume)."""

from __future__ import annotations

import os
from pathlib import Path

from crashstudy.results import integrity
from crashstudy.results.zarr_file import exchange
from crashstudy.safefs import clear_entry


def swap_store(new: Path, final: Path) -> None:
    """Put the finished Zarr store ``new`` at ``final``, replacing an older one there: ``new`` is renamed
    to ``final.replacing``, swapped with the old store in one step (:func:`exchange`) and the old store
    removed after, so a kill at any moment leaves a whole store at ``final`` (the old, until the swap).
    Where no swap exists (not Linux, some network file systems) the old store is moved aside first."""
    staged = final.with_name(final.name + ".replacing")
    aside = final.with_name(final.name + ".replaced")
    remove_store(staged)  # left by a run killed here
    remove_store(aside)
    if os.path.lexists(final):
        os.replace(new, staged)
        if exchange(staged, final):
            remove_store(staged)  # now the old store
            return
        os.replace(final, aside)
        new = staged
    os.replace(new, final)
    remove_store(aside)


def remove_store(path: Path) -> None:
    """Remove a result store at ``path``: a link or file is unlinked (never followed), a folder removed."""
    if os.path.isdir(path) and not os.path.islink(path):
        import shutil

        shutil.rmtree(path)
    else:
        clear_entry(path)


def partial_opens(path: Path) -> bool:
    """Whether a partial result store opens and carries its fingerprint and done flags."""
    try:
        with integrity.open_store(path, "r") as nc:
            nc.getncattr("plan_fingerprint")
            nc.variables["done"][:]
        return True
    except (OSError, RuntimeError, AttributeError, KeyError, IndexError):
        return False
