"""Whether a result folder holds one finished run's results: completion mark, checksums, manifest.

A run ends with several renames (``results.nc.partial`` -> ``results.nc``, then the summary tables),
and a process can be killed between any two of them; a file can also be renamed or damaged by hand.
Three records make each case visible:

- **Completion mark**: ``results.nc`` carries the global attributes ``complete = 1`` and ``run_id``,
  set just before its rename. A ``results.nc.partial`` renamed by hand has no mark and is refused when
  opened and never reused.
- **Checksums**: each variant's stored status, input hash, summary metrics and histories are summed
  into a 64-bit ``checksum`` (:func:`variant_sums`), written with the chunk that computed (or
  copied) the variant. ``--resume`` computes again every variant whose data no longer match, and a
  re-run does not reuse such a variant. One number per variant rather than per chunk: the file does
  not depend on how the variants were cut into chunks or in which order the chunks finished
  (``--jobs 2`` and a resumed run give the same file as one plain run). The text indices
  (``failure_reason``, ``dt_control``) are left out: they are renumbered at the end.
- **Manifest**: ``manifest.json`` (the run id, and each final file's size and, for the summaries,
  SHA-256) is written last, after every rename. ``results.nc`` is renamed first, so a kill after
  it leaves a ``results.nc`` whose ``run_id`` the folder's manifest does not name (or no manifest at
  all), and a kill before it leaves the earlier set whole. :func:`folder_problem` checks this on
  every open. The run id is a hash of the results (:func:`run_id`): two runs share it only if their
  files hold the same results, so mixing their files would be harmless.

Files written before these records existed (no ``checksum`` variable, no ``run_id``) are accepted
when every variant is marked done, as before.
"""

from __future__ import annotations

import hashlib
import json
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import netCDF4
import numpy as np

from crashstudy.results.zarr_file import ZARR_FINAL, ZARR_PARTIAL, ZarrFile, store_size
from crashstudy.safefs import PlantedEntryError, open_regular, replacing

MANIFEST = "manifest.json"
FINAL, PARTIAL = "results.nc", "results.nc.partial"
MANIFEST_MAX = 16 * 2**20  # bytes: a manifest names a handful of files
INCONSISTENT = "the result folder is inconsistent: re-run with --force"
UNFINISHED = (
    "results.nc is not a finished result (it has no completion mark: an unfinished run's "
    "results.nc.partial renamed by hand?): finish that run with --resume, or re-run with --force"
)
CHECKSUM = "checksum"
NOT_CHECKED = ("failure_reason", "dt_control", "criteria_note")  # renumbered when the text tables are sorted
_ODD = np.uint64(0x9E3779B97F4A7C15)  # odd: every weight below is odd, so a change of any one word shows
BLOCK_BYTES = 64 * 2**20  # stored bytes read at once when checking a file
CHECK_BLOCK = 1_000_000  # variants read at once by the whole-file passes (checksums, run id, tables)


def checked_names(nc: netCDF4.Dataset) -> list[str]:
    """Per-variant variables covered by the checksum, in checksum order (not the study axes, written
    when the file is created, nor the checksum itself)."""
    axes = json.loads(nc.getncattr("crashstudy_axes")) if "crashstudy_axes" in nc.ncattrs() else []
    skip = set(axes) | set(NOT_CHECKED) | {"variant", "done", CHECKSUM}
    return sorted(
        n
        for n, v in nc.variables.items()
        if v.dimensions[:1] == ("variant",) and n not in skip and not n.endswith("_text")
    )


NARROW = 8  # words per variant up to which variant_sums adds column by column


def variant_sums(arrays: Mapping[str, np.ndarray], names: list[str]) -> np.ndarray:
    """Checksum (uint64, one per variant) of ``arrays[name]`` (each (V, ...) as stored), in ``names`` order.

    Each variant's bytes, zero-padded to 8-byte words per array, are summed with distinct odd weights
    (modulo 2^64): any single changed word changes the sum; vectorised, it costs a multiply-add per word."""
    total: np.ndarray | None = None
    offset = 0
    for name in names:
        a = np.ascontiguousarray(arrays[name])
        n = a.shape[0]
        raw = a.reshape(n, -1).view(np.uint8).reshape(n, -1)
        pad = -raw.shape[1] % 8
        if pad:
            raw = np.concatenate([raw, np.zeros((n, pad), dtype=np.uint8)], axis=1)
        words = raw.view("<u8")
        weights = (
            np.arange(offset, offset + words.shape[1], dtype=np.uint64) * np.uint64(2) + np.uint64(1)
        ) * _ODD
        with np.errstate(over="ignore"):  # the same sum two ways: numpy's row sums of few columns are slow
            if words.shape[1] <= NARROW:
                part = np.zeros(n, dtype=np.uint64)
                for j in range(words.shape[1]):
                    part += words[:, j] * weights[j]
            else:
                part = np.einsum("ij,j->i", words, weights)
            total = part if total is None else total + part
        offset += words.shape[1]
    assert total is not None
    return total


