"""Regression check of a result folder against a baseline (``crashstudy compare``, docs/regression.md).

Variants are matched by their parameter values (the study axes named in ``crashstudy_axes``),
never by position: a baseline may list its variants in another order or hold another set.

What is compared
----------------
* Every numeric summary column except the bookkeeping in :data:`NOT_COMPARED` (``variant`` and
  the solver's ``dt`` and ``dt_crit``: how the run was integrated, not what it found; a change of
  time step shows up in the metrics it affects) and the axis columns (they are the match key).
  ``t_end`` *is* compared: a run that now stops at another time behaved differently. A column of
  :data:`NOT_COMPARED` is compared after all when the ``regression:`` block names it.
* ``status``: a variant that was ``ok`` in the baseline and ``failed`` now is a failure; the
  reverse is reported as fixed, not as a failure.
* Variants: one in the baseline but not in the new result is a failure (the new run lost it); one
  only in the new result is reported, not a failure. A metric column of the baseline missing from
  the new result is a failure; a new column is reported.

A metric value passes when ``|new - old| <= atol + rtol * |old|`` (NaN against NaN is equal, NaN
against a number is not). Per-metric tolerances come from the *new* result's study file, its
``regression:`` block (stored verbatim in the ``study_yaml`` attribute): a key is a metric name
(``peak_force``, for all its items) or a full column (``peak_force.cabin``, which wins over the
metric name); a key gives ``rtol`` and ``atol``, each 0 when left out. Every other column uses
the defaults, ``rtol=1e-6`` and ``atol=0``: the kernel is deterministic, so an unchanged code and
model reproduce a result to round-off (1e-12 and below, e.g. across CPUs or compiler versions),
while a change of the model or the physics moves the metrics by far more than 1e-6. ``atol`` is 0
because the columns carry different units (N, m, J, 1): no single absolute tolerance fits them all.
One exception, :data:`ATOL_FLOOR`: ``energy_error`` (dimensionless) gets at least ``atol=1e-9``,
since its value in a conservative model is round-off that any reordering of sums changes by 100 %.
"""

from __future__ import annotations

import os
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pandas as pd
from pydantic import TypeAdapter

from crashstudy.analysis.compare_inputs import (  # noqa: F401 - re-exported
    _XML_BAD,
    ATOL_FLOOR,
    DEFAULT_ATOL,
    DEFAULT_RTOL,
    JUNIT_LIST,
    JUNIT_SUITE,
    NOT_COMPARED,
    TEXT_COLUMNS,
    ResultsLike,
    _axis_frame,
    _check_keys,
    _damage,
    _keys,
    _metric_columns,
    _round_key,
    _Side,
    _tolerance_for,
    _xml_text,
    check_tolerance,
    load_results,
    study_tolerances,
)
from crashstudy.analysis.compare_match import merged
from crashstudy.analysis.compare_stream import streamed_if_large
from crashstudy.analysis.compare_values import ColumnStats, _Column, top_rows
from crashstudy.analysis.factors import factors
from crashstudy.schema.study import Tolerance


