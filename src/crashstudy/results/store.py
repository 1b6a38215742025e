"""Result files: ``results.nc`` written chunk by chunk, ``summary.parquet`` / ``summary.csv``.

The netCDF file is built as ``results.nc.partial`` (netCDF4, variants written as they finish, a
``done`` flag and a checksum per variant flushed with them) and renamed to ``results.nc``
only when every variant is in it: an interrupted run never leaves a file that looks complete, and
``--resume`` continues the partial file. The summary tables are written to temporary files:
``summary.parquet`` always, ``summary.csv`` up to ``CSV_MAX`` variants unless asked otherwise. Then
``results.nc`` (marked ``complete``), the tables and last ``manifest.json`` are renamed into place;
:class:`Results` refuses a folder whose files are not one finished run's (:mod:`crashstudy.results.integrity`).

Texts that repeat across variants are stored compactly (:mod:`crashstudy.results.tables`, docs/format.md
"Results"); :attr:`Results.dataset` and :attr:`Results.summary` give them back as texts.
"""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path
from typing import Any

import netCDF4
import numpy as np

from crashstudy import __version__
from crashstudy.errors import InputError, Problem
from crashstudy.kernel.output import ALL_SHAPES
from crashstudy.metrics.record import METRIC_META, asked_nodes, result_names, standard
from crashstudy.results import integrity
from crashstudy.results.attributes import axis_unit, model_facts, plan_fingerprint, units_of
from crashstudy.results.chunk_result import ChunkResult
from crashstudy.results.curve_ends import curve_springs
from crashstudy.results.integrity import FINAL, PARTIAL
from crashstudy.results.placement import partial_opens, remove_store, swap_store
from crashstudy.results.reader import Results, open_raw, open_results  # the one reader, re-exported
from crashstudy.results.regions import Receipt, codes_in, record, stored_arrays, text_values
from crashstudy.results.summary_stream import SummaryStream
from crashstudy.results.tables import (
    CSV_MAX,
    HISTORY_META,
    PARQUET,
    STATUS_MEANINGS,
    SUMMARY,
    TEXT_LEN,
    chars,
    decode_texts,
    read_texts,
    stored_table,
    summary_frame,
    text_tables,
    write_summary,
)
from crashstudy.results.zarr_file import ZARR_FINAL, ZarrFile
from crashstudy.safefs import PlantedEntryError, clear_entry, create_new, is_regular
from crashstudy.study.plan import Plan
from crashstudy.study.provenance import HASH_WORDS, text_hash
from crashstudy.vocabulary.summary import SUMMARY_META

__all__ = [
    "CSV_MAX",
    "FINAL",
    "PARQUET",
    "PARTIAL",
    "SUMMARY",
    "ResultWriter",
    "Results",
    "decode_texts",
    "open_results",
    "summary_frame",
    "write_summary",
]

ID_LEN = 64  # longest id (the schema allows 64 characters)
AXIS_BLOCK = 1_000_000  # variants whose axis coordinates are written at once
CHUNK_BYTES = 2**21  # most bytes of a per-variant HDF5 chunk (the run's chunk halved to fit, else 4096)
REUSE_BLOCK = 65536  # variants copied at once from an earlier result


