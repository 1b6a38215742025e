"""Sensitivity of a summary column to the study axes, and exceedance probabilities (docs/design.md).

Methods (``crashstudy sensitivity DIR --metric COLUMN --method ...``):

- ``correlation``: Spearman rank and Pearson correlation of the column with each axis, over every
  variant of the study (any design, a matrix too), with 95% confidence intervals from Fisher's z
  transform (``tanh(atanh(r) +- 1.96 / sqrt(n - 3))``).
- ``sobol``: first-order and total Sobol' indices (``S1``, ``ST``) with SALib's bootstrap 95%
  confidence intervals; needs a ``design: {method: saltelli}`` study (SALib's estimator needs that
  sample structure).
- ``morris``: Morris elementary effects (``mu_star``, its confidence interval, ``sigma``); needs a
  ``design: {method: morris}`` study. Effects are per unit of the design's unit coordinate (the
  inverse CDF is applied afterwards), so the axes compare with one another.

With ``matrix``/``zip`` axes beside the design, Sobol' and Morris indices are computed for every
combination of those axes (a ``group`` column names it).

Failed variants (``status`` failed, NaN metric) never bias an index silently: ``correlation`` leaves
them out and says how many; ``sobol`` and ``morris`` need every row of their sample structure, so a
group with a failed variant gets NaN indices and the reason. ``exceedance`` gives the probability
that a column exceeds a limit with its exact (Clopper-Pearson) 95% interval, failed variants left
out and counted, and the probability if every failed variant had exceeded it.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from crashstudy.analysis.correlation import correlation_table
from crashstudy.study.design import salib_problem, unit_rows


def _design(attrs: dict[str, Any]) -> dict[str, Any] | None:
    """The ``design:`` block of the study stored with the results (None without one)."""
    import yaml

    data = yaml.safe_load(str(attrs.get("study_yaml", "")) or "{}") or {}
    design = data.get("design") if isinstance(data, dict) else None
    return design if isinstance(design, dict) else None


def indices(summary: pd.DataFrame, attrs: dict[str, Any], metric: str, method: str) -> pd.DataFrame:
    """One row per (group, axis, index): columns ``metric, group, axis, index, value, confidence, note``."""
    axes = [str(a) for a in json.loads(attrs.get("crashstudy_axes", "[]"))]
    if method == "correlation":
        return correlation_table(lambda: iter([summary]), factor_columns(attrs, axes), metric)
    design = _design(attrs)
    if design is None or design.get("method") != ("saltelli" if method == "sobol" else "morris"):
        need = "saltelli" if method == "sobol" else "morris"
        raise ValueError(
            f"--method {method} needs a study with design: {{method: {need}}} (its estimator needs "
            f"that sample structure); use --method correlation for any study"
        )
    d_axes = list(design["axes"])
    from crashstudy.analysis.factors import factors

    other = list(factors(attrs, [a for a in axes if a not in d_axes]))  # a zip group by its first path
    rows: list[dict[str, Any]] = []
    groups = summary.groupby(other, sort=False) if other else [((), summary)]
    for key, part in groups:
        label = ", ".join(
            f"{a}={v:g}" for a, v in zip(other, key if isinstance(key, tuple) else (key,), strict=True)
        )
        rows += _salib(part.sort_values("variant"), design, d_axes, metric, method, label)
    return pd.DataFrame(rows)


def factor_columns(attrs: dict[str, Any], axes: list[str]) -> dict[str, str]:
    """Factor name -> the summary column of its values: a zip group's paths move together, so it is one
    factor, named by :func:`crashstudy.analysis.factors.factor_name`, with its first path's values."""
    from crashstudy.analysis.factors import factor_name, factors

    return {(factor_name(m) if len(m) > 1 else first): first for first, m in factors(attrs, axes).items()}


def _salib(
    part: pd.DataFrame, design: dict[str, Any], axes: list[str], metric: str, method: str, label: str
) -> list[dict[str, Any]]:
    from SALib.analyze import morris, sobol

    y = part[metric].to_numpy(dtype=float)
    problem = salib_problem(len(axes))
    base = {"metric": metric, "group": label}
    failed = int((~np.isfinite(y) | (part["status"] != "ok").to_numpy()).sum())
    names = ("S1", "ST") if method == "sobol" else ("mu_star", "sigma")
    if failed:
        why = f"{failed} of {len(y)} variants failed: the {method} estimator needs every row (no index)"
        return [
            {**base, "axis": a, "index": i, "value": np.nan, "confidence": np.nan, "note": why}
            for a in axes
            for i in names
        ]
    out = []
    if method == "sobol":
        res = sobol.analyze(problem, y, calc_second_order=True, seed=int(design.get("seed", 0)))
        for k, a in enumerate(axes):
            for i in names:
                out.append(
                    {
                        **base,
                        "axis": a,
                        "index": i,
                        "value": float(res[i][k]),
                        "confidence": float(res[f"{i}_conf"][k]),
                        "note": "",
                    }
                )
        return out
    x = unit_rows("morris", int(design["n"]), int(design.get("seed", 0)), len(axes))
    res = morris.analyze(problem, x, y, num_levels=4, seed=int(design.get("seed", 0)))
    for k, a in enumerate(axes):
        out.append(
            {
                **base,
                "axis": a,
                "index": "mu_star",
                "value": float(res["mu_star"][k]),
                "confidence": float(res["mu_star_conf"][k]),
                "note": "",
            }
        )
        out.append(
            {
                **base,
                "axis": a,
                "index": "sigma",
                "value": float(res["sigma"][k]),
                "confidence": np.nan,
                "note": "",
            }
        )
    return out


