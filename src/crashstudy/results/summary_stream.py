"""``summary.parquet`` made from the chunks as they are written, not read back from the finished store.

:func:`crashstudy.results.tables.write_summary` makes the table at the end of a run by reading every
summary variable of the finished store again (at 10^6 variants ~1 CPU s of the run, after the last
chunk). :class:`SummaryStream` makes the same table during the run: :class:`~crashstudy.results.store.ResultWriter`
hands it each chunk's stored arrays and text codes (on the writer thread, behind the kernel); it keeps the
rows of the row group being filled (``SUMMARY_BLOCK`` rows at most) and writes each whole row group
through the same :func:`~crashstudy.results.tables.summary_columns`, over a dataset that holds what the
store holds for those variants. The file is the one ``write_summary`` would write, byte for byte
(tests/test_summary_stream.py), or it is not used:

- only a fresh run whose chunks arrive in variant order from 0 (the in-process runner) streams, and
  ``summary.csv`` with it when asked for (the same tables through pyarrow's CSV writer); a resumed run,
  reused variants or a chunk out of order (process pools, Dask): the finished store is read as before;
- a row group's texts are coded against the text tables as they are when it is written; when a table
  at the end (sorted, :meth:`ResultWriter._sort_tables`) is not the one every row group used (a text that
  first appeared later), or a text would not be stored whole, the stream is dropped and the table is made
  from the store.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
from pathlib import Path
from typing import Any, cast

import numpy as np

from crashstudy.metrics.record import NOTE_TEXT
from crashstudy.results import tables as T
from crashstudy.safefs import open_new
from crashstudy.vocabulary.summary import SUMMARY_META

STREAM = (
    ".stream.partial"  # suffix of the tables being made (renamed to summary.parquet / .csv when the run ends)
)


class SummaryStream:
    """The summary table of a run written as its chunks arrive (see the module docstring)."""

    def __init__(self, folder: Path, nc: Any, plan: Any, csv: bool = False) -> None:
        from crashstudy.metrics.record import METRIC_META

        self.plan, self.n = plan, plan.n_variants
        self.paths = {name: folder / (name + STREAM) for name in (T.PARQUET, *([T.SUMMARY] if csv else []))}
        self.axes = [a.path for a in plan.axes]
        topo = plan.topology
        self.ids = {"spring": topo.spring_ids, "node": topo.node_ids, "wall": topo.wall_ids}
        # the summary variables the store holds, with the attributes summary_columns reads (asked items)
        self.names: dict[str, tuple[tuple[str, ...], dict[str, str]]] = {}
        for name, dims in [
            *((n, d) for n, (d, _, _) in SUMMARY_META.items()),
            *((n, ("node",)) for n in METRIC_META),
        ]:
            if name in nc.variables:
                var = nc.variables[name]
                self.names[name] = (
                    dims,
                    {k: str(var.getncattr(k)) for k in ("nodes", "springs") if k in var.ncattrs()},
                )
        self.texts = [n for n in T.text_tables(topo) if n in nc.variables]
        self.next = 0  # the first variant not yet handed over
        self.rows: list[Any] = []  # the summary rows (pyarrow Tables) of the row group being filled
        self.held = 0  # rows in them
        self.used: list[dict[str, list[str]]] = []  # the text tables each chunk's rows were coded with
        self.files: list[_Hashing] = []  # the open tables, in the order of self.paths
        self.digests: dict[str, str] = {}  # final name: SHA-256, once the tables are finished
        self.writers: list[Any] = []  # their writers (Parquet, then CSV)
        self.live = self.n > 0

    def add(
        self,
        lo: int,
        hi: int,
        data: dict[str, np.ndarray],
        codes: dict[str, np.ndarray],
        tables: dict[str, dict[str, int]],
    ) -> None:
        """Variants ``lo`` .. ``hi - 1``: their stored arrays ``data``, their text codes into the writer's
        ``tables`` (text -> code, in the order the texts first came)."""
        if not self.live:
            return
        if lo != self.next:
            self.drop()
            return
        self.next = hi
        table = self._rows(lo, hi, data, codes, tables)
        if table is None:
            return
        self.rows.append(table)
        self.held += hi - lo
        block = T.SUMMARY_BLOCK
        while self.live and (self.held >= block or (self.next == self.n and self.held)):
            self._write_group(min(block, self.held))

    def _rows(
        self,
        lo: int,
        hi: int,
        data: dict[str, np.ndarray],
        codes: dict[str, np.ndarray],
        tables: dict[str, dict[str, int]],
    ) -> Any:
        """The summary rows of variants ``lo`` .. ``hi - 1`` (a pyarrow Table), their texts coded against
        the sorted ``tables`` (recorded in ``used``); None if the stream is dropped."""

        size = hi - lo
        sorted_tables = {n: sorted(tables[n]) for n in self.texts}
        if any(len(t.encode("utf-8")) > T.TEXT_LEN or "\0" in t for ts in sorted_tables.values() for t in ts):
            self.drop()  # stored cut or padded: the store's table is not these texts
            return None
        rows: dict[str, _Var] = {}
        for name, (_, attrs) in self.names.items():
            rows[name] = _Var(data[name], attrs)
        rows["status"] = _Var(data["status"])
        for n, table in sorted_tables.items():  # the store's codes once its tables are sorted
            old = tables[n]
            new_code = np.empty(len(old), dtype=np.int32)
            for k, text in enumerate(table):
                new_code[old[text]] = k
            rows[n] = _Var(new_code[codes[n]])
            rows[f"{n}_text"] = _Var(np.array(table, dtype=str))
        rows["variant"] = _Var(np.arange(lo, hi, dtype=np.int64))
        for path, values in self.plan.axis_values(lo, hi).items():
            rows[path] = _Var(values)
        for d, ids in self.ids.items():
            if ids:
                rows[d] = _Var(np.array(ids, dtype=str))
        ds = _Rows(rows, {"crashstudy_axes": json.dumps(self.axes)}, size)
        self.used.append(sorted_tables)
        return T.arrow_table(T.summary_columns(cast(Any, ds), 0, size))  # read as a store opened by xarray

    def _write_group(self, size: int) -> None:
        """Write the first ``size`` rows held as one row group (contiguous columns, as write_summary's)."""
        import pyarrow as pa
        import pyarrow.parquet as pq

        held = pa.concat_tables(self.rows)
        table = held.slice(0, size)  # chunked as the chunks came: the same row group (tests: same bytes)
        self.rows = [held.slice(size)] if self.held > size else []
        self.held -= size
        if not self.writers:  # the writers of write_summary
            import pyarrow.csv as pcsv

            for path in self.paths.values():
                self.files.append(_Hashing(open_new(path, mode="wb")))
            texts = [n for n in ("status", *T.TEXT_TABLES, NOTE_TEXT) if n in table.column_names]
            self.writers.append(pq.ParquetWriter(self.files[0], table.schema, use_dictionary=texts))
            if len(self.files) > 1:
                self.writers.append(pcsv.CSVWriter(self.files[1], table.schema))
        for w in self.writers:
            w.write_table(table)

    def result(self, tables: dict[str, dict[str, int]]) -> dict[str, Path] | None:
        """The finished tables ({final name: temporary path}) if they are the ones the store's final
        ``tables`` give, else None (dropped: the caller makes them from the store). Their SHA-256 (of the
        bytes as they were written): :attr:`digests`."""
        final = {n: sorted(tables[n]) for n in self.texts}
        if not (
            self.live
            and self.next == self.n
            and not self.held
            and self.writers
            and all(u == final for u in self.used)
        ):
            self.drop()
            return None
        while self.writers:
            self.writers.pop(0).close()
        for fh in self.files:
            fh.close()
        self.digests = {name: fh.sha.hexdigest() for name, fh in zip(self.paths, self.files, strict=True)}
        self.live = False
        return dict(self.paths)

    def drop(self) -> None:
        """Stop streaming and remove what was written."""
        self.live, self.rows, self.held = False, [], 0
        while self.writers:
            with contextlib.suppress(Exception):
                self.writers.pop(0).close()
        while self.files:
            with contextlib.suppress(OSError):  # a full disk: the file is removed below anyway
                self.files.pop(0).close()
        for path in self.paths.values():
            with contextlib.suppress(OSError):
                path.unlink()


class _Hashing:
    """A file open for writing that hashes what is written to it (the manifest's SHA-256 of a table without
    reading the table again: 0.1 s of a 10^6-variant run's end). pyarrow writes to it through ``write``."""

    def __init__(self, fh: Any) -> None:
        self.fh, self.sha = fh, hashlib.sha256()

    def write(self, data: Any) -> int:
        self.sha.update(data)
        return int(self.fh.write(data))

    def __getattr__(self, name: str) -> Any:  # tell, flush, close, closed, ...: the file's own
        return getattr(self.fh, name)


class _Var:
    """A variable of :class:`_Rows`: its values and attributes."""

    def __init__(self, values: np.ndarray, attrs: dict[str, str] | None = None) -> None:
        self.values, self.attrs = values, attrs or {}


class _Rows:
    """The rows of one row group as :func:`~crashstudy.results.tables.summary_columns` reads a store opened
    with xarray (the variables it asks for; ``isel`` is the whole group): no xarray Dataset, whose
    construction imports Dask when it is installed (1 CPU s of imports under load)."""

    def __init__(self, variables: dict[str, _Var], attrs: dict[str, str], size: int) -> None:
        self.variables, self.attrs, self.sizes = variables, attrs, {"variant": size}

    def isel(self, variant: slice) -> _Rows:
        assert variant.start in (0, None) and variant.stop in (self.sizes["variant"], None), variant
        return self

    def __contains__(self, name: object) -> bool:
        return name in self.variables

    def __getitem__(self, name: str) -> _Var:
        return self.variables[name]