def stored(nc: netCDF4.Dataset, name: str, lo: int, hi: int) -> np.ndarray:
    """The raw stored values of ``name`` for variants ``lo`` .. ``hi - 1`` (no masking of fill values)."""
    v = nc.variables[name]
    v.set_auto_mask(False)
    try:
        return np.asarray(v[lo:hi], dtype=v.dtype)
    finally:
        v.set_auto_mask(True)


def _block(nc: netCDF4.Dataset, names: list[str]) -> int:
    per = sum(
        int(np.prod([len(nc.dimensions[d]) for d in nc.variables[n].dimensions[1:]], dtype=np.int64))
        * nc.variables[n].dtype.itemsize
        for n in names
    )
    return max(1, BLOCK_BYTES // max(per, 1))


def file_sums(nc: netCDF4.Dataset, lo: int, hi: int) -> np.ndarray:
    """Checksums of variants ``lo`` .. ``hi - 1`` computed from the data stored in ``nc``."""
    names = checked_names(nc)
    parts = []
    step = _block(nc, names)
    for a in range(lo, hi, step):
        b = min(hi, a + step)
        parts.append(variant_sums({n: stored(nc, n, a, b) for n in names}, names))
    return np.concatenate(parts) if parts else np.zeros(0, dtype=np.uint64)


def intact(nc: netCDF4.Dataset, among: np.ndarray) -> np.ndarray:
    """Which variants of the boolean mask ``among`` have data that match their stored checksum
    (boolean (V,)). A file without checksums (written before they existed) trusts every variant."""
    ok = np.zeros(len(among), dtype=bool)
    if CHECKSUM not in nc.variables:
        return among.copy()
    # run by run, in blocks: no whole-study array besides the masks (bounded memory at 10^8 variants)
    edges = np.flatnonzero(np.diff(np.concatenate([[0], among.astype(np.int8), [0]])))
    for lo, hi in zip(edges[::2].tolist(), edges[1::2].tolist(), strict=True):
        for a in range(lo, hi, CHECK_BLOCK):
            b = min(hi, a + CHECK_BLOCK)
            ok[a:b] = file_sums(nc, a, b) == stored(nc, CHECKSUM, a, b)
    return ok


def run_id(nc: netCDF4.Dataset) -> str:
    """A hash of everything the result files show: the plan's fingerprint, every checksum, the text
    indices and tables (read from an open, finished partial file)."""
    h = hashlib.sha256(str(nc.getncattr("plan_fingerprint")).encode())
    n = len(nc.dimensions["variant"])
    for name in (CHECKSUM, *NOT_CHECKED, *(f"{t}_text" for t in NOT_CHECKED), "status"):
        if name not in nc.variables:  # criteria_note: only with metrics
            continue
        v = nc.variables[name]
        for lo in range(0, max(len(nc.dimensions[v.dimensions[0]]), 1), CHECK_BLOCK):
            h.update(
                stored(nc, name, lo, min(lo + CHECK_BLOCK, len(nc.dimensions[v.dimensions[0]]))).tobytes()
            )
    h.update(str(n).encode())
    return h.hexdigest()[:32]


def finished_problem(nc: netCDF4.Dataset) -> str:
    """Why an open ``results.nc`` is not a finished result ("" if it is)."""
    attrs = nc.ncattrs()
    if "complete" in attrs:
        return "" if int(nc.getncattr("complete")) == 1 else UNFINISHED
    if CHECKSUM in nc.variables or "run_id" in attrs:  # written with completion marks, yet none set
        return UNFINISHED
    if "done" in nc.variables and not np.ma.filled(nc.variables["done"][:], 0).all():  # an older file
        return UNFINISHED
    return ""


def final_name(folder: Path) -> str:
    """The name of the finished result store in ``folder``: ``results.zarr`` when there is one, else
    ``results.nc`` (a run removes the other store's final when it finishes)."""
    return ZARR_FINAL if os.path.lexists(folder / ZARR_FINAL) else FINAL


def partial_name(final: str) -> str:
    return ZARR_PARTIAL if final == ZARR_FINAL else PARTIAL


def open_store(path: Path, mode: str = "r") -> Any:
    """``results.nc[.partial]`` as a ``netCDF4.Dataset``, ``results.zarr[.partial]`` as a
    :class:`~crashstudy.results.zarr_file.ZarrFile` (the same API)."""
    if path.name.startswith(ZARR_FINAL):
        return ZarrFile(path, mode)
    return netCDF4.Dataset(path, mode)  # type: ignore[arg-type]


def store_bytes(path: Path) -> int:
    """Size of a result store for the manifest: a file's size, a Zarr folder's total."""
    return store_size(path) if path.name.startswith(ZARR_FINAL) else os.stat(path).st_size


def sha256(path: Path, block: int = 2**16) -> str:
    with open_regular(path) as fh:
        return sha256_of(fh, block)


def sha256_of(fh: Any, block: int = 2**16) -> str:
    """SHA-256 of an open binary file from its start (left at its end), read into one buffer of ``block``
    bytes (a fresh 1 MiB bytes object per read showed as ~50 B per variant of memory growth up to 1 MiB)."""
    h = hashlib.sha256()
    fh.seek(0)
    buf = bytearray(block)
    view = memoryview(buf)
    while n := fh.readinto(buf):
        h.update(view[:n])
    return h.hexdigest()


def write_manifest(
    folder: Path, run_id: str, names: list[str], digests: dict[str, str] | None = None
) -> None:
    """Write ``manifest.json`` (through a temporary file and a rename): the run id and, for each file
    ``names`` in ``folder``, its size and (summaries) SHA-256: from ``digests`` where the writer hashed the
    bytes as it wrote them, else read from the file."""
    entries: dict[str, dict[str, object]] = {}
    for name in names:
        entry: dict[str, object] = {"size": store_bytes(folder / name)}
        if not name.startswith(("results.nc", ZARR_FINAL)):
            entry["sha256"] = (digests or {}).get(name) or sha256(folder / name)
        entries[name] = entry
    with replacing(folder / MANIFEST) as fh:
        json.dump({"crashstudy_manifest": 1, "run_id": run_id, "files": entries}, fh, indent=1)
        fh.write("\n")


def folder_problem(folder: Path, final: str, summaries: tuple[str, ...]) -> str:
    """Why ``folder`` does not hold one finished run's results ("" if it does): see the module docstring."""
    return check_folder(folder, final, summaries)[0]


def check_folder(folder: Path, final: str, summaries: tuple[str, ...]) -> tuple[str, dict[str, Any] | None]:
    """(:func:`folder_problem`, the manifest's file list or None for a folder written before manifests).

    ``results.nc`` and ``manifest.json`` are opened only as regular files (a FIFO, a link or a device
    there is refused, never read), and ``results.nc`` must have the size the manifest records."""
    try:
        if final == ZARR_FINAL:  # a folder: a real one, never a link
            if os.path.islink(folder / final) or not (folder / final).is_dir():
                raise PlantedEntryError(f"{folder / final} is not a folder (a link or a file planted there)")
            size = store_size(folder / final)
        else:
            with open_regular(folder / final, what=final) as fh:
                size = os.fstat(fh.fileno()).st_size
        with open_store(folder / final) as nc:
            problem = finished_problem(nc)
            run_id = str(nc.getncattr("run_id")) if "run_id" in nc.ncattrs() else None
    except PlantedEntryError as exc:
        return str(exc), None
    except OSError as exc:
        return f"{final} cannot be read ({exc.strerror or exc})", None
    if problem:
        return problem, None
    path = folder / MANIFEST
    if not os.path.lexists(path):
        if run_id is None:
            return "", None  # written before manifests existed
        return (
            f"{INCONSISTENT} ({final} is from run {run_id}, and there is no {MANIFEST}: the run that wrote it "
            "stopped before its last rename)"
        ), None
    try:
        with open_regular(path, MANIFEST_MAX, MANIFEST) as fh:
            manifest = json.loads(fh.read().decode("utf-8"))
        listed = manifest["files"]
        their_id = str(manifest["run_id"])
        if not isinstance(listed, dict):
            raise TypeError("'files' is not a mapping")
    except PlantedEntryError as exc:
        return f"{INCONSISTENT} ({exc})", None
    except (OSError, ValueError, KeyError, TypeError) as exc:
        return f"{INCONSISTENT} ({MANIFEST} cannot be read: {exc})", None
    if their_id != run_id:
        return f"{INCONSISTENT} ({final} is from run {run_id}, {MANIFEST} from run {their_id})", None
    stale = [n for n in summaries if n not in listed and os.path.lexists(folder / n)]
    if stale:
        return f"{INCONSISTENT} ({', '.join(stale)} not written by the run that wrote {final})", None
    want = listed.get(final, {}).get("size") if isinstance(listed.get(final), dict) else None
    if want is not None and want != size:
        return f"{INCONSISTENT} ({final} has {size} bytes, {MANIFEST} records {want})", None
    return "", listed