class ResultWriter:
    """Writes a plan's results into ``directory`` chunk by chunk (see the module docstring)."""

    def __init__(
        self,
        directory: str | os.PathLike[str],
        plan: Plan,
        resume: bool = False,
        csv: bool | None = None,
        store: str = "netcdf",
        chunk: int = 4096,
    ) -> None:
        self.dir = Path(directory)
        self.final_name = ZARR_FINAL if store == "zarr" else FINAL
        self.chunk = chunk  # variants per stored chunk along ``variant`` (Zarr: the run's chunk size)
        self.csv = plan.n_variants <= CSV_MAX if csv is None else csv
        self.plan = plan
        self.plan_axes = {a.path for a in plan.axes}
        # netCDF's default 64 MiB chunk cache per variable keeps written chunks in memory (a 10^6-variant
        # study peaked at 1.2 GiB); chunks are written once, so a small cache costs nothing
        netCDF4.set_chunk_cache(4 * 2**20)
        self.dir.mkdir(parents=True, exist_ok=True)
        self.path = self.dir / integrity.partial_name(self.final_name)
        if resume and os.path.islink(self.path):
            raise InputError(
                [
                    Problem(
                        plan.study_file or plan.model_file,
                        None,
                        "",
                        f"{self.path} is a symbolic link, not a partial result of crashstudy; "
                        "refusing to write through it (remove it, or use --force)",
                    )
                ]
            )
        if resume and self.path.exists() and not partial_opens(self.path):
            # cut off before its first chunk was flushed (SIGKILL, full disk): nothing in it can be used
            print(
                f"note: {self.path} could not be read (cut off while being written); starting it again",
                file=sys.stderr,
            )
            remove_store(self.path)
        if resume and self.path.exists():
            self.nc = integrity.open_store(self.path, "a")
            if self.nc.getncattr("plan_fingerprint") != plan_fingerprint(plan):
                self.nc.close()
                raise InputError(
                    [
                        Problem(
                            plan.study_file or plan.model_file,
                            None,
                            "",
                            f"the unfinished run in {self.dir} was started from a different study or "
                            "model; use --force to start again",
                        )
                    ]
                )
            self._verify_resumed()
        else:
            self.nc = self._create()
        self.tables = {
            name: {t: k for k, t in enumerate(stored_table(self.nc, name))}
            for name in text_tables(plan.topology)
        }
        # summary.parquet made as the chunks come (a fresh run's), else from the finished store
        self.stream = SummaryStream(self.dir, self.nc, plan, self.csv) if not resume else None

    def _verify_resumed(self) -> None:
        """Forget the done variants whose data no longer match their checksum: they are computed again.
        A partial file from before checksums gets them now (its done variants trusted)."""
        done = self.done()
        if integrity.CHECKSUM not in self.nc.variables:
            cs = self.nc.createVariable(integrity.CHECKSUM, "u8", ("variant",), fill_value=0)
            cs.units, cs.long_name = "1", "sum of the variant's stored results (crashstudy.results.integrity)"
            for lo, hi in _ranges_of(done):
                cs[lo:hi] = integrity.file_sums(self.nc, lo, hi)
        lost = done & ~integrity.intact(self.nc, done)
        if lost.any():
            first = np.flatnonzero(lost)
            where = ", ".join(str(k) for k in first[:5]) + (", ..." if len(first) > 5 else "")
            print(
                f"note: {len(first)} finished variant(s) of {self.path} no longer match their checksum "
                f"(variants {where}); computing them again",
                file=sys.stderr,
            )
            self.nc.variables["done"][:] = (done & ~lost).astype("i1")
            self.nc.sync()
        missing = [n for n in self._summary_names() if n not in self.nc.variables]
        if missing:  # a partial file of an earlier version: its done variants keep NaN there (not computed)
            for name in missing:
                self._summary_variable(self.nc, name)
            for lo, hi in _ranges_of(done & ~lost):
                self.nc.variables[integrity.CHECKSUM][lo:hi] = integrity.file_sums(self.nc, lo, hi)
            self.nc.sync()

    def _summary_names(self) -> list[str]:
        """The summary variables of this plan's results (SUMMARY_META; walls only with walls)."""
        walls = bool(self.plan.topology.wall_ids)
        return [n for n, (dims, _, _) in SUMMARY_META.items() if walls or dims != ("wall",)]

    def done(self) -> np.ndarray:
        """Boolean (V,): variants already written."""
        return np.asarray(self.nc.variables["done"][:], dtype=bool)

    def _create(self) -> netCDF4.Dataset:
        p = self.plan
        topo = p.topology
        units = units_of(p)
        V = p.n_variants
        if self.final_name == ZARR_FINAL:
            remove_store(self.path)  # a planted link at the partial's name is removed, never written through
            nc: Any = ZarrFile(self.path, "w", chunk=min(self.chunk, max(V, 1)))
        else:
            create_new(self.path)  # a planted link at the partial's name is removed, never written through
            nc = netCDF4.Dataset(self.path, "w", format="NETCDF4")
        nc.createDimension("variant", V)
        nc.createDimension("time", p.n_out)
        nc.createDimension("node", topo.n_nodes)
        nc.createDimension("spring", topo.n_springs)
        nc.createDimension("axis", topo.dim)
        nc.createDimension("wall", len(topo.wall_ids))
        var = nc.createVariable("variant", "i8", ("variant",))
        for lo in range(0, V, AXIS_BLOCK):  # in blocks: np.arange of 10^8 variants alone is 800 MB
            var[lo : min(lo + AXIS_BLOCK, V)] = np.arange(lo, min(lo + AXIS_BLOCK, V))
        var.units, var.long_name = "1", "variant number (row-major over the study axes)"
        tv = nc.createVariable("time", "f8", ("time",))
        tv[:] = p.times
        tv.units, tv.long_name = units["time"], "time"
        # strings are fixed-width character arrays (CF): variable-length strings crash libhdf5 when a
        # file is opened many times (netcdf4-python issue 1444)
        nc.createDimension("id_len", ID_LEN)
        for dim, ids in (
            ("node", topo.node_ids),
            ("spring", topo.spring_ids),
            ("axis", ("x", "y")[: topo.dim]),
            ("wall", topo.wall_ids),
        ):
            v = nc.createVariable(dim, "S1", (dim, "id_len"))
            v._Encoding = "utf-8"
            v.units, v.long_name = "", f"{dim} id" if dim != "axis" else "coordinate axis"
            if ids:
                v[:] = chars(list(ids), ID_LEN)
        for ax in p.axes:
            v = nc.createVariable(ax.path, "f8", ("variant",), zlib=False)
            v.long_name = f"study axis {ax.path}"
            v.units = units[axis_unit(ax.path, p)]
        for lo in range(0, V, AXIS_BLOCK):  # in blocks: bounded memory for any number of variants
            for path, values in p.axis_values(lo, min(V, lo + AXIS_BLOCK)).items():
                nc.variables[path][lo : lo + len(values)] = values
        for name in topo.histories + topo.extra_histories:
            dims = ("variant", "time", *ALL_SHAPES[name])
            sizes = [1, p.n_out] + [len(nc.dimensions[d]) for d in ALL_SHAPES[name]]
            v = nc.createVariable(name, "f8", dims, fill_value=np.nan, chunksizes=[max(1, s) for s in sizes])
            v.units, v.long_name = units[HISTORY_META[name][0]], HISTORY_META[name][1]
        for name in self._summary_names():
            self._summary_variable(nc, name)
        for name in (
            result_names(topo) if topo.metrics else ()
        ):  # the crash criteria (none: no numba import here)
            kind, long = METRIC_META[name]
            cn = [self._cv(topo.n_nodes), topo.n_nodes]
            v = nc.createVariable(name, "f8", ("variant", "node"), fill_value=np.nan, chunksizes=cn)
            v.units, v.long_name, v.standard = units[kind], long, standard(name)
            v.nodes = " ".join(asked_nodes(topo, name))  # the others are NaN (and have no summary column)
        # compressed ~50x, costs little
        small: dict[str, Any] = {"zlib": True, "complevel": 1, "shuffle": True, "chunksizes": [self._cv(1)]}
        st = nc.createVariable("status", "i1", ("variant",), fill_value=-1, **small)
        st.units, st.long_name = "1", "ok or failed (failure_reason says why)"
        st.flag_values, st.flag_meanings = (
            np.arange(len(STATUS_MEANINGS), dtype="i1"),
            " ".join(STATUS_MEANINGS),
        )
        nc.createDimension("text_len", TEXT_LEN)
        for name, long in text_tables(topo).items():
            nc.createDimension(f"{name}_kind", None)
            tv = nc.createVariable(
                f"{name}_text", "S1", (f"{name}_kind", "text_len"), chunksizes=[16, TEXT_LEN]
            )
            tv._Encoding = "utf-8"
            tv.units, tv.long_name = "", f"the distinct texts of {name}"
            v = nc.createVariable(name, "i4", ("variant",), fill_value=-1, **small)
            v.units, v.long_name, v.texts = "1", f"{long}: index into {name}_text", f"{name}_text"
        nc.createDimension("hash_word", HASH_WORDS)
        hv = nc.createVariable(
            "input_hash", "u8", ("variant", "hash_word"), chunksizes=[self._cv(HASH_WORDS), HASH_WORDS]
        )
        hv.units, hv.long_name = "1", "hash of everything that determines the variant's results (reuse key)"
        d = nc.createVariable("done", "i1", ("variant",), fill_value=0, **small)
        d.units, d.long_name = "1", "1 once the variant's results are written"
        cs = nc.createVariable(integrity.CHECKSUM, "u8", ("variant",), fill_value=0, **small)
        cs.units, cs.long_name = "1", "sum of the variant's stored results (crashstudy.results.integrity)"
        if p.axes:  # CF: the study axes are coordinates of every per-variant variable
            coords = " ".join(a.path for a in p.axes)
            for v in nc.variables.values():
                if v.dimensions[:1] == ("variant",) and v.name != "variant" and v.name not in self.plan_axes:
                    v.coordinates = coords
        nc.setncatts(
            {
                "title": f"crashstudy results of {p.name}",
                "crashstudy_version": __version__,
                "units": topo.units,
                "model_name": topo.name,
                "model_file": p.model_file,
                "model_yaml": p.model_text,
                "study_file": p.study_file,
                "study_yaml": p.study_text,
                "crashstudy_axes": json.dumps([a.path for a in p.axes]),
                "plan_fingerprint": plan_fingerprint(p),
                "history_interval": p.interval,
                "study_name": p.name,
                "model_sha256": text_hash(p.model_text),
                "study_sha256": text_hash(p.study_text),
                "Conventions": "CF-1.8",
                **model_facts(p),
            }
        )
        return nc

    def write(self, res: ChunkResult | Receipt) -> None:
        """Write one chunk's variants (``res.index`` must be a contiguous range), or record the region a
        worker wrote (a :class:`~crashstudy.results.regions.Receipt`, :func:`~crashstudy.results.regions.record`)."""
        if isinstance(res, Receipt):
            self._no_stream()
            record(self, res)
            return
        lo, hi = int(res.index[0]), int(res.index[-1]) + 1
        assert hi - lo == len(res.index), "chunks are contiguous ranges"
        nc = self.nc
        data = stored_arrays(self.plan, res)  # as stored: the chunk's checksum is taken over these
        names = integrity.checked_names(nc)
        assert sorted(data) == names, (sorted(data), names)
        for name in names:
            nc.variables[name][lo:hi] = data[name]
        codes = {}
        for name, texts in text_values(res).items():  # each table grown, then its codes written (file layout)
            codes[name] = nc.variables[name][lo:hi] = self._codes(name, texts)
        nc.variables["done"][lo:hi] = 1
        nc.variables[integrity.CHECKSUM][lo:hi] = integrity.variant_sums(data, names)
        nc.sync()
        if self.stream is not None:
            self.stream.add(lo, hi, data, codes, self.tables)

    def _no_stream(self) -> None:
        """Make summary.parquet from the finished store (variants not written here in order from 0)."""
        if self.stream is not None:
            self.stream.drop()
            self.stream = None

    def _cv(self, width: int) -> int:
        """Chunk length along ``variant`` of ``width`` 8-byte values: the run's (whole HDF5 chunks per write)."""
        c = self.chunk if self.final_name != ZARR_FINAL else 4096
        while c > 4096 and c % 2 == 0 and c * 8 * width > CHUNK_BYTES:
            c //= 2
        return max(1, min(self.plan.n_variants, c if 4096 <= c and c * 8 * width <= CHUNK_BYTES else 4096))

    def _summary_variable(self, nc: netCDF4.Dataset, name: str) -> None:
        """Create summary variable ``name`` (SUMMARY_META), chunked by :meth:`_cv`."""
        dims, kind, long = SUMMARY_META[name]
        rest = [max(1, len(nc.dimensions[d])) for d in dims]
        shape = [self._cv(int(np.prod(rest))), *rest]
        v = nc.createVariable(name, "f8", ("variant", *dims), fill_value=np.nan, chunksizes=shape)
        v.units, v.long_name = units_of(self.plan)[kind], long
        if name == "past_curve_end":  # the springs with a drawn curve (the others have no summary column)
            topo = self.plan.topology
            v.springs = " ".join(
                topo.spring_ids[s] for s in curve_springs(topo.material, topo.spring_curves[:, 0])
            )

    def _codes(self, name: str, texts: Any) -> np.ndarray:
        """Indices of ``texts`` in the file's table of ``name``; new texts are appended to it."""
        table = self.tables[name]
        start = len(table)
        codes, new = codes_in(table, texts)
        if new:
            self.nc.variables[f"{name}_text"][start : start + len(new)] = chars(new, TEXT_LEN)
        return codes

    def reuse(self, old: netCDF4.Dataset, new_idx: np.ndarray, old_idx: np.ndarray) -> int:
        """Copy finished variants ``old_idx`` of an earlier result into variants ``new_idx`` and mark them
        done, except those whose data do not match their checksum (left to compute). Returns how many
        were kept."""
        if not len(new_idx):
            return 0
        self._no_stream()
        names = [
            n
            for n, v in self.nc.variables.items()
            if v.dimensions[:1] == ("variant",)
            and n != "variant"
            and n not in self.plan_axes
            and n in old.variables
        ]
        brk = np.nonzero((np.diff(new_idx) != 1) | (np.diff(old_idx) != 1))[0] + 1
        starts = np.concatenate([[0], brk]).tolist()
        ends = np.concatenate([brk, [len(new_idx)]]).tolist()
        kept = 0
        done = self.nc.variables["done"]
        for s, e in zip(starts, ends, strict=True):  # runs of consecutive variants on both sides
            for k in range(s, e, REUSE_BLOCK):  # in blocks: bounded memory however long the run
                a, c = int(new_idx[k]), int(old_idx[k])
                m = min(e - k, REUSE_BLOCK)
                b, d = a + m, c + m
                for n in names:
                    if n in self.tables:  # texts: re-coded into this file's tables
                        self.nc.variables[n][a:b] = self._codes(n, read_texts(old, n, c, d))
                    elif n == "status":
                        self.nc.variables[n][a:b] = (read_texts(old, n, c, d) != "ok").astype("i1")
                    else:
                        self.nc.variables[n][a:b] = old.variables[n][c:d]
                if (
                    integrity.CHECKSUM not in old.variables
                ):  # a file from before checksums: trusted, summed now
                    self.nc.variables[integrity.CHECKSUM][a:b] = integrity.file_sums(self.nc, a, b)
                # a copied variant whose data do not match its checksum is left to compute
                good = integrity.file_sums(self.nc, a, b) == integrity.stored(
                    self.nc, integrity.CHECKSUM, a, b
                )
                done[a:b] = good.astype("i1")
                kept += int(good.sum())
        self.nc.sync()
        return kept

    def _sort_tables(self) -> None:
        """Put each text table in sorted order (and renumber its indices), so that a file does not depend
        on the order in which chunks finished (process pools, resume)."""
        block = integrity.CHECK_BLOCK
        for name, table in self.tables.items():
            texts = sorted(table, key=lambda t: table[t])
            order = sorted(range(len(texts)), key=lambda k: texts[k])
            if order == list(range(len(texts))):
                continue
            new_id = np.empty(len(texts), dtype=np.int32)
            new_id[order] = np.arange(len(texts), dtype=np.int32)
            var = self.nc.variables[name]
            for lo in range(0, self.plan.n_variants, block):
                hi = min(
                    lo + block, self.plan.n_variants
                )  # Zarr: a slice past the end fails on its last chunk
                got = var[lo:hi]
                codes = np.asarray(got.filled(-1) if np.ma.isMaskedArray(got) else got)
                var[lo:hi] = np.where(codes >= 0, new_id[np.clip(codes, 0, None)], -1)
            self.nc.variables[f"{name}_text"][: len(texts)] = chars([texts[k] for k in order], TEXT_LEN)
            self.tables[name] = {texts[k]: i for i, k in enumerate(order)}

    def abort(self) -> None:
        """Close the partial file (kept for ``--resume``)."""
        try:
            self._no_stream()
        finally:  # the store is closed whatever the summary's file did (a full disk)
            if self.nc.isopen():
                self.nc.close()

    def finish(self) -> Path:
        """Mark the partial file complete, write the summary tables under temporary names, then rename
        ``results.nc`` first, the tables next (or remove an old ``summary.csv``) and ``manifest.json``
        last (see :mod:`crashstudy.results.integrity` for why this order)."""
        self._sort_tables()
        streamed = self.stream.result(self.tables) if self.stream is not None else None
        run_id = integrity.run_id(self.nc)
        self.nc.setncatts({"complete": np.int8(1), "run_id": run_id})
        self.nc.close()
        final = self.dir / self.final_name
        if streamed is not None:
            tables = streamed
        else:
            with open_raw(
                self.path, indexes=False
            ) as ds:  # no index (of every variant: memory; others: dask)
                tables = write_summary(ds, self.dir, self.csv, rename=False)
        zarr = self.final_name == ZARR_FINAL
        if not (self.path.is_dir() and not self.path.is_symlink() if zarr else is_regular(self.path)):
            raise PlantedEntryError(
                f"{self.path} was replaced by something else while the run was writing it"
            )
        if zarr:
            swap_store(self.path, final)
        else:
            os.replace(
                self.path, final
            )  # first: the old manifest names this file only if its results are the same
        remove_store(self.dir / (FINAL if zarr else ZARR_FINAL))  # one store per folder: the other is stale
        for name, tmp in tables.items():
            os.replace(tmp, self.dir / name)
        if SUMMARY not in tables:
            clear_entry(self.dir / SUMMARY)
        digests = self.stream.digests if streamed is not None and self.stream is not None else {}
        integrity.write_manifest(
            self.dir, run_id, [self.final_name, *tables], digests
        )  # last: the set is whole
        return final


def _ranges_of(mask: np.ndarray) -> list[tuple[int, int]]:
    """The contiguous runs of True in ``mask`` as (lo, hi) pairs."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], mask.astype(np.int8), [0]])))
    return [(int(a), int(b)) for a, b in zip(edges[::2], edges[1::2], strict=True)]
