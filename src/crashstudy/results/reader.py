"""The one reader of result folders: every command (summary, plot, compare, sensitivity) and the Python
API (:func:`open_results`) open a folder's files here, and nowhere else.

A folder is read only when it holds one finished run's set (:func:`crashstudy.results.integrity.check_folder`:
completion mark, run id named by ``manifest.json``). Each file is then read so that what is parsed is
what the run wrote:

- opened without following a link and without blocking, and used only if it is a regular file
  (:func:`crashstudy.safefs.open_regular`): a FIFO would hang the reader, a link to ``/dev/zero``
  fill memory;
- ``results.nc`` must have the size the manifest records (its variants carry their own checksums);
- a summary table must have the size and the SHA-256 the manifest records, hashed from the very
  handle that is then parsed: an edited ``summary.parquet``, or one copied beside another run's
  ``results.nc`` and manifest, is refused (exit 2), never used. It is hashed once per :class:`Results`
  (a 10^8-variant summary is ~12 GB): later handles of the same unchanged file (device, inode, size,
  mtime, ctime; the hashed handle is held open) are not hashed again, any other file is.

A folder written before manifests existed (no run id) is read as before: regular files only.
"""

from __future__ import annotations

import contextlib
import json
import os
import weakref
from collections.abc import Generator, Iterator
from pathlib import Path
from typing import IO, TYPE_CHECKING, Any

from crashstudy.errors import InputError, Problem
from crashstudy.metrics.record import NOTE_TEXT
from crashstudy.results import integrity
from crashstudy.results.integrity import FINAL, MANIFEST, PARTIAL
from crashstudy.results.tables import PARQUET, SUMMARY, decode_texts, summary_frame
from crashstudy.results.zarr_file import DIMS, ZARR_FINAL, ZarrFile
from crashstudy.safefs import PlantedEntryError, open_regular

if TYPE_CHECKING:  # imported where used: a run reads and writes without xarray
    import pandas as pd
    import xarray as xr

__all__ = ["Results", "open_results"]
NOT_THE_RUNS = "it is not the file that run wrote (changed or copied in since)"
READ_BLOCK = 65_536  # rows of the summary table a block-wise reader holds at once (a few MiB per column)
SUMMARY_ROWS_MAX = 4_000_000  # rows :attr:`Results.summary` reads whole (~250 B a row in pandas: ~1 GiB)