@dataclass
class Exceedance:
    """P(column > limit) over the variants that ran, with its exact 95% interval."""

    column: str
    limit: float
    n: int  # variants that ran
    exceed: int  # ... of which above the limit
    failed: int  # variants left out (failed)
    probability: float
    low: float
    high: float
    if_failed_exceed: float  # the probability if every failed variant had exceeded the limit

    def text(self) -> str:
        out = (
            f"P({self.column} > {self.limit:g}) = {self.probability:.4g}  (95% CI {self.low:.4g} .. {self.high:.4g}, "
            f"exact binomial; {self.exceed} of {self.n} variants)"
        )
        if self.failed:
            out += (
                f"\n  {self.failed} failed variant(s) left out; if every one had exceeded the limit: "
                f"{self.if_failed_exceed:.4g}"
            )
        return out


SAMPLED = ("lhs", "sobol", "halton", "random")  # design methods whose rows sample the axes' distributions


def sample_caveat(attrs: dict[str, Any]) -> str:
    """Why the variants of a study are not a random sample of its inputs ("" when they are): a fraction of
    a matrix or of a sensitivity design's structured rows is no probability, and its binomial interval
    no confidence interval."""
    design = _design(attrs)
    method = str((design or {}).get("method", ""))
    axes = [str(a) for a in json.loads(attrs.get("crashstudy_axes", "[]"))]
    fixed = [a for a in axes if a not in list((design or {}).get("axes") or [])]
    if design is None:
        return (
            "this study has no sampled design (matrix/zip axes only): the variants are chosen points, not a "
            "random sample, so the fraction printed is not a probability of anything and its binomial "
            "interval is not a confidence interval; use a design: block (lhs, sobol, halton, random) with "
            "the axes' distributions (docs/design.md)"
        )
    if method not in SAMPLED:
        return (
            f"design method {method} places its rows for a sensitivity estimator, not as a random sample: "
            "the fraction printed is not a probability and its binomial interval not a confidence interval"
        )
    if fixed:
        return (
            f"the design is crossed with matrix/zip axes {fixed}: the fraction pools their chosen values "
            "with equal weight, a probability only if that is how they occur"
        )
    return ""


def exceedance(summary: pd.DataFrame, column: str, limit: float) -> Exceedance:
    return exceedance_of(column, limit, exceed_counts(summary, column, limit))


def exceed_counts(summary: pd.DataFrame, column: str, limit: float) -> np.ndarray:
    """(variants that ran, of which above ``limit``, failed) in a (block of a) summary: sums over blocks."""
    y = summary[column].to_numpy(dtype=float)
    ran = (summary["status"].astype(str) == "ok").to_numpy() & np.isfinite(y)
    return np.array([int(ran.sum()), int((y[ran] > limit).sum()), int((~ran).sum())], dtype=np.int64)


def exceedance_of(column: str, limit: float, counts: np.ndarray) -> Exceedance:
    """The :class:`Exceedance` of the counts of :func:`exceed_counts` (exact: they are integers)."""
    from scipy import stats

    n, k, failed = (int(c) for c in counts)
    if n == 0:
        return Exceedance(column, limit, 0, 0, failed, float("nan"), float("nan"), float("nan"), float("nan"))
    ci = stats.binomtest(k, n).proportion_ci(confidence_level=0.95, method="exact")
    return Exceedance(
        column, limit, n, k, failed, k / n, float(ci.low), float(ci.high), (k + failed) / (n + failed)
    )


def over_time(ds: Any, quantity: str, item: str | None = None) -> Any:
    """Spearman correlation of history ``quantity`` (of spring/node ``item``, default the first; the
    first axis component of a node history) with each study axis, at every history sample: an xarray
    DataArray (axis_path, time). Failed variants are left out (their histories stop early); a sample
    where the history does not vary is NaN."""
    import xarray as xr
    from scipy import stats

    from crashstudy.analysis.factors import factor_name, factors

    groups = factors(dict(ds.attrs), [str(a) for a in json.loads(ds.attrs.get("crashstudy_axes", "[]"))])
    axes = list(groups)  # a zip group once, by its first path's values
    da = ds[quantity]
    for dim in ("spring", "node", "wall"):
        if dim in da.dims:
            ids = [str(v) for v in ds[dim].values]
            if item is not None and item not in ids:
                raise ValueError(f"no {dim} {item!r}; the {dim}s are {ids}")
            da = da.isel({dim: ids.index(item) if item is not None else 0})
            item = item or ids[0]
    if "axis" in da.dims:
        da = da.isel(axis=0)
    ok = np.asarray(ds["status"].values == "ok")
    y = np.asarray(da.values, dtype=float)[ok]  # (variants, time)
    ry = stats.rankdata(y, axis=0)
    out = np.full((len(axes), y.shape[1]), np.nan)
    for k, a in enumerate(axes):
        rx = stats.rankdata(np.asarray(ds[a].values, dtype=float)[ok])
        cx = rx - rx.mean()
        cy = ry - ry.mean(axis=0)
        den = np.sqrt((cx**2).sum() * (cy**2).sum(axis=0))
        with np.errstate(invalid="ignore", divide="ignore"):
            out[k] = np.where(den > 0, (cx[:, None] * cy).sum(axis=0) / den, np.nan)
    return xr.DataArray(
        out,
        dims=("axis_path", "time"),
        coords={"axis_path": [factor_name(groups[a]) for a in axes], "time": ds["time"].values},
        name=f"spearman_{quantity}",
        attrs={
            "units": "1",
            "long_name": (
                f"Spearman correlation of {quantity}"
                + (f" of {item}" if item else "")
                + f" with each study axis ({int(ok.sum())} variants that ran)"
            ),
        },
    )
