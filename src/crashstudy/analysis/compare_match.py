"""How ``crashstudy compare`` pairs the variants of two summary tables by their axis values (an outer merge
on the rounded values and the occurrence number, :func:`merged`), and the same for tables too large to
merge in memory (:func:`partitioned`): both are split by a hash of their keys into part files in a
temporary folder, so that equal keys land in the same part, and each part is merged as a whole table is.
Rows keep their order inside a part, so the occurrence numbers, the rows kept for the report and the
order of everything listed are those of the whole-table merge."""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from crashstudy.analysis.compare_inputs import _axis_frame, _keys, _round_key
from crashstudy.analysis.compare_values import STATUS_KEPT, ColumnStats, _Column, empty_lists, status_rows
from crashstudy.results.scratch import scratch_folder

if TYPE_CHECKING:
    from crashstudy.analysis.compare_inputs import _Side

PART_ROWS = 1 << 18  #: rows of a side in one part (on average): its merge holds ~700 B a row at once


def merged(
    N: pd.DataFrame,
    B: pd.DataFrame,
    axes: list[str],
    tolerances: dict[str, tuple[float, float]],
    stats: dict[str, ColumnStats],
    keep: bool = True,
) -> dict[str, Any]:
    """Match the rows of ``N`` (new) and ``B`` (baseline) by their axis values, add the matched values to
    ``stats``: matched, missing, extra, status (in the new rows' order, the missing in the baseline's) and
    the per-variant columns (only if ``keep``: ~2.4 kB a row). A ``_row`` column, where present, numbers the
    rows of the whole table."""
    kn, kb = _keys(N, axes), _keys(B, axes)
    on = [c for c in kn.columns if c != "_row"]
    m = kn.merge(kb, on=on, how="outer", suffixes=("_new", "_base"), indicator=True)
    both = m[m["_merge"] == "both"].sort_values("_row_new")
    rn, rb = both["_row_new"].to_numpy(dtype=int), both["_row_base"].to_numpy(dtype=int)
    only_b = np.sort(m.loc[m["_merge"] == "right_only", "_row_base"].to_numpy(dtype=int))
    only_n = np.sort(m.loc[m["_merge"] == "left_only", "_row_new"].to_numpy(dtype=int))

    matched = _axis_frame(N, rn, axes)
    for ax in axes:  # an axis only the baseline has: its values
        if ax not in N:
            matched[ax] = B[ax].to_numpy()[rb]
    matched["variant"] = N["variant"].to_numpy()[rn].astype(int)
    matched["baseline_variant"] = B["variant"].to_numpy()[rb].astype(int)
    missing = _axis_frame(B, only_b, axes).assign(
        baseline_variant=B["variant"].to_numpy()[only_b].astype(int)
    )
    extra = _axis_frame(N, only_n, axes).assign(variant=N["variant"].to_numpy()[only_n].astype(int))
    reason = N["failure_reason"].fillna("").astype(str).to_numpy()[rn]
    old_st, new_st = B["status"].astype(str).to_numpy()[rb], N["status"].astype(str).to_numpy()[rn]
    status = status_rows(matched, old_st, new_st, reason)
    pos = N["_row"].to_numpy()[rn] if "_row" in N else np.arange(len(rn))  # the order of the whole merge
    columns = {}
    for c, (r, a) in tolerances.items():
        old = pd.to_numeric(B[c], errors="coerce").to_numpy(dtype=np.float64)[rb]
        nw = pd.to_numeric(N[c], errors="coerce").to_numpy(dtype=np.float64)[rn]
        column = _Column(old, nw, r, a)
        stats[c].add(column, matched, pos)
        if keep:
            columns[c] = column
    if "_row" in N:  # where each listed row comes in the whole table's order
        status["_row"], missing["_row"] = pos[old_st != new_st], B["_row"].to_numpy()[only_b]
        extra["_row"] = N["_row"].to_numpy()[only_n]
    return {"matched": matched, "missing": missing, "extra": extra, "status": status, "columns": columns}


