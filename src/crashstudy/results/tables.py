"""Summary tables: one row per variant (:func:`summary_frame`), written as ``summary.parquet`` and
``summary.csv`` (:func:`write_summary`), and the texts stored as indices decoded (:func:`decode_texts`).

Texts that repeat across variants are stored compactly in ``results.nc`` (docs/format.md, "Results"): ``status``
is a CF flag variable (``STATUS_MEANINGS``); ``failure_reason`` and ``dt_control`` are indices into a
table of their distinct texts (``TEXT_TABLES``). See :mod:`crashstudy.results.store` for the file itself.
"""

from __future__ import annotations

import json
import os
from contextlib import nullcontext
from pathlib import Path
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np

from crashstudy.metrics.record import METRIC_META, NOTE_LONG, NOTE_TEXT, asked_nodes
from crashstudy.safefs import clear_entry, open_new
from crashstudy.units import UNIT_SYSTEMS
from crashstudy.vocabulary.summary import SUMMARY_META

if TYPE_CHECKING:  # imported where used: a run writes its summary with pyarrow, without xarray
    import pandas as pd
    import xarray as xr

SUMMARY = "summary.csv"
PARQUET = "summary.parquet"
CSV_MAX = 100_000  # variants up to which summary.csv is written by default
SUMMARY_BLOCK = 200_000  # rows of the summary tables made and written at once (a Parquet row group each)
STATUS_MEANINGS = ("ok", "failed")  # flag_meanings of ``status`` (value = index)
TEXT_LEN = 1024  # longest stored message (a text table holds each distinct text once)
TEXT_TABLES = {
    "failure_reason": "why a variant failed (empty if ok)",
    "dt_control": "node (and its stiffest spring) that controls the critical step",
}
HISTORY_META = {  # name: (unit kind, long name)
    "position": ("length", "node position"),
    "displacement": ("length", "node displacement from the initial position"),
    "velocity": ("velocity", "node velocity"),
    "acceleration": ("acceleration", "node acceleration (forces / mass; prescribed dofs: kinematic)"),
    "spring_force": ("force", "spring force (positive = tension)"),
    "spring_elongation": ("length", "spring elongation (negative = compression)"),
    "kinetic_energy": ("energy", "kinetic energy"),
    "internal_energy": (
        "energy",
        "work done on all springs and dampers, plus the energy they stored at t = 0",
    ),
    "external_work": ("energy", "work of loads, gravity and prescribed motion"),
    "wall_energy": (
        "energy",
        "kinetic energy removed by rigid walls, plus the energy stored in penalty walls",
    ),
    "wall_force": ("force", "rigid wall contact force (reaction to the forces pushing held nodes into it)"),
    "filtered_acceleration": ("g", "resultant acceleration of a metric node, SAE J211 filtered (its cfc)"),
}


def text_tables(topo: Any) -> dict[str, str]:
    """The text tables of a result file: ``TEXT_TABLES``, and ``criteria_note`` with metrics."""
    return {**TEXT_TABLES, NOTE_TEXT: NOTE_LONG} if topo.metrics else dict(TEXT_TABLES)


class Coded(NamedTuple):
    """A text column as codes into its table of distinct texts (-1: no text): a pandas ``Categorical``
    in :func:`summary_frame`, an Arrow dictionary column in the written tables (:func:`arrow_table`)."""

    codes: np.ndarray
    texts: list[str]


def _categorical(ds: xr.Dataset, sub: xr.Dataset, name: str) -> Any:
    """``sub[name]`` as texts: :class:`Coded` when stored as codes, plain strings for files of 0.1."""
    arr = sub[name].values
    if arr.dtype.kind in "iuf":  # codes (xarray turns the -1 fill of an unwritten variant into NaN)
        cats = _table(ds, name)
        codes = code_indices(arr, len(cats))
        if len(set(cats)) < len(cats):  # a table never repeats a text; guard a hand-edited file
            return np.asarray(cats, dtype=object)[np.clip(codes, 0, None)]
        return Coded(codes, cats)
    return arr.astype(str)


def _code_type(n: int) -> Any:
    """The integer type of the codes of a table of ``n`` texts: the smallest pandas' ``Categorical``
    takes (so that a table written from either is the same file)."""
    return (
        next(t for t in (np.int8, np.int16, np.int32) if n < np.iinfo(t).max) if n < 2**31 - 1 else np.int64
    )


