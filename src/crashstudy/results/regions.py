"""Workers write their own regions of a Zarr store (``--scheduler`` with ``--store zarr``, issue 19 item 3).

The client (:class:`crashstudy.results.store.ResultWriter`) creates ``results.zarr.partial`` with every
variable, chunked along ``variant`` by the run's chunk size. Each task (:func:`write_region`, on a worker)
computes the variant ranges of one stored chunk, writes them into the store at its shared path (every
per-variant variable, the text variables as codes into a table of the task's own, the checksums last)
and returns a :class:`Receipt`: the ranges, the per-variant checksums, the count of failed variants and
the task's text tables. The client then (:func:`record`):

1. reads the region's stored checksums back and compares them with the receipt's (a store the client
   does not see, i.e. an output folder that is not shared with the workers, is an input error);
2. turns the task's text codes into the store's (the texts new to the store are appended to its tables;
   the region's codes are rewritten only when the two numberings differ);
3. marks the region ``done``.

A task never shares a stored object with another: its ranges lie in one chunk of the store
(:func:`region_tasks` cuts and groups them), and only the client writes ``done`` and the tables. A worker
that dies mid-task leaves a region without ``done``: Dask computes the task again (the region is written
anew), and ``--resume`` computes it again. A task still running from an interrupted run (a remote
worker finishes what it started) writes nothing into the store of another study. The worker checks its region by reading it back before it
sends the receipt. The finished store is the in-process one, bit for bit: the same arrays, and the text
tables sorted at the end as always.
"""

from __future__ import annotations

import functools
import os
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from crashstudy.errors import InputError, Problem
from crashstudy.metrics.record import NOTE_TEXT
from crashstudy.results import integrity
from crashstudy.results.attributes import plan_fingerprint
from crashstudy.results.tables import metric_arrays, summary_arrays, text_tables
from crashstudy.results.zarr_file import ZarrFile, variant_chunk

NOT_SHARED = (
    "the Dask workers wrote {path} where this process does not see it (variants {lo} .. {last}: "
    "checksums differ): with --scheduler and --store zarr the output folder must be a path every "
    "worker sees (a shared file system), or use --store netcdf"
)


@dataclass(frozen=True)
class Receipt:
    """What a worker sends back for a region it wrote: no arrays but the checksums."""

    ranges: tuple[tuple[int, int], ...]  # the variant ranges written, in order, within one stored chunk
    sums: np.ndarray  # uint64 checksums of the ranges' variants, in order
    n_failed: int
    texts: dict[str, tuple[str, ...]]  # per text variable: code k in the region means texts[name][k]

    @property
    def size(self) -> int:
        """Variants written."""
        return sum(hi - lo for lo, hi in self.ranges)


def stored_arrays(plan: Any, res: Any) -> dict[str, np.ndarray]:
    """The checksummed per-variant arrays of a computed chunk (a ``ChunkResult``), as stored."""
    o = res.out
    data: dict[str, np.ndarray] = {}
    for name, arr in o.histories.items():
        data[name] = np.ascontiguousarray(np.moveaxis(arr, -1, 0), dtype=np.float64)
    data.update(summary_arrays(plan, res))
    if plan.topology.metrics:
        data.update(metric_arrays(plan, res))
    data["status"] = (o.status != 0).astype("i1")
    data["input_hash"] = np.ascontiguousarray(res.hashes, dtype=np.uint64)
    for arr in data.values():  # -0.0 (a zero force on the other side, say) is stored and shown as 0.0
        if arr.dtype.kind == "f":
            np.add(arr, 0.0, out=arr)
    return data


def text_values(res: Any) -> dict[str, np.ndarray]:
    """The texts of a computed chunk stored as codes into a table: {variable: (V,) texts}."""
    texts = {"failure_reason": res.reasons, "dt_control": res.dt_control}
    if res.criteria is not None:
        texts[NOTE_TEXT] = np.where(res.out.status != 0, "", res.criteria.notes)
    return texts


