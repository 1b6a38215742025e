"""What ``crashstudy compare`` finds in one metric column: the pass/fail law of a value (:class:`_Column`,
over aligned old/new arrays) and what is kept of a column for the report (:class:`ColumnStats`: counts,
largest differences, the rows that moved most). A comparison adds its matched variants to a
``ColumnStats`` block by block (all of them at once when the tables are read whole), so that what it
prints does not depend on how the tables were read, and its memory not on the number of variants."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

KEPT = 100  #: rows of each column kept for the report (the largest scores): ``top(n)`` for n up to this
STATUS_KEPT = 10_000  #: status changes listed (the first ones); all are counted
SHOWN = (
    "metric",
    "old",
    "new",
    "rel_diff",
    "tolerance",
    "score",
    "passed",
)  #: columns of ``top`` after the row's


@dataclass
class _Column:
    """Aligned old/new values of one metric column over matched variants."""

    old: np.ndarray
    new: np.ndarray
    rtol: float
    atol: float

    def __post_init__(self) -> None:
        old, new = self.old, self.new
        both_nan = np.isnan(old) & np.isnan(new)
        with np.errstate(invalid="ignore", divide="ignore", over="ignore"):  # rtol 1e308 * old -> inf: passes
            self.diff = np.where(both_nan, 0.0, new - old)
            self.abs_diff = np.abs(self.diff)
            self.rel_diff = np.where(self.diff == 0.0, 0.0, self.diff / np.abs(old))
            self.tolerance = self.atol + self.rtol * np.abs(np.where(np.isnan(old), 0.0, old))
            self.passed = both_nan | (self.abs_diff <= self.tolerance)  # False when one side only is NaN
            score = np.where(self.abs_diff == 0.0, 0.0, self.abs_diff / self.tolerance)
        self.score = np.where(np.isnan(score), np.inf, score)  # NaN against a number: worst


@dataclass
class ColumnStats:
    """What the report of one compared column needs, added block by block (exact: counts, maxima and the
    top rows of the blocks merge into those of the whole)."""

    rtol: float
    atol: float
    compared: int = 0
    failed: int = 0
    max_rel_diff: float = 0.0  #: largest |rel diff| (NaN left out)
    worst_score: float = 0.0
    failed_rel_max: float | None = None  #: largest |rel diff| of the failed values that have one
    failed_nan: int = 0  #: failed values that are a number on one side and NaN on the other
    top: pd.DataFrame | None = None  #: the KEPT rows that moved most (score > 0), largest score first
    top_failed: pd.DataFrame | None = None  #: the KEPT failed rows that moved most

    def add(self, c: _Column, rows: pd.DataFrame, start: int | np.ndarray) -> None:
        """Add the values of ``c``: ``rows`` are their matched rows (axis values, ``variant``,
        ``baseline_variant``) and ``start`` the position of the first among all matched rows (or of each:
        what orders equal scores)."""
        failed = ~c.passed
        self.compared += len(c.old)
        self.failed += int(failed.sum())
        self.max_rel_diff = max(self.max_rel_diff, float(np.nanmax(np.abs(c.rel_diff), initial=0.0)))
        self.worst_score = max(self.worst_score, float(c.score.max(initial=0.0)))
        nan = failed & np.isnan(c.rel_diff)
        self.failed_nan += int(nan.sum())
        rel = np.abs(c.rel_diff[failed & ~nan])
        if len(rel):
            self.failed_rel_max = max(self.failed_rel_max or 0.0, float(rel.max()))
        self.top = _keep(self.top, c, rows, start, c.score > 0)
        self.top_failed = _keep(self.top_failed, c, rows, start, failed)


def _keep(
    kept: pd.DataFrame | None, c: _Column, rows: pd.DataFrame, start: int | np.ndarray, mask: np.ndarray
) -> pd.DataFrame | None:
    """``kept`` and the rows of ``mask`` together: the KEPT largest scores (ties: the earlier row first)."""
    idx = np.flatnonzero(mask)
    if len(idx) > KEPT:
        idx = idx[np.argsort(-c.score[idx], kind="stable")[:KEPT]]
    if not len(idx):
        return kept
    part = rows.iloc[idx].reset_index(drop=True)
    part["old"], part["new"], part["rel_diff"] = c.old[idx], c.new[idx], c.rel_diff[idx]
    part["tolerance"], part["score"], part["passed"] = c.tolerance[idx], c.score[idx], c.passed[idx]
    part["_pos"] = start[idx] if isinstance(start, np.ndarray) else start + idx
    both = part if kept is None else pd.concat([kept, part], ignore_index=True)
    both = both.sort_values(["score", "_pos"], ascending=[False, True])
    return both.head(KEPT).reset_index(drop=True)


def top_rows(
    stats: dict[str, ColumnStats], row_columns: list[str], n: int, column: str | None, only_failed: bool
) -> pd.DataFrame:
    """The ``n`` values that moved most relative to their tolerance over the columns of ``stats`` (or only
    ``column``): the row's columns, then :data:`SHOWN`; largest score first, ties in column order."""
    if n > KEPT:
        raise ValueError(f"top(n) keeps at most {KEPT} rows per metric column; got n={n}")
    parts = []
    for name, s in stats.items():
        kept = s.top_failed if only_failed else s.top
        if (column is None or name == column) and kept is not None:
            parts.append(kept.head(n).assign(metric=name))
    cols = [*row_columns, *SHOWN]
    if not parts:
        return pd.DataFrame({c: pd.Series(dtype=object if c == "metric" else float) for c in cols})
    out = pd.concat(parts, ignore_index=True).sort_values("score", ascending=False, kind="stable").head(n)
    return out[cols].reset_index(drop=True)


def status_rows(rows: pd.DataFrame, old: np.ndarray, new: np.ndarray, reason: np.ndarray) -> pd.DataFrame:
    """The matched ``rows`` whose status changed (old -> new, with the new failure reason); ``passed``
    False for ok -> failed."""
    changed = old != new
    out = rows[changed].reset_index(drop=True)
    out["old"], out["new"], out["failure_reason"] = old[changed], new[changed], reason[changed]
    out["passed"] = ~((out["old"] == "ok") & (out["new"] != "ok"))
    return out


def empty_lists(axes: list[str]) -> dict[str, Any]:
    """The per-variant fields of a comparison that keeps none (read block by block): empty, with their columns."""
    empty = pd.DataFrame({ax: pd.Series(dtype=float) for ax in axes})
    matched = empty.assign(variant=pd.Series(dtype=int), baseline_variant=pd.Series(dtype=int))
    none = np.array([], dtype=str)
    return {
        "matched": matched,
        "missing": empty.assign(baseline_variant=pd.Series(dtype=int)),
        "extra": empty.assign(variant=pd.Series(dtype=int)),
        "status": status_rows(matched, none, none, none),
        "columns": {},
        "streamed": True,
    }
