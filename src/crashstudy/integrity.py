"""Whether a result folder holds one finished run's results: completion mark, chunk checksums, manifest.

A run ends with several renames (``results.nc.partial`` -> ``results.nc``, then the summary tables),
and a process can be killed between any two of them; a file can also be renamed or damaged by hand.
Three records make each case visible:

- **Completion mark**: ``results.nc`` carries the global attributes ``complete = 1`` and ``run_id``
  (a random hex id), set just before its rename. A ``results.nc.partial`` renamed by hand has no mark
  and is refused when opened and never reused.
- **Chunk checksums**: every chunk written (computed, or copied from an earlier result) appends a
  record ``chunk_lo``, ``chunk_hi``, ``chunk_crc`` (CRC-32 of the chunk's stored status, input hashes,
  summary metrics and histories, in the order of :func:`checked_names`). ``--resume`` recomputes a
  chunk whose data no longer matches its checksum, and a re-run reuses only variants of such chunks.
  The text indices (``failure_reason``, ``dt_control``) are left out: they are renumbered at the end.
- **Manifest**: ``manifest.json`` (the run id, and each final file's size and, for the summaries,
  SHA-256) is written last, after every rename. ``results.nc`` is renamed first, so a kill after
  it leaves a ``results.nc`` whose ``run_id`` no earlier manifest names (or no manifest at all), and a
  kill before it leaves the earlier set whole. :func:`folder_problem` checks this on every open.

Files written before these records existed (no ``chunk_crc`` variable, no ``run_id``) are accepted
when every variant is marked done, as before.
"""

from __future__ import annotations

import hashlib
import json
import os
import zlib
from collections.abc import Iterable
from pathlib import Path

import netCDF4
import numpy as np

from crashstudy.safefs import open_new

MANIFEST = "manifest.json"
INCONSISTENT = "the result folder is inconsistent: re-run with --force"
UNFINISHED = ("results.nc is not a finished result (it has no completion mark: an unfinished run's "
              "results.nc.partial renamed by hand?): finish that run with --resume, or re-run with --force")  # fmt: skip
CHUNK_VARS = ("chunk_lo", "chunk_hi", "chunk_crc")
NOT_CHECKED = ("failure_reason", "dt_control")  # renumbered when the text tables are sorted at the end


def crc(arrays: Iterable[np.ndarray]) -> int:
    """CRC-32 of the bytes of ``arrays`` (each made C-contiguous), in order."""
    value = 0
    for a in arrays:
        value = zlib.crc32(np.ascontiguousarray(a).view(np.uint8).reshape(-1).data, value)
    return value


def checked_names(nc: netCDF4.Dataset) -> list[str]:
    """Per-variant variables covered by a chunk's checksum, in checksum order (not the study axes,
    written when the file is created)."""
    axes = json.loads(nc.getncattr("crashstudy_axes")) if "crashstudy_axes" in nc.ncattrs() else []
    skip = set(axes) | set(NOT_CHECKED) | {"variant", "done"}
    return sorted(n for n, v in nc.variables.items()
                  if v.dimensions[:1] == ("variant",) and n not in skip and not n.endswith("_text"))  # fmt: skip


def stored(nc: netCDF4.Dataset, name: str, lo: int, hi: int) -> np.ndarray:
    """The raw stored values of ``name`` for variants ``lo`` .. ``hi - 1`` (no masking of fill values)."""
    v = nc.variables[name]
    v.set_auto_mask(False)
    try:
        return np.asarray(v[lo:hi], dtype=v.dtype)
    finally:
        v.set_auto_mask(True)


def file_crc(nc: netCDF4.Dataset, names: list[str], lo: int, hi: int) -> int:
    """CRC-32 of the stored data of variants ``lo`` .. ``hi - 1`` (see :func:`crc`)."""
    return crc(stored(nc, n, lo, hi) for n in names)


def add_chunk_vars(nc: netCDF4.Dataset) -> None:
    """Create the chunk record variables (an unlimited ``chunk`` dimension)."""
    nc.createDimension("chunk", None)
    for name, long in (("chunk_lo", "first variant of a written chunk"),
                       ("chunk_hi", "one past the last variant of a written chunk"),
                       ("chunk_crc", "CRC-32 of the chunk's stored data (crashstudy.integrity)")):  # fmt: skip
        v = nc.createVariable(name, "i8", ("chunk",))
        v.units, v.long_name = "1", long


def record_chunk(nc: netCDF4.Dataset, lo: int, hi: int, value: int) -> None:
    """Append the record of a chunk written at variants ``lo`` .. ``hi - 1``."""
    k = len(nc.dimensions["chunk"])
    nc.variables["chunk_lo"][k] = lo
    nc.variables["chunk_hi"][k] = hi
    nc.variables["chunk_crc"][k] = value