def codes_in(table: dict[str, int], texts: Any) -> tuple[np.ndarray, list[str]]:
    """Codes of ``texts`` in ``table`` (text -> code), the new texts added to it at the next codes;
    returns (int32 codes, the new texts in code order)."""
    import pyarrow as pa  # (was pandas' factorize: the same codes, and no pandas import of its own)

    coded = pa.array(np.asarray(texts, dtype=object), type=pa.string()).dictionary_encode()
    codes, uniq = coded.indices.to_numpy(), coded.dictionary.to_pylist()  # uniq in order of first appearance
    new = [t for t in uniq if t not in table]
    start = len(table)
    table.update({t: start + k for k, t in enumerate(new)})
    ids = np.array([table[t] for t in uniq], dtype=np.int32)
    return (ids[codes] if len(codes) else np.zeros(0, dtype=np.int32)), new


def write_region(
    compute: Callable[..., Any], path: str, plan: Any, ranges: list[tuple[int, int]], kernel: str
) -> Receipt:
    """On a worker: compute each range with ``compute(plan, lo, hi, kernel)`` (``run_chunk``), write it
    into the store at ``path``, read it back, and return the :class:`Receipt`."""
    nc: Any = ZarrFile(path, "a")  # the netCDF4 API subset integrity uses
    if nc.getncattr("plan_fingerprint") != plan_fingerprint(plan):  # a task left running by an earlier run
        raise OSError(
            f"{path} is no longer the store of this task's study (it was started again): not written"
        )
    names = integrity.checked_names(nc)
    local: dict[str, dict[str, int]] = {name: {} for name in text_tables(plan.topology)}
    sums, failed = [], 0
    for lo, hi in ranges:
        res = compute(plan, lo, hi, kernel)
        data = stored_arrays(plan, res)
        assert sorted(data) == names, (sorted(data), names)
        for name in names:
            nc.variables[name][lo:hi] = data[name]
        for name, texts in text_values(res).items():
            nc.variables[name][lo:hi] = codes_in(local[name], texts)[0]
        s = integrity.variant_sums(data, names)
        if not np.array_equal(integrity.file_sums(nc, lo, hi), s):
            raise OSError(f"{path}: variants {lo} .. {hi - 1} read back differ from what was written")
        nc.variables[integrity.CHECKSUM][lo:hi] = s  # last: the region's data are in place
        sums.append(s)
        failed += int(np.count_nonzero(res.out.status))
    nc.close()
    return Receipt(tuple(ranges), np.concatenate(sums), failed, {n: tuple(t) for n, t in local.items()})


def regions(ranges: list[tuple[int, int]], chunk: int) -> Iterator[list[tuple[int, int]]]:
    """``ranges`` (sorted, disjoint) cut at the multiples of ``chunk`` and grouped by stored chunk."""
    group: list[tuple[int, int]] = []
    for lo, hi in ranges:
        while lo < hi:
            end = min(hi, (lo // chunk + 1) * chunk)
            if group and group[-1][0] // chunk != lo // chunk:
                yield group
                group = []
            group.append((lo, end))
            lo = end
    if group:
        yield group


def region_tasks(
    writer: Any, compute: Callable[..., Any], plan: Any, ranges: list[tuple[int, int]], kernel: str
) -> tuple[Callable[..., Any], Iterator[tuple[Any, ...]]]:
    """The function and tasks that have workers write the variants ``ranges`` into ``writer``'s store."""
    chunk = variant_chunk(writer.path) or max(1, plan.n_variants)
    fn = functools.partial(write_region, compute, os.path.abspath(writer.path))
    return fn, ((plan, group, kernel) for group in regions(ranges, chunk))


def record(writer: Any, receipt: Receipt) -> None:
    """On the client: check ``receipt`` against the store, give its texts the store's codes, mark it done."""
    nc = writer.nc
    at = 0
    for lo, hi in receipt.ranges:
        if not np.array_equal(
            integrity.stored(nc, integrity.CHECKSUM, lo, hi), receipt.sums[at : at + hi - lo]
        ):
            raise InputError(
                [Problem("-o", None, "", NOT_SHARED.format(path=Path(writer.path), lo=lo, last=hi - 1))]
            )
        at += hi - lo
    for name, local in receipt.texts.items():
        ids = writer._codes(name, np.asarray(local, dtype=object))  # the store's code of each local code
        if np.array_equal(ids, np.arange(len(ids))):
            continue
        for lo, hi in receipt.ranges:
            codes = integrity.stored(nc, name, lo, hi)
            nc.variables[name][lo:hi] = np.where(codes >= 0, ids[np.clip(codes, 0, None)], -1)
    for lo, hi in receipt.ranges:
        nc.variables["done"][lo:hi] = 1
    nc.sync()
