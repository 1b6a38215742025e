"""The output folder of a run: what a new run may overwrite, and the plots it makes stale.

A run writes into a folder only after :func:`prepare_output` has said it may, while it holds the
folder's lock (:func:`crashstudy.safefs.folder_lock`, taken by :func:`crashstudy.run.runner.run_plan`):
another study's results and an unfinished run are kept unless ``--force``/``--resume`` say otherwise.
"""

from __future__ import annotations

import os
from pathlib import Path

from crashstudy.errors import InputError, Problem
from crashstudy.results.integrity import MANIFEST
from crashstudy.results.store import FINAL, PARQUET, PARTIAL, SUMMARY
from crashstudy.safefs import clear_entry


def prepare_output(out_dir: Path, resume: bool, force: bool, source: str, study_name: str) -> None:
    """Refuse to overwrite another study's results or an unfinished run unless ``force``; clear when forced.

    A finished result of the *same* study is not refused: the run reuses its unchanged variants.
    Whenever new results are about to be written, the plots that ``crashstudy plot`` made of the
    earlier results in the folder (``plots/``) are removed: they would no longer show these results.
    """
    final, partial = out_dir / FINAL, out_dir / PARTIAL
    if out_dir.exists() and not out_dir.is_dir():
        raise InputError([Problem(source, None, "", f"the output path {out_dir} is a file, not a folder")])
    if force and out_dir.exists():
        for p in (final, partial, out_dir / SUMMARY, out_dir / PARQUET, out_dir / MANIFEST):
            clear_entry(p)  # a link is removed, never followed (a dangling one too)
        remove_stale_plots(out_dir)
        return
    if final.exists() and not resume:
        other = study_of(final)
        if other != study_name:
            raise InputError([Problem(source, None, "", f"{out_dir} holds the results of {other!r}, not of "
                                      f"{study_name!r}; use --force to overwrite or choose another -o")])  # fmt: skip
    if os.path.lexists(partial) and not resume:
        raise InputError([Problem(source, None, "", f"an unfinished run is in {out_dir}; use --resume to finish it or --force to start again")])
    if not (resume and final.exists() and not os.path.lexists(partial)):  # else: nothing will be written
        remove_stale_plots(out_dir)


def remove_stale_plots(out_dir: Path) -> list[Path]:
    """Remove the PNGs in ``out_dir/plots`` that ``crashstudy plot`` wrote (never other files); return them."""
    folder = out_dir / "plots"
    if not folder.is_dir() or folder.is_symlink():
        return []
    from crashstudy.analysis.plot import is_crashstudy_plot

    gone = []
    for png in sorted(folder.glob("*.png")):
        if not png.is_symlink() and png.is_file() and is_crashstudy_plot(png):
            png.unlink()
            gone.append(png)
    if gone and not any(folder.iterdir()):
        folder.rmdir()  # it held only those plots
    return gone


def study_of(final: Path) -> str:
    import netCDF4

    try:
        with netCDF4.Dataset(final) as nc:
            return str(nc.getncattr("study_name")) if "study_name" in nc.ncattrs() else "an unknown study"
    except OSError:
        return "an unreadable file"