def frame_columns(cols: dict[str, Any]) -> dict[str, Any]:
    """:func:`summary_columns` with each :class:`Coded` column as a pandas ``Categorical``."""
    import pandas as pd

    return {
        k: pd.Categorical.from_codes(v.codes, categories=v.texts) if isinstance(v, Coded) else v
        for k, v in cols.items()
    }


def arrow_table(cols: dict[str, Any]) -> Any:
    """:func:`summary_columns` as a pyarrow Table, each :class:`Coded` column a dictionary column (the
    types pyarrow gives a pandas ``Categorical``: the same Parquet and CSV bytes)."""
    import pyarrow as pa

    out = {}
    for k, v in cols.items():
        if isinstance(v, Coded):
            idx = pa.array(v.codes.astype(_code_type(len(v.texts))), mask=v.codes < 0)
            v = pa.DictionaryArray.from_arrays(idx, pa.array(v.texts, type=pa.string()))
        out[k] = v
    return pa.table(out)


def _table(ds: xr.Dataset, name: str) -> list[str]:
    """The texts the codes of variable ``name`` index."""
    if name == "status":
        return list(STATUS_MEANINGS)
    raw = ds[f"{name}_text"].values
    return [str(t) for t in raw] if len(raw) else [""]


def code_indices(arr: np.ndarray, n: int) -> np.ndarray:
    """Stored codes as int64 indices into a table of ``n`` texts; -1 where none (unwritten, out of range)."""
    arr = np.where(np.isfinite(arr), arr, -1).astype(np.int64)
    return np.where((arr >= 0) & (arr < n), arr, -1)


def decode_texts(ds: xr.Dataset, lazy: bool = False) -> xr.Dataset:
    """``ds`` with ``status``, ``failure_reason`` and ``dt_control`` as texts (the tables dropped);
    ``lazy``: decoded only where indexed (nothing read now)."""
    from crashstudy.results.lazy_texts import lazy_texts

    out = ds
    for name in ("status", *TEXT_TABLES, NOTE_TEXT):
        if name in ds and ds[name].dtype.kind in "iuf":
            texts: Any
            if lazy:  # decoded where indexed: a 10^8-variant result decoded whole would be GBs of texts
                texts = lazy_texts(ds[name].variable, _table(ds, name), code_indices)
            else:
                texts = _decoded(_categorical(ds, ds, name))
            long = ds[name].attrs.get("long_name", "").split(": index into")[0]
            out = out.assign({name: (ds[name].dims, texts, {"units": "", "long_name": long})})
    return out.drop_vars([f"{n}_text" for n in (*TEXT_TABLES, NOTE_TEXT) if f"{n}_text" in out])


def _decoded(col: Any) -> np.ndarray:
    """A text column as strings ('nan' where no text, as a decoded ``Categorical``)."""
    if isinstance(col, Coded):
        return np.asarray([*col.texts, "nan"], dtype=str)[col.codes]  # -1: the last entry
    return np.asarray(col, dtype=str)


def summary_frame(ds: xr.Dataset, lo: int = 0, hi: int | None = None) -> pd.DataFrame:
    """Tidy summary table, one row per variant: axis values, status, then one column per metric and item."""
    import pandas as pd

    return pd.DataFrame(frame_columns(summary_columns(ds, lo, hi)))


def summary_columns(ds: xr.Dataset, lo: int = 0, hi: int | None = None) -> dict[str, Any]:
    """The columns of :func:`summary_frame`, in order (arrays; the texts as :class:`Coded`)."""
    sub = ds.isel(variant=slice(lo, hi))
    axes = json.loads(ds.attrs.get("crashstudy_axes", "[]"))
    # opened without the variant coordinate (its index would hold 8 bytes per variant): its numbers
    variant = sub["variant"].values if "variant" in ds.variables else np.arange(lo, lo + sub.sizes["variant"])
    cols: dict[str, Any] = {"variant": variant}
    for ax in axes:
        cols[ax] = sub[ax].values
    for name in ("status", "failure_reason"):
        cols[name] = _categorical(ds, sub, name)
    dims_of = {**{n: d for n, (d, _, _) in SUMMARY_META.items()}, **{n: ("node",) for n in METRIC_META}}
    for name, dims in dims_of.items():
        if name not in sub:
            continue
        arr = sub[name].values
        if not dims:
            cols[name] = arr
        else:
            ids = sub[dims[0]].values.astype(str)
            # a criterion: only the nodes that ask for it; past_curve_end: the springs with a drawn curve
            asked = ds[name].attrs.get("nodes" if name in METRIC_META else "springs", " ".join(ids)).split()
            for k, item in enumerate(ids):
                if item in asked:  # no columns of NaN
                    cols[f"{name}.{item}"] = arr[:, k]
    cols["dt_control"] = _categorical(ds, sub, "dt_control")
    if NOTE_TEXT in sub:
        cols[NOTE_TEXT] = _categorical(ds, sub, NOTE_TEXT)
    return cols


