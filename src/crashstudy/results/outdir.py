"""The output folder policy of every command that writes results (``run``, ``simulate``, ``optimize``,
``calibrate``): what a new run may overwrite, and the files it makes stale.

A command writes into a folder only after :func:`prepare_output` (or, before a long search,
:func:`check_output`) has said it may, while it holds the folder's lock
(:func:`crashstudy.safefs.folder_lock`, taken by :func:`crashstudy.run.runner.output_folder`):
another study's results and an unfinished run are kept unless ``--force``/``--resume`` say otherwise.

Whenever new results are written, every file derived from the earlier results goes with them
(:data:`DERIVED`: what ``plot``, ``sensitivity``, ``optimize`` and ``calibrate`` write beside them).
Other files in the folder (the user's own) are left alone.
"""

from __future__ import annotations

import fnmatch
import os
import stat
from pathlib import Path

from crashstudy.errors import InputError, Problem
from crashstudy.results.integrity import MANIFEST, final_name, partial_name
from crashstudy.results.placement import remove_store
from crashstudy.results.store import FINAL, PARQUET, PARTIAL, SUMMARY
from crashstudy.results.zarr_file import ZARR_FINAL, ZARR_PARTIAL
from crashstudy.safefs import PlantedEntryError, clear_entry, open_regular

DERIVED = (
    "sensitivity.csv",
    "sensitivity_*.nc",
    "sensitivity_*.png",
    "optimum.yaml",
    "history.csv",
    "calibrated.yaml",
    "calibration.png",
    "report.html",
    "correlation.csv",
)
"""Files written beside a result from it (name patterns in the result folder); plus ``plots/``."""


def check_output(out_dir: Path, force: bool, source: str, study_name: str) -> None:
    """Refuse ``out_dir`` for a new result of ``study_name`` when it holds another study's results or an
    unfinished run (unless ``force``); nothing is changed. A finished result of the same study is
    replaced. ``optimize``/``calibrate`` call it before their search, :func:`prepare_output` again
    before writing."""
    final = out_dir / final_name(out_dir)
    if os.path.lexists(out_dir) and not out_dir.is_dir():
        raise InputError([Problem(source, None, "", f"the output path {out_dir} is a file, not a folder")])
    if force:
        return
    if os.path.lexists(final):
        other = study_of(final)
        if other != study_name:
            raise InputError(
                [
                    Problem(
                        source,
                        None,
                        "",
                        f"{out_dir} holds the results of {other!r}, not of "
                        f"{study_name!r}; use --force to overwrite or choose another -o",
                    )
                ]
            )
    if os.path.lexists(out_dir / PARTIAL) or os.path.lexists(out_dir / ZARR_PARTIAL):
        raise InputError(
            [
                Problem(
                    source,
                    None,
                    "",
                    f"an unfinished run is in {out_dir}; use --resume to finish it "
                    "(run only) or --force to start again",
                )
            ]
        )


def prepare_output(out_dir: Path, resume: bool, force: bool, source: str, study_name: str) -> None:
    """Refuse to overwrite another study's results or an unfinished run unless ``force``; clear when forced.

    A finished result of the *same* study is not refused: the run reuses its unchanged variants.
    Whenever new results are about to be written, the files derived from the earlier results in the
    folder (:func:`remove_derived`) are removed: they would no longer describe these results.
    """
    final = out_dir / final_name(out_dir)
    partial = out_dir / partial_name(final.name)
    if out_dir.exists() and not out_dir.is_dir():
        raise InputError([Problem(source, None, "", f"the output path {out_dir} is a file, not a folder")])
    if force and out_dir.exists():
        for p in (
            out_dir / FINAL,
            out_dir / PARTIAL,
            out_dir / SUMMARY,
            out_dir / PARQUET,
            out_dir / MANIFEST,
        ):
            clear_entry(p)  # a link is removed, never followed (a dangling one too)
        for p in (out_dir / ZARR_FINAL, out_dir / ZARR_PARTIAL):
            remove_store(p)
        remove_derived(out_dir)
        return
    if not resume:
        check_output(out_dir, force, source, study_name)
    if not (resume and final.exists() and not os.path.lexists(partial)):  # else: nothing will be written
        remove_derived(out_dir)


def remove_derived(out_dir: Path) -> list[Path]:
    """Remove the files derived from the results in ``out_dir`` (:data:`DERIVED`, and the plots that
    ``crashstudy plot`` wrote into ``plots/``); a link among them is removed, never followed. Returns them."""
    gone = []
    try:
        names = sorted(os.listdir(out_dir))
    except OSError:
        names = []
    for name in names:
        if any(fnmatch.fnmatchcase(name, pat) for pat in DERIVED):
            path = out_dir / name
            try:
                mode = os.lstat(path).st_mode
            except FileNotFoundError:
                continue
            if stat.S_ISREG(mode) or stat.S_ISLNK(mode):
                clear_entry(path)
                gone.append(path)
    return gone + remove_stale_plots(out_dir)


def remove_stale_plots(out_dir: Path) -> list[Path]:
    """Remove the PNGs in ``out_dir/plots`` that ``crashstudy plot`` wrote (never other files); return them."""
    folder = out_dir / "plots"
    if not folder.is_dir() or folder.is_symlink():
        return []
    from crashstudy.results.plot_tag import is_crashstudy_plot

    gone = []
    for png in sorted(folder.glob("*.png")):
        if not png.is_symlink() and png.is_file() and is_crashstudy_plot(png):
            png.unlink()
            gone.append(png)
    if gone and not any(folder.iterdir()):
        folder.rmdir()  # it held only those plots
    return gone


def study_of(final: Path) -> str:
    from crashstudy.results.integrity import open_store

    try:
        if final.name == FINAL:
            open_regular(final).close()  # a FIFO there would hang netCDF
        with open_store(final) as nc:
            return str(nc.getncattr("study_name")) if "study_name" in nc.ncattrs() else "an unknown study"
    except (OSError, PlantedEntryError):
        return "an unreadable file"