class Results:
    """A finished result folder, for notebooks: ``.dataset`` (xarray) and ``.summary`` (pandas)."""

    def __init__(self, directory: str | os.PathLike[str]) -> None:
        self.dir = Path(directory)
        self.final = integrity.final_name(self.dir)  # results.zarr or results.nc
        final = self.dir / self.final
        try:
            os.lstat(final)  # a path too long or a loop of links raises here, named as such by the CLI
        except FileNotFoundError:
            raise FileNotFoundError(
                f"no {FINAL} in {self.dir} (an unfinished run leaves only {PARTIAL})"
            ) from None
        problem, self.manifest = integrity.check_folder(self.dir, self.final, (PARQUET, SUMMARY))
        if problem:
            raise InputError([Problem(str(self.dir), None, "", problem)])
        self.path = final
        self._ds: xr.Dataset | None = None
        self._raw: xr.Dataset | None = None
        self._pinned: dict[str, tuple[IO[bytes], tuple[int, ...]]] = {}  # hashed files, held open (_vouched)
        weakref.finalize(
            self, _close_pinned, self._pinned
        )  # closed with the object if close() is never called
        self.summary_limit: int | None = SUMMARY_ROWS_MAX  #: rows :attr:`summary` reads whole (None: any)

    def open_file(self, name: str) -> IO[bytes]:
        """The folder's file ``name``, open and checked against the manifest (size; SHA-256 where it
        records one), positioned at its start. Refused (:class:`InputError`) when it does not match."""
        try:
            fh = open_regular(self.dir / name, what=name)
        except PlantedEntryError as exc:
            raise InputError(
                [Problem(str(self.dir), None, "", f"{integrity.INCONSISTENT} ({exc})")]
            ) from None
        if self.manifest is None:
            return fh
        entry = self.manifest.get(name)
        size = os.fstat(fh.fileno()).st_size
        why = ""
        if not isinstance(entry, dict):
            why = f"{name} is not listed in {MANIFEST}: the run that wrote {FINAL} did not write it"
        elif entry.get("size") != size:
            why = f"{name} has {size} bytes, {MANIFEST} records {entry.get('size')}: {NOT_THE_RUNS}"
        elif "sha256" in entry and not self._vouched(name, fh, entry["sha256"]):
            why = f"the SHA-256 of {name} is not the one {MANIFEST} records: {NOT_THE_RUNS}"
        if why:
            fh.close()
            raise InputError([Problem(str(self.dir), None, "", f"{integrity.INCONSISTENT} ({why})")])
        fh.seek(0)
        return fh

    def _vouched(self, name: str, fh: IO[bytes], sha256: str) -> bool:
        """Whether the open file ``fh`` has the SHA-256 ``sha256``, hashed once per Results object: the first
        handle whose hash matches stays open (its inode cannot be reused while it is) and its identity is
        kept; a later handle with the same device, inode, size, mtime and ctime is that same file, unchanged
        (an edit in place moves ctime, which no user can set back; a file renamed over it has another
        inode). Anything else is hashed again. A file that changes while it is hashed is refused."""
        stamp = _identity(fh)
        pinned = self._pinned.get(name)
        if pinned is not None and pinned[1] == stamp:
            return True
        if integrity.sha256_of(fh) != sha256 or _identity(fh) != stamp:
            return False
        if pinned is not None:
            pinned[0].close()
        self._pinned[name] = (os.fdopen(os.dup(fh.fileno()), "rb"), stamp)
        return True

    @property
    def dataset(self) -> xr.Dataset:
        """The results as an xarray Dataset (lazily loaded; study axes are coordinates along ``variant``).
        Beyond :attr:`summary_limit` variants nothing is read on opening: the text variables are decoded
        where indexed, and ``variant`` is a dimension without an index (its position is its number)."""
        import xarray as xr

        if self._ds is None:
            ds = self.raw_dataset
            big = self.summary_limit is not None and ds.sizes.get("variant", 0) > self.summary_limit
            if not big:
                ds.close()
                if self.final == FINAL:
                    ds = xr.open_dataset(self.path)
                else:  # Zarr: lazily, without dask (one array region read per access)
                    ds = _open_zarr(self.path)
            axes = json.loads(ds.attrs.get("crashstudy_axes", "[]"))
            self._raw = ds
            self._ds = decode_texts(ds, lazy=big).set_coords([a for a in axes if a in ds])
        return self._ds

    @property
    def raw_dataset(self) -> xr.Dataset:
        """The results as stored (texts as indices into their tables), lazily loaded and without an
        index of the variant numbers: what reads a few variables of a large result in bounded memory."""
        if self.final == FINAL:
            open_regular(self.path, what=FINAL).close()
        return open_raw(self.path)

    @property
    def raw_unindexed(self) -> xr.Dataset:
        """:attr:`raw_dataset` without the indexes of its small dimension coordinates (spring, node, ...):
        for reading attributes and whole variables, not for ``.sel`` by label (:func:`open_raw`)."""
        if self.final == FINAL:
            open_regular(self.path, what=FINAL).close()
        return open_raw(self.path, indexes=False)

    @contextlib.contextmanager
    def stored(self) -> Iterator[Any]:
        """The store as written, read through the netCDF4 API (a ``netCDF4.Dataset``, or a
        :class:`~crashstudy.results.zarr_file.ZarrFile`), without xarray: attributes and whole variables
        for the checks after a run (xarray's import and opening were ~0.15 s of every run)."""
        if self.final == FINAL:
            import netCDF4

            open_regular(self.path, what=FINAL).close()
            nc: Any = netCDF4.Dataset(self.path, "r")
        else:
            nc = ZarrFile(self.path, "r")
        try:
            yield nc
        finally:
            nc.close()

    def column_peak(self, column: str) -> tuple[float, int] | None:
        """(largest value, its variant) of a summary column, read batch by batch; None when the column
        has no value (all NaN) or no such column exists."""
        if self.summary_source != PARQUET:
            s = self.summary
            if column not in s or not s[column].notna().any():
                return None
            k = s[column].idxmax()
            return float(s.loc[k, column]), int(s.loc[k, "variant"])
        import numpy as np

        best: tuple[float, int] | None = None
        with self.open_file(PARQUET) as fh:
            f = _parquet(fh)
            if column not in f.schema_arrow.names:
                return None
            for b in f.iter_batches(columns=["variant", column]):
                vals = b.column(1).to_numpy(zero_copy_only=False)
                if np.isfinite(vals).any():
                    k = int(np.nanargmax(vals))
                    if best is None or vals[k] > best[0]:
                        best = (float(vals[k]), int(b.column(0)[k].as_py()))
        return best

    @property
    def summary_source(self) -> str:
        """The file :attr:`summary` reads: summary.parquet, summary.csv, or results.nc."""
        return next((n for n in (PARQUET, SUMMARY) if os.path.lexists(self.dir / n)), self.final)

    def summary_columns(self, columns: list[str]) -> pd.DataFrame:
        """Only ``columns`` of :attr:`summary` (read without the others where the file allows: a
        10^6-variant summary.parquet is ~250 MiB in memory, two of its columns 16 MiB)."""
        import pandas as pd

        if self.summary_source == PARQUET:
            with self.open_file(PARQUET) as fh:
                return pd.read_parquet(fh, columns=columns)
        return self.summary[columns]

    def count_failed(self) -> int:
        """Variants whose status is not ok, counted block by block (:meth:`summary_batches`: bounded memory
        for any size)."""
        return sum(int((b["status"] != "ok").sum()) for b in self.summary_batches(["status"]))

    def summary_names(self) -> list[str]:
        """The column names of :attr:`summary` (from the Parquet schema, without reading its rows)."""
        if self.summary_source != PARQUET:
            return list(self.summary.columns)

        with self.open_file(PARQUET) as fh:
            return list(_parquet(fh).schema_arrow.names)

    def summary_rows(self) -> int:
        """The number of rows of :attr:`summary` (from the Parquet footer, without reading its rows)."""
        if self.summary_source != PARQUET:
            return len(self.summary)

        with self.open_file(PARQUET) as fh:
            return int(_parquet(fh).metadata.num_rows)

    def summary_batches(
        self, columns: list[str] | None = None, rows: int | None = None
    ) -> Generator[pd.DataFrame, None, None]:
        """:attr:`summary` (only ``columns``, in their order; default all) in blocks of at most ``rows``
        rows (default :data:`READ_BLOCK`), in variant order: what reads a summary of any size in memory
        bounded by the block (a Parquet row group at a time; text columns come as categoricals or strings
        per block; the index numbers the rows of the whole table). A ``summary.csv`` or a dataset-only folder is read whole first (older folders)."""
        import pandas as pd

        rows = rows or READ_BLOCK
        if self.summary_source == PARQUET:
            with self.open_file(PARQUET) as fh:
                lo = 0
                for b in _parquet(fh).iter_batches(batch_size=rows, columns=columns):
                    df = b.to_pandas()
                    df.index = pd.RangeIndex(lo, lo + len(df))  # the row numbers of the whole table
                    lo += len(df)
                    yield df
            return
        df = self.summary if columns is None else self.summary[columns]
        for lo in range(0, len(df), rows):
            yield df.iloc[lo : lo + rows]

    def summary_row(self, variant: int, columns: list[str] | None = None) -> pd.DataFrame:
        """The rows of :attr:`summary` whose ``variant`` is ``variant`` (0 or 1 of them), read through
        the Parquet row-group statistics (the row groups that cannot hold it are skipped)."""
        import pandas as pd

        if self.summary_source != PARQUET:
            df = self.summary if columns is None else self.summary[columns]
            return df[df["variant"] == variant].reset_index(drop=True)

        with self.open_file(PARQUET) as fh:
            f = _parquet(fh)
            parts = []
            for g in range(f.num_row_groups):
                st = f.metadata.row_group(g).column(f.schema_arrow.get_field_index("variant")).statistics
                if st is not None and st.has_min_max and not st.min <= variant <= st.max:
                    continue
                t = f.read_row_group(g, columns=columns).to_pandas()
                parts.append(t[t["variant"] == variant])
        return (
            pd.concat(parts, ignore_index=True)
            if parts
            else pd.DataFrame(columns=columns or f.schema_arrow.names)
        )

    @property
    def summary(self) -> pd.DataFrame:
        """One row per variant: the axis values as columns, then status and summary metrics (from
        ``summary.parquet``, else ``summary.csv``, else the dataset), whole in memory: up to
        :attr:`summary_limit` rows (default :data:`SUMMARY_ROWS_MAX`); a larger summary is refused with
        an error naming the readers that work in bounded memory (:meth:`summary_batches`,
        :meth:`summary_columns`); set ``summary_limit = None`` to read it whole anyway."""
        import pandas as pd

        source = self.summary_source
        if source == PARQUET:
            rows = self.summary_rows()
            if self.summary_limit is not None and rows > self.summary_limit:
                raise InputError(
                    [Problem(str(self.dir / PARQUET), None, "", too_large(rows, self.summary_limit))]
                )
            with self.open_file(PARQUET) as fh:
                return pd.read_parquet(fh)
        if source == SUMMARY:
            with self.open_file(SUMMARY) as fh:
                df = pd.read_csv(
                    fh, dtype={"status": str, "failure_reason": str, "dt_control": str, NOTE_TEXT: str}
                )
            for name in ("failure_reason", NOTE_TEXT):
                if name in df:
                    df[name] = df[name].fillna("")
            return df
        _ = self.dataset  # opens the raw file
        assert self._raw is not None
        return summary_frame(self._raw)

    def close(self) -> None:
        _close_pinned(self._pinned)
        if self._ds is not None:
            self._ds.close()
            if self._raw is not None:
                self._raw.close()
            self._ds = self._raw = None

    def __repr__(self) -> str:
        return f"Results({str(self.dir)!r})"