def verified(nc: netCDF4.Dataset, blank_bad: bool = False) -> tuple[np.ndarray, list[tuple[int, int]]]:
    """Variants whose chunk checksum matches the data (boolean (V,)) and the ranges that do not.

    A file without chunk records (written before they existed) counts every done variant as
    verified. ``blank_bad``: also empty the records of the bad chunks (``--resume`` computes them
    again and records them anew)."""
    n = len(nc.dimensions["variant"])
    done = np.ma.filled(nc.variables["done"][:], 0).astype(bool) if "done" in nc.variables else np.ones(n, bool)
    if "chunk_crc" not in nc.variables:
        return done, []
    ok = np.zeros(n, dtype=bool)
    bad: list[tuple[int, int]] = []
    names = checked_names(nc)
    lo_v, hi_v, crc_v = (np.asarray(np.ma.filled(nc.variables[k][:], 0), dtype=np.int64) for k in CHUNK_VARS)
    for k, (lo, hi, want) in enumerate(zip(lo_v, hi_v, crc_v, strict=True)):
        if not 0 <= lo < hi <= n:
            continue
        if file_crc(nc, names, int(lo), int(hi)) == want:
            ok[lo:hi] = True
        else:
            ok[lo:hi] = False
            bad.append((int(lo), int(hi)))
            if blank_bad:
                nc.variables["chunk_lo"][k] = 0
                nc.variables["chunk_hi"][k] = 0
    return ok & done, bad


def finished_problem(nc: netCDF4.Dataset) -> str:
    """Why an open ``results.nc`` is not a finished result ("" if it is)."""
    attrs = nc.ncattrs()
    if "complete" in attrs:
        return "" if int(nc.getncattr("complete")) == 1 else UNFINISHED
    if "chunk_crc" in nc.variables or "run_id" in attrs:  # written with completion marks, yet none set
        return UNFINISHED
    if "done" in nc.variables and not np.ma.filled(nc.variables["done"][:], 0).all():  # an older file
        return UNFINISHED
    return ""


def sha256(path: Path, block: int = 2**20) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        while chunk := fh.read(block):
            h.update(chunk)
    return h.hexdigest()


def write_manifest(folder: Path, run_id: str, files: dict[str, Path]) -> None:
    """Write ``manifest.json`` (through a temporary file and a rename): the run id and, for each final
    name in ``files`` (mapped to the file now holding it), its size and (summaries) SHA-256."""
    entries: dict[str, dict[str, object]] = {}
    for name, path in files.items():
        entry: dict[str, object] = {"size": os.stat(path).st_size}
        if not name.endswith(".nc"):
            entry["sha256"] = sha256(path)
        entries[name] = entry
    tmp = folder / (MANIFEST + ".partial")
    with open_new(tmp) as fh:
        json.dump({"crashstudy_manifest": 1, "run_id": run_id, "files": entries}, fh, indent=1)
        fh.write("\n")
        fh.flush()
        os.fsync(fh.fileno())
    os.replace(tmp, folder / MANIFEST)


def folder_problem(folder: Path, final: str, summaries: tuple[str, ...]) -> str:
    """Why ``folder`` does not hold one finished run's results ("" if it does): see the module docstring."""
    try:
        with netCDF4.Dataset(folder / final) as nc:
            problem = finished_problem(nc)
            run_id = str(nc.getncattr("run_id")) if "run_id" in nc.ncattrs() else None
    except OSError as exc:
        return f"{final} cannot be read ({exc})"
    if problem:
        return problem
    path = folder / MANIFEST
    if not os.path.lexists(path):
        if run_id is None:
            return ""  # written before manifests existed
        return f"{INCONSISTENT} ({final} is from run {run_id}, and there is no {MANIFEST}: the run that wrote it " \
               "stopped before its last rename)"
    try:
        with open(path, encoding="utf-8") as fh:
            manifest = json.load(fh)
        listed = manifest["files"]
        their_id = str(manifest["run_id"])
    except (OSError, ValueError, KeyError, TypeError) as exc:
        return f"{INCONSISTENT} ({MANIFEST} cannot be read: {exc})"
    if their_id != run_id:
        return f"{INCONSISTENT} ({final} is from run {run_id}, {MANIFEST} from run {their_id})"
    stale = [n for n in summaries if n not in listed and os.path.lexists(folder / n)]
    if stale:
        return f"{INCONSISTENT} ({', '.join(stale)} not written by the run that wrote {final})"
    return ""