@dataclass
class Comparison:
    """Result of :func:`compare`.

    Attributes
    ----------
    new_dir, baseline_dir : Path
        The two result folders.
    axes : list[str]
        Study axes the variants were matched on (union of both sides).
    matched : pandas.DataFrame
        One row per matched variant: the axis values, ``variant`` (new) and ``baseline_variant``.
    missing : pandas.DataFrame
        Baseline variants absent from the new result (axis values, ``baseline_variant``): failures.
    extra : pandas.DataFrame
        New variants absent from the baseline (axis values, ``variant``): reported, not failures.
    status : pandas.DataFrame
        Matched variants whose ``status`` changed: axis values, ``variant``, ``old``, ``new``,
        ``failure_reason`` (new) and ``passed`` (False for ``ok`` -> ``failed``); the first
        :data:`~crashstudy.analysis.compare_values.STATUS_KEPT` of a streamed comparison
        (``n_status`` counts them all).
    stats : dict[str, ColumnStats]
        Per compared metric column: counts, largest differences and the rows that moved most (what
        the report, the verdict and the JUnit XML are made of).
    columns : dict[str, _Column]
        Per compared metric column, the aligned per-variant arrays: only when the tables were read
        whole (empty for a streamed comparison, like ``matched``; see docs/scale.md).
    missing_columns, extra_columns : list[str]
        Metric columns only in the baseline (failures) or only in the new result (reported).
    notes : list[str]
        Anything else worth reading (axes that differ, different crashstudy versions).
    """

    new_dir: Path
    baseline_dir: Path
    axes: list[str]
    matched: pd.DataFrame
    missing: pd.DataFrame
    extra: pd.DataFrame
    status: pd.DataFrame
    columns: dict[str, _Column]
    missing_columns: list[str]
    extra_columns: list[str]
    stats: dict[str, ColumnStats] = field(default_factory=dict)
    n_matched: int = 0
    n_status: int = 0  #: status changes (all; ``status`` lists at most STATUS_KEPT of a streamed comparison)
    n_status_failures: int = 0  #: ... of which ok -> failed
    n_missing: int = (
        0  #: baseline variants missing (``missing`` lists at most STATUS_KEPT of a streamed comparison)
    )
    n_extra: int = 0  #: new variants not in the baseline (``extra``: idem)
    streamed: bool = (
        False  #: read block by block: no per-variant arrays (``frame``, ``columns``, ``matched``)
    )
    notes: list[str] = field(default_factory=list)
    damaged: list[str] = field(
        default_factory=list
    )  #: a side whose summary lost (or repeats) variants: failures
    rtol: float = DEFAULT_RTOL
    atol: float = DEFAULT_ATOL
    study_name: str = ""
    factors: dict[str, list[str]] = field(default_factory=dict)  #: first path -> its zip group (one factor)
    _frame: pd.DataFrame | None = field(default=None, repr=False)

    @property
    def frame(self) -> pd.DataFrame:
        """Tidy table, one row per (matched variant, metric column).

        Columns: the axis values, ``variant``, ``baseline_variant``, ``metric``, ``old``, ``new``,
        ``diff`` (new - old), ``abs_diff``, ``rel_diff`` (diff / |old|, signed; inf when old is 0),
        ``rtol``, ``atol``, ``tolerance`` (atol + rtol |old|), ``score`` (abs_diff / tolerance) and
        ``passed``. Built on first use (a study of 10^6 variants makes a large table).
        """
        if self.streamed:
            raise ValueError(
                "this comparison was read block by block (a large result in the same variant order "
                "as its baseline): it keeps no per-variant table; see docs/scale.md"
            )
        if self._frame is None:
            parts = []
            for name, c in self.columns.items():
                part = self.matched.copy()
                part["metric"] = name
                part["old"], part["new"], part["diff"], part["abs_diff"] = c.old, c.new, c.diff, c.abs_diff
                part["rel_diff"], part["rtol"], part["atol"] = c.rel_diff, c.rtol, c.atol
                part["tolerance"], part["score"], part["passed"] = c.tolerance, c.score, c.passed
                parts.append(part)
            self._frame = pd.concat(parts, ignore_index=True) if parts else pd.DataFrame()
        return self._frame

    @property
    def failed_values(self) -> int:
        """Metric values (variant x column) that moved past their tolerance."""
        return sum(c.failed for c in self.stats.values())

    @property
    def status_failures(self) -> int:
        """Variants that went from ``ok`` to ``failed``."""
        return self.n_status_failures

    @property
    def failed(self) -> int:
        """Number of findings that fail the check: metric values past tolerance, variants missing
        from the new result, ``ok`` -> ``failed`` status changes and metric columns gone missing."""
        return (
            self.failed_values
            + self.n_missing
            + self.status_failures
            + len(self.missing_columns)
            + len(self.damaged)
        )

    def failing_columns(self) -> dict[str, int]:
        """Metric column -> number of its values past tolerance (only columns with any)."""
        return {n: c.failed for n, c in self.stats.items() if c.failed}

    def by_metric(self) -> pd.DataFrame:
        """One row per compared metric column: ``metric``, ``failed`` (values past tolerance),
        ``compared``, ``max_rel_diff`` (largest |rel diff|), ``rtol``, ``atol``, ``worst_score``;
        the worst first."""
        rows = [
            {
                "metric": n,
                "failed": c.failed,
                "compared": c.compared,
                "max_rel_diff": c.max_rel_diff,
                "rtol": c.rtol,
                "atol": c.atol,
                "worst_score": c.worst_score,
            }
            for n, c in self.stats.items()
        ]
        df = pd.DataFrame(
            rows, columns=["metric", "failed", "compared", "max_rel_diff", "rtol", "atol", "worst_score"]
        )
        return df.sort_values(["failed", "worst_score"], ascending=False, kind="stable").reset_index(
            drop=True
        )

    def top(self, n: int = 20, column: str | None = None, only_failed: bool = False) -> pd.DataFrame:
        """The ``n`` values that moved most relative to their tolerance (largest ``score`` first);
        unchanged values are left out. At most :data:`~crashstudy.analysis.compare_values.KEPT` (100)."""
        return top_rows(self.stats, [*self.axes, "variant", "baseline_variant"], n, column, only_failed)

    def table(self, n: int = 20) -> str:
        """Text table of the ``n`` values that moved most (by |new - old| / tolerance)."""
        top = self.top(n)
        if top.empty:
            return "no metric value changed"
        text = pd.DataFrame(
            {
                "variant": top["variant"].astype(str),
                "parameters": [self._params(r) for _, r in top.iterrows()],
                "metric": top["metric"],
                "old": [f"{v:.7g}" for v in top["old"]],
                "new": [f"{v:.7g}" for v in top["new"]],
                "rel diff": [f"{v:+.3e}" for v in top["rel_diff"]],
                "tolerance": [f"{v:.3g}" for v in top["tolerance"]],
                "diff/tol": [f"{v:.3g}" for v in top["score"]],
                "": ["ok" if p else "FAIL" for p in top["passed"]],
            }
        )
        head = f"what moved most (|new - old| / tolerance, largest first; {len(top)} shown):"
        return head + "\n" + text.to_string(index=False)

    def _params(self, row: pd.Series) -> str:
        """``axis=value`` per factor: a zip group by its first path (its other paths move with it)."""
        groups = self.factors or {a: [a] for a in self.axes}
        return (
            " ".join(
                f"{ax}={row[ax]:.6g}" + (f" (+{len(m) - 1} zipped)" if len(m) > 1 else "")
                for ax, m in groups.items()
                if ax in row and pd.notna(row[ax])
            )
            or "-"
        )

    def verdict(self) -> str:
        """One line: FAILED or OK, with what failed."""
        n_cols = len(self.stats)
        if not self.failed:
            extra = f"; {self.n_extra} new variants not in the baseline" if self.n_extra else ""
            return f"OK: {self.n_matched} variants x {n_cols} metrics within tolerance of the baseline{extra}"
        parts = list(self.damaged)
        if self.failed_values:
            parts.append(
                f"{self.failed_values} values in {len(self.failing_columns())} of {n_cols} metrics "
                f"moved past tolerance"
            )
        if self.status_failures:
            parts.append(f"{self.status_failures} variants went from ok to failed")
        if self.n_missing:
            parts.append(f"{self.n_missing} baseline variants missing from the new result")
        if self.missing_columns:
            parts.append(f"metric columns missing from the new result: {', '.join(self.missing_columns)}")
        return f"FAILED: {'; '.join(parts)} ({self.n_matched} variants matched)"

    def report(self, n: int = 20) -> str:
        """Everything ``crashstudy compare`` prints."""
        lines = [
            f"comparing {self.new_dir} against baseline {self.baseline_dir}",
            *("note: " + s for s in self.notes),
            self.table(n),
        ]
        for title, df, col, count in (
            (
                "baseline variants missing from the new result",
                self.missing,
                "baseline_variant",
                self.n_missing,
            ),
            ("new variants not in the baseline (not a failure)", self.extra, "variant", self.n_extra),
        ):
            if count:
                lines.append(f"{title} ({count}):")
                lines += [f"  variant {int(r[col])}: {self._params(r)}" for _, r in df.head(n).iterrows()]
                if count > n:
                    lines.append(f"  ... and {count - n} more")
        if self.n_status:
            lines.append(f"status changes ({self.n_status}):")
            for _, r in self.status.head(n).iterrows():
                why = f" ({r['failure_reason']})" if r["failure_reason"] else ""
                lines.append(
                    f"  variant {int(r['variant'])} {self._params(r)}: {r['old']} -> {r['new']}{why}"
                )
        if self.extra_columns:
            lines.append(f"new metric columns, not compared: {', '.join(self.extra_columns)}")
        bad = self.by_metric().query("failed > 0")
        if len(bad):
            lines.append("metrics past tolerance:")
            lines += [self._past_tolerance(r) for r in bad.itertuples()]
        lines.append(self.verdict())
        return "\n".join(lines)

    def _past_tolerance(self, r: Any) -> str:
        """The summary line of one failing metric: how many values failed, and by how much (a value
        that is a number on one side and NaN on the other has no relative difference: counted apart)."""
        c = self.stats[r.metric]
        parts = [f"largest |rel diff| {c.failed_rel_max:.3e}"] if c.failed_rel_max is not None else []
        if c.failed_nan:
            parts.append(f"{c.failed_nan} a number on one side and NaN on the other")
        return f"  {r.metric}: {r.failed} of {r.compared} variants, {'; '.join(parts)} (rtol={r.rtol:g}, atol={r.atol:g})"

    def to_junit(self, path: str | os.PathLike[str] | None = None) -> ET.ElementTree:
        """JUnit XML of this comparison (:func:`crashstudy.analysis.compare_junit.junit`), written to ``path``
        when given."""
        from crashstudy.analysis.compare_junit import junit

        return junit(self, path)