def too_large(rows: int, limit: int) -> str:
    """Why :attr:`Results.summary` refuses a summary of ``rows`` rows, and what reads it instead."""
    return (
        f"the summary has {rows} rows, more than the {limit} that Results.summary reads whole into one "
        f"pandas DataFrame (~250 bytes a row): read it in bounded memory with "
        f".summary_batches(columns, rows) (blocks in variant order), .summary_columns([...]) (only the "
        f"columns you need), .summary_row(variant) or .column_peak(column); or set "
        f".summary_limit = None to read it whole anyway"
    )


def _close_pinned(pinned: dict[str, tuple[IO[bytes], tuple[int, ...]]]) -> None:
    for fh, _ in pinned.values():
        fh.close()
    pinned.clear()


def _identity(fh: IO[bytes]) -> tuple[int, ...]:
    """What tells one file's unchanged contents from another's: device, inode, size, mtime, ctime (ns)."""
    st = os.fstat(fh.fileno())
    return (st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns, st.st_ctime_ns)


def _parquet(fh: IO[bytes]) -> Any:
    """``summary.parquet`` for reading row group by row group: without pyarrow's ``pre_buffer`` (on by
    default, it reads every selected row group ahead: 8192 rows, 256 a group, held 1.1 MB, 2048 rows 0.3)."""
    import pyarrow.parquet as pq

    return pq.ParquetFile(fh, pre_buffer=False)