def write_summary(
    ds: xr.Dataset, folder: Path, csv: bool, chunk: int | None = None, rename: bool = True
) -> dict[str, Path]:
    """Write ``summary.parquet`` and, when ``csv``, ``summary.csv`` chunk by chunk (bounded memory),
    each through a temporary file and a rename; without ``csv`` an older ``summary.csv`` is removed.
    Both through pyarrow (its CSV writer is ~10x pandas' ``to_csv``; every float round-trips).
    ``rename=False``: leave them under their temporary names and return {final name: temporary path}
    (the caller renames them and removes an older ``summary.csv``)."""
    import pyarrow.csv as pcsv
    import pyarrow.parquet as pq

    n = ds.sizes["variant"]
    chunk = chunk or SUMMARY_BLOCK
    tmp_pq, tmp_csv = folder / (PARQUET + ".partial"), folder / (SUMMARY + ".partial")
    writers: list[Any] = []
    try:
        with open_new(tmp_pq, mode="wb") as raw, open_new(tmp_csv, mode="wb") if csv else nullcontext() as fh:
            for lo in range(0, max(n, 1), chunk):
                # straight from the arrays: a DataFrame in between copied every column once more
                table = arrow_table(summary_columns(ds, lo, min(n, lo + chunk)))
                if not writers:
                    # dictionary pages for the texts only: trying them on every float column doubled the time
                    texts = [n for n in ("status", *TEXT_TABLES, NOTE_TEXT) if n in table.column_names]
                    writers.append(pq.ParquetWriter(raw, table.schema, use_dictionary=texts))
                    if csv:
                        writers.append(pcsv.CSVWriter(fh, table.schema))
                for w in writers:
                    w.write_table(table)
            while writers:
                writers.pop(0).close()
    finally:  # a failed write (disk full) must not leave a writer that complains when collected
        for w in writers:
            if hasattr(w, "is_open"):
                w.is_open = False
    tables = {PARQUET: tmp_pq, **({SUMMARY: tmp_csv} if csv else {})}
    if not rename:
        return tables
    for name, tmp in tables.items():
        os.replace(tmp, folder / name)
    if not csv:
        clear_entry(folder / SUMMARY)
    return tables


def summary_arrays(plan: Any, res: Any) -> dict[str, np.ndarray]:
    """The summary variables of a chunk (a :class:`crashstudy.results.chunk_result.ChunkResult` of ``plan``), (variants[, items]) each, NaN where a variant failed (but its
    ``dt``, ``dt_crit``): what :class:`crashstudy.results.store.ResultWriter` stores and :func:`chunk_frame` tabulates."""
    o = res.out
    g = UNIT_SYSTEMS[plan.topology.units].g
    summary = {
        "peak_force": o.peak_force.T,
        "max_crush": o.max_crush.T,
        "max_elongation": o.max_elongation.T,
        "failure_time": o.spring_fail_time.T,
        "absorbed_energy": o.absorbed_energy.T,
        "peak_deceleration": o.peak_acceleration.T,
        "peak_deceleration_g": o.peak_acceleration.T / g,
        "energy_error": o.energy_error,
        "dt": res.dt,
        "dt_crit": res.dt_crit,
        "t_end": o.t_end,
        "final_kinetic_energy": o.final_energy[0],
        "final_internal_energy": o.final_energy[1],
        "error_estimate": res.error_estimate,
        "past_curve_end": res.curve_end.T if res.curve_end is not None else np.zeros_like(o.peak_force.T),
    }
    if plan.topology.wall_ids:
        summary["peak_wall_force"] = o.peak_wall_force.T
        summary["wall_impulse"] = o.wall_impulse.T
    failed = o.status != 0
    out = {}
    for name, arr in summary.items():
        a = np.array(arr, dtype=np.float64)
        if name not in ("dt", "dt_crit"):
            a[failed] = np.nan  # a failed variant has no trustworthy summary
        out[name] = a
    return out