def compare(
    new: ResultsLike,
    baseline: ResultsLike,
    rtol: float | None = None,
    atol: float | None = None,
    tolerances: dict[str, dict[str, float]] | None = None,
) -> Comparison:
    """Compare a result with its baseline, variant by variant (matched by parameter values).

    Parameters
    ----------
    new, baseline : Results or path
        The result under test and the reference (folders written by ``crashstudy run``).
    rtol, atol : float, optional
        Tolerance of every metric the per-metric tolerances do not name; defaults
        :data:`DEFAULT_RTOL` (1e-6) and :data:`DEFAULT_ATOL` (0, in each metric's own unit).
    tolerances : dict, optional
        ``{metric or column: {"rtol": r, "atol": a}}``; default: the ``regression:`` block of the
        new result's study file. A full column (``peak_force.cabin``) wins over its metric name.

    Returns
    -------
    Comparison

    Raises
    ------
    InputError
        A folder holds no finished results, or a tolerance key names no metric.
    """
    rtol = DEFAULT_RTOL if rtol is None else check_tolerance("rtol", rtol)
    atol = DEFAULT_ATOL if atol is None else check_tolerance("atol", atol)
    n_side, b_side = _Side.read(new, "new"), _Side.read(baseline, "baseline")
    tol = (
        study_tolerances(n_side.attrs)
        if tolerances is None
        else TypeAdapter(dict[str, Tolerance]).validate_python(tolerances)
    )
    notes = []
    axes = list(dict.fromkeys([*n_side.axes, *b_side.axes]))
    if bool(n_side.axes) != bool(b_side.axes):  # a single model run against a study: nothing can match
        single, study = ("new", "baseline") if not n_side.axes else ("baseline", "new")
        axes_of = b_side.axes if not n_side.axes else n_side.axes
        notes.append(
            f"the {single} result is a single model run (crashstudy simulate: no study axes) and the "
            f"{study} result is a study over {axes_of}: variants are matched by their axis values, "
            "which a single run does not have, so no variant can be matched; compare a simulate "
            "result with a simulate result, or a study with a run of the same study"
        )
    elif set(n_side.axes) != set(b_side.axes):
        notes.append(
            f"the study axes differ (new: {n_side.axes or 'none'}, baseline: {b_side.axes or 'none'}): "
            "variants match only on equal values of every axis"
        )
    vn, vb = n_side.attrs.get("crashstudy_version"), b_side.attrs.get("crashstudy_version")
    if vn != vb:
        notes.append(f"crashstudy versions differ: new {vn}, baseline {vb}")

    named = set(tol)
    n_cols = _metric_columns(n_side.head(), axes, named)
    b_cols = _metric_columns(b_side.head(), axes, named)
    _check_keys(tol, set(n_cols) | set(b_cols), n_side.attrs)
    tol_of = {c: _tolerance_for(c, tol, rtol, atol) for c in n_cols if c in b_cols}  # compared columns
    fields = streamed_if_large(n_side, b_side, axes, tol_of) or _whole(n_side, b_side, axes, tol_of)
    return Comparison(
        new_dir=n_side.dir,
        baseline_dir=b_side.dir,
        axes=axes,
        missing_columns=[c for c in b_cols if c not in n_cols],
        extra_columns=[c for c in n_cols if c not in b_cols],
        notes=notes,
        rtol=rtol,
        atol=atol,
        damaged=[s.damage for s in (n_side, b_side) if s.damage],
        study_name=n_side.study_name,
        factors=factors(n_side.attrs, axes),
        **fields,
    )


def _whole(
    new: _Side, base: _Side, axes: list[str], tolerances: dict[str, tuple[float, float]]
) -> dict[str, Any]:
    """The fields of a comparison of the two summaries read whole, matched by their axis values (an outer
    merge: any order, any subsets)."""
    stats = {c: ColumnStats(*t) for c, t in tolerances.items()}
    got = merged(new.summary, base.summary, axes, tolerances, stats)
    status = got["status"]
    return {
        **got,
        "stats": stats,
        "n_matched": len(got["matched"]),
        "n_status": len(status),
        "n_missing": len(got["missing"]),
        "n_extra": len(got["extra"]),
        "n_status_failures": int((~status["passed"]).sum()) if len(status) else 0,
    }