def open_raw(path: Path, indexes: bool = True) -> xr.Dataset:
    """A result store (netCDF file or Zarr folder) as xarray reads it, lazily, texts as stored, without
    the variant coordinate (its index would hold every variant number in memory). ``indexes=False``: no
    index of the other dimension coordinates either (no ``.sel`` by spring or node label); making those
    indexes imports dask when it is installed (xarray asks whether they are dask arrays): 0.3 CPU s."""
    import xarray as xr

    if path.name.startswith(ZARR_FINAL):
        return _open_zarr(path, drop_variables=["variant"], create_default_indexes=indexes)
    return xr.open_dataset(path, drop_variables=["variant"], create_default_indexes=indexes)


def _open_zarr(path: Path, **kw: Any) -> xr.Dataset:
    """A Zarr store as xarray reads it, lazily without dask; the writer's own bookkeeping attribute
    dropped (so that it shows what ``results.nc`` shows)."""
    import warnings

    import xarray as xr

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # zarr: 'S1' (CF character arrays) has no v3 specification yet
        ds = xr.open_dataset(path, engine="zarr", chunks=None, consolidated=False, **kw)
    ds.attrs.pop(DIMS, None)
    return ds


def open_results(directory: str | os.PathLike[str]) -> Results:
    """Open a result folder written by ``crashstudy run`` or ``crashstudy simulate`` (see the module
    docstring for what is checked)."""
    return Results(directory)