def partitioned(
    new: _Side, base: _Side, axes: list[str], tolerances: dict[str, tuple[float, float]]
) -> dict[str, Any]:
    """The fields of a comparison of two summaries too large to merge in memory: split by a hash of their
    keys into parts of about :data:`PART_ROWS` rows (Parquet files in a scratch folder of ``TMPDIR``, :mod:`crashstudy.results.scratch`), each
    part merged by :func:`merged`. Kept: the aggregates per column, the counts, and the first
    :data:`STATUS_KEPT` status changes, missing and new variants."""
    n_parts = max(1, math.ceil(max(new.rows, base.rows) / PART_ROWS))
    stats = {c: ColumnStats(*t) for c, t in tolerances.items()}
    kept: dict[str, pd.DataFrame] = {}  # the first STATUS_KEPT status changes, missing and new variants
    counts = {"status": 0, "missing": 0, "extra": 0, "matched": 0, "failures": 0}
    with scratch_folder("compare") as tmp:
        sides = {}
        for side, texts in ((new, ["status", "failure_reason"]), (base, ["status"])):
            cols = list(dict.fromkeys([*(a for a in axes if a in side.axes), "variant", *texts, *tolerances]))
            sides[side.role] = (cols, _split(side, cols, texts, axes, n_parts, Path(tmp)))
        for p in range(n_parts):
            N, B = (_read(Path(tmp) / f"{role}-{p}.bin", *sides[role]) for role in (new.role, base.role))
            got = merged(N, B, axes, tolerances, stats, keep=False)
            counts["matched"] += len(got["matched"])
            counts["failures"] += int((~got["status"]["passed"]).sum()) if len(got["status"]) else 0
            for key in ("status", "missing", "extra"):
                counts[key] += len(got[key])
                both = pd.concat([kept[key], got[key]], ignore_index=True) if key in kept else got[key]
                kept[key] = both.sort_values("_row", kind="stable").head(STATUS_KEPT)
    lists = {key: df.drop(columns="_row").reset_index(drop=True) for key, df in kept.items()}
    return {
        **empty_lists(axes),
        **lists,
        "stats": stats,
        "n_matched": counts["matched"],
        "n_status": counts["status"],
        "n_status_failures": counts["failures"],
        "n_missing": counts["missing"],
        "n_extra": counts["extra"],
    }


def _split(
    side: _Side, cols: list[str], texts: list[str], axes: list[str], n_parts: int, folder: Path
) -> dict[str, dict[str, int]]:
    """Write the rows of ``side`` into the part files ``{role}-{part}.bin`` of ``folder``, each in the table's
    row order: one float64 per column (a text as its code in the returned tables), then the row number."""
    tables: dict[str, dict[str, int]] = {t: {} for t in texts}
    for block in side.res.summary_batches(cols):
        rows = np.empty((len(block), len(cols) + 1))
        for j, c in enumerate(cols):
            if c in tables:
                values, inverse = np.unique(
                    block[c].astype(object).fillna("").astype(str).to_numpy(), return_inverse=True
                )
                rows[:, j] = np.array([tables[c].setdefault(v, len(tables[c])) for v in values])[inverse]
            else:
                rows[:, j] = pd.to_numeric(block[c], errors="coerce").to_numpy(dtype=np.float64)
        rows[:, -1] = block.index.to_numpy()
        part = _part_of(block, axes, n_parts)
        order = np.argsort(part, kind="stable")
        edges = np.searchsorted(part[order], np.arange(n_parts + 1))
        for p in np.flatnonzero(np.diff(edges)).tolist():  # appended: no file held open (hundreds of parts)
            with open(folder / f"{side.role}-{p}.bin", "ab") as fh:
                fh.write(rows[order[edges[p] : edges[p + 1]]].tobytes())
    return tables


def _read(path: Path, cols: list[str], tables: dict[str, dict[str, int]]) -> pd.DataFrame:
    """A part file as a table (no rows when the side has none in that part)."""
    rows = np.fromfile(path).reshape(-1, len(cols) + 1) if path.exists() else np.empty((0, len(cols) + 1))
    out = pd.DataFrame({c: rows[:, j] for j, c in enumerate(cols)})
    for c, table in tables.items():
        out[c] = np.array(list(table) or [""], dtype=object)[rows[:, cols.index(c)].astype(np.int64)]
    out["_row"] = rows[:, -1].astype(np.int64)
    return out


def _part_of(block: pd.DataFrame, axes: list[str], n_parts: int) -> np.ndarray:
    """The part of each row: a hash of its rounded axis values (-0.0 as 0.0, one NaN), the same for equal keys."""
    keys = pd.DataFrame(
        {
            f"_k{i}": _round_key(block[ax]) if ax in block else np.full(len(block), np.nan)
            for i, ax in enumerate(axes)
        }
    )
    keys = keys.apply(lambda k: np.where(np.isnan(k), np.nan, k + 0.0)) if axes else keys
    if not axes:
        return np.zeros(len(block), dtype=np.int64)
    return (pd.util.hash_pandas_object(keys, index=False).to_numpy() % np.uint64(n_parts)).astype(np.int64)