def metric_arrays(plan: Any, res: Any) -> dict[str, np.ndarray]:
    """The crash criteria of a chunk, (variants, nodes) each, NaN where a variant failed."""
    failed = res.out.status != 0
    out = {}
    for name, arr in res.criteria.values.items():
        a = np.array(arr, dtype=np.float64)
        a[failed] = np.nan
        out[name] = a
    return out


def chunk_frame(plan: Any, res: Any) -> pd.DataFrame:
    """The summary table of a computed chunk, without writing files: the columns of ``summary.parquet``
    (optimisation and calibration evaluate candidates this way)."""
    topo = plan.topology
    dims = {"spring": topo.spring_ids, "node": topo.node_ids, "wall": topo.wall_ids}
    data: dict[str, Any] = {
        name: (("variant", *SUMMARY_META[name][0]), a) for name, a in summary_arrays(plan, res).items()
    }
    data["status"] = ("variant", np.where(res.out.status != 0, "failed", "ok"))
    data["failure_reason"] = ("variant", np.asarray(res.reasons, dtype=str))
    data["dt_control"] = ("variant", np.asarray(res.dt_control, dtype=str))
    if res.criteria is not None:
        data.update(
            {
                name: (("variant", "node"), a, {"nodes": " ".join(asked_nodes(topo, name))})
                for name, a in metric_arrays(plan, res).items()
            }
        )
        data[NOTE_TEXT] = (
            "variant",
            np.where(res.out.status != 0, "", np.asarray(res.criteria.notes, dtype=str)),
        )
    lo, hi = int(res.index[0]), int(res.index[-1]) + 1
    for path, values in plan.axis_values(lo, hi).items():
        data[path] = ("variant", values)
    import xarray as xr

    ds = xr.Dataset(
        data,
        coords={"variant": res.index, **{d: list(ids) for d, ids in dims.items() if ids}},
        attrs={"crashstudy_axes": json.dumps([a.path for a in plan.axes])},
    )
    return summary_frame(ds)


def stored_table(nc: Any, name: str) -> list[str]:
    """The distinct texts of ``name`` stored in ``nc`` (empty for files without a table)."""
    return _char_rows(nc, f"{name}_text")


def stored_ids(nc: Any, dim: str) -> list[str]:
    """The ids along dimension ``dim`` (spring, node, wall) of an open result store (netCDF4 API)."""
    return _char_rows(nc, dim)


def _char_rows(nc: Any, name: str) -> list[str]:
    """Each row of the (n, width) 'S1' character variable ``name`` of ``nc`` as a text (UTF-8, the NULs
    that pad it dropped); empty when ``nc`` has no such variable or it has no row."""
    if name not in nc.variables:
        return []
    raw = nc.variables[name]
    raw.set_auto_chartostring(False)
    raw.set_auto_mask(False)
    chars = np.asarray(raw[:])
    if chars.ndim < 2 or not chars.shape[0]:
        return []
    return [bytes(r).rstrip(b"\0").decode("utf-8", "replace") for r in chars.view(f"S{chars.shape[1]}")[:, 0]]


def read_texts(nc: Any, name: str, lo: int, hi: int) -> np.ndarray:
    """Texts of ``status``, ``failure_reason`` or ``dt_control`` of variants ``lo`` .. ``hi - 1`` from an
    open netCDF file, in either storage (index + table, flags, or the character arrays of 0.1)."""
    import netCDF4

    v = nc.variables[name]
    if v.dtype == np.dtype("S1") or v.dtype is str:  # crashstudy 0.1: fixed-width characters
        return np.asarray(netCDF4.chartostring(np.asarray(v[lo:hi])), dtype=object)
    codes = np.asarray(v[lo:hi]).astype(np.int64)
    table = np.array(
        list(STATUS_MEANINGS) if name == "status" else stored_table(nc, name) or [""], dtype=object
    )
    return np.where(codes >= 0, table[np.clip(codes, 0, len(table) - 1)], "")


def chars(texts: list[str], width: int) -> np.ndarray:
    """Strings as a (len, width) 'S1' character array, UTF-8, cut to ``width`` bytes."""
    import netCDF4

    raw = np.array([t.encode("utf-8")[:width] for t in texts], dtype=f"S{width}")
    return netCDF4.stringtochar(raw) if len(texts) else np.zeros((0, width), dtype="S1")
