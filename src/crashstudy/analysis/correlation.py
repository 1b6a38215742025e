"""Spearman and Pearson correlation of a summary column with each study axis, read block by block
(``crashstudy sensitivity --method correlation``): memory bounded by a block and a bucket, whatever the
number of variants (issue 19).

- **Pearson**: the means and co-moments of each block, merged (Chan, Golub and LeVeque's pairwise update).
- **Spearman** is the Pearson correlation of the average ranks (what ``scipy.stats.spearmanr`` computes).
  An axis of a matrix or zip has few distinct values: its ranks come from its value counts (at most
  :data:`DISTINCT_MAX` values). The metric's ranks need a global order: its values are split by value
  into buckets of about :data:`BUCKET_ROWS` rows (the cut points are quantiles of a strided sample; equal
  values always fall into one bucket), written with each row's axis value codes to temporary files, and
  ranked one bucket at a time (the ranks of the buckets before it are its offset). Only per-axis sums
  over the distinct axis values are kept: sum over the rows of (rank x - mean) (rank y - mean).
- An axis with more distinct values than :data:`DISTINCT_MAX` (a sampled design axis) is ranked with its
  column whole (SciPy), as before: memory grows with the variants for that axis only.

Failed variants (``status`` not ok, or a NaN metric) are left out and counted.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from crashstudy.results.scratch import scratch_folder

Z95 = 1.959963984540054
BUCKET_ROWS = 1 << 20  #: rows of the metric ranked at once (~1 M: ~70 MB with the rank's work arrays)
DISTINCT_MAX = 1 << 20  #: distinct values of an axis ranked from its value counts (else its column whole)
SAMPLE = 1 << 16  #: values of the metric sampled for the bucket cut points

Blocks = Callable[[], Iterator[pd.DataFrame]]  #: a fresh pass over the summary's blocks (read more than once)


@dataclass
class _Moments:
    """Count, means and centred second moments of (x, y), merged block by block (exact to round-off)."""

    n: int = 0
    mx: float = 0.0
    my: float = 0.0
    sxx: float = 0.0
    syy: float = 0.0
    sxy: float = 0.0
    lo: float = math.inf
    hi: float = -math.inf  # range of x: a constant axis has no correlation

    def add(self, x: np.ndarray, y: np.ndarray) -> None:
        nb = len(x)
        if not nb:
            return
        mxb, myb = float(x.mean()), float(y.mean())
        dx, dy = x - mxb, y - myb
        n = self.n + nb
        ex, ey, w = mxb - self.mx, myb - self.my, self.n * nb / n
        self.sxx += float(dx @ dx) + ex * ex * w
        self.syy += float(dy @ dy) + ey * ey * w
        self.sxy += float(dx @ dy) + ex * ey * w
        self.mx += ex * nb / n
        self.my += ey * nb / n
        self.n = n
        self.lo, self.hi = min(self.lo, float(x.min())), max(self.hi, float(x.max()))

    def r(self) -> float:
        den = math.sqrt(self.sxx * self.syy)
        return float(np.clip(self.sxy / den, -1.0, 1.0)) if den > 0 else math.nan


@dataclass
class _Counts:
    """The distinct values of an axis over the rows that ran, and how often each occurs."""

    values: np.ndarray = field(default_factory=lambda: np.empty(0))
    counts: np.ndarray = field(default_factory=lambda: np.empty(0, dtype=np.int64))
    too_many: bool = False

    def add(self, x: np.ndarray) -> None:
        if self.too_many or not len(x):
            return
        v, c = np.unique(x, return_counts=True)
        merged, inv = np.unique(np.concatenate([self.values, v]), return_inverse=True)
        self.counts = np.bincount(
            inv, weights=np.concatenate([self.counts, c]), minlength=len(merged)
        ).astype(np.int64)
        self.values = merged
        if len(merged) > DISTINCT_MAX:
            self.too_many, self.values, self.counts = True, np.empty(0), np.empty(0, dtype=np.int64)

    def centred_ranks(self, mean: float) -> np.ndarray:
        """The average rank of each distinct value (1-based, as scipy.stats.rankdata), minus ``mean``."""
        before = np.cumsum(self.counts) - self.counts
        return before + (self.counts + 1) / 2.0 - mean


def correlation_table(blocks: Blocks, factors: dict[str, str], metric: str) -> pd.DataFrame:
    """Spearman and Pearson correlation of ``metric`` with each factor (``{name: its column}``), with
    the 95% Fisher interval: one row per (factor, index): ``metric, group, axis, index, value,
    confidence, note``."""
    names = list(factors)
    columns = list(factors.values())
    pearson = [_Moments() for _ in names]
    counts = [_Counts() for _ in names]
    y_range, n, dropped = [math.inf, -math.inf], 0, 0
    sample: list[np.ndarray] = []
    stride = 1
    for block in blocks():  # pass 1: Pearson, the axes' value counts, a sample of the metric
        ok, y = _ran(block, metric)
        dropped += int((~ok).sum())
        y = y[ok]
        if not len(y):
            continue
        n += len(y)
        y_range = [min(y_range[0], float(y.min())), max(y_range[1], float(y.max()))]
        for col, mom, cnt in zip(columns, pearson, counts, strict=True):
            x = block[col].to_numpy(dtype=float)[ok]
            mom.add(x, y)
            cnt.add(x)
        sample.append(y[::stride])
        if sum(len(s) for s in sample) > 2 * SAMPLE:  # keep the sample bounded: every other value
            sample, stride = [np.concatenate(sample)[::2]], stride * 2
    varies_y = y_range[1] > y_range[0]
    by_counts = [k for k, c in enumerate(counts) if not c.too_many]
    spearman = [math.nan] * len(names)
    if n > 2 and varies_y and by_counts:
        sums = _rank_sums(
            blocks,
            metric,
            [columns[k] for k in by_counts],
            [counts[k] for k in by_counts],
            n,
            np.concatenate(sample),
        )
        for k, r in zip(by_counts, sums, strict=True):
            spearman[k] = r
    for k, c in enumerate(counts):
        if c.too_many and n > 2 and varies_y:
            spearman[k] = _whole_spearman(blocks, metric, columns[k])
    note = f"{dropped} failed variant(s) left out" if dropped else ""
    rows = []
    for k, name in enumerate(names):
        varies = n > 2 and varies_y and pearson[k].hi > pearson[k].lo
        for index, r in (("spearman", spearman[k]), ("pearson", pearson[k].r())):
            r = float(r) if varies else math.nan
            half = Z95 / np.sqrt(n - 3) if n > 3 else math.nan
            lo, hi = np.tanh(np.arctanh(np.clip(r, -0.999999, 0.999999)) + np.array([-half, half]))
            rows.append(
                {
                    "metric": metric,
                    "group": "",
                    "axis": name,
                    "index": index,
                    "value": r,
                    "confidence": float((hi - lo) / 2),
                    "note": note,
                }
            )
    return pd.DataFrame(rows)


def _ran(block: pd.DataFrame, metric: str) -> tuple[np.ndarray, np.ndarray]:
    """(the rows that ran: status ok and a finite metric, the metric) of a block."""
    y = block[metric].to_numpy(dtype=float)
    return (block["status"].astype(str) == "ok").to_numpy() & np.isfinite(y), y


def _rank_sums(
    blocks: Blocks, metric: str, columns: list[str], counts: list[_Counts], n: int, sample: np.ndarray
) -> list[float]:
    """Spearman's r of the metric with each of ``columns`` (ranked from ``counts``): the metric split by
    value into buckets on disk (pass 2), each bucket ranked in memory (pass 3)."""
    n_buckets = max(1, math.ceil(n / BUCKET_ROWS))
    cuts = np.unique(np.quantile(np.sort(sample), np.arange(1, n_buckets) / n_buckets, method="lower"))
    mean = (n + 1) / 2.0
    with scratch_folder("ranks") as tmp:
        files = [Path(tmp) / f"b{b}" for b in range(len(cuts) + 1)]
        handles = [open(f, "wb") for f in files]  # noqa: SIM115 - closed below, before the buckets are read
        try:
            for block in blocks():
                ok, y = _ran(block, metric)
                y = y[ok]
                codes = [
                    np.searchsorted(c.values, block[col].to_numpy(dtype=float)[ok]).astype(np.int32)
                    for col, c in zip(columns, counts, strict=True)
                ]
                bucket = np.searchsorted(cuts, y, side="right")  # equal values: one bucket
                order = np.argsort(bucket, kind="stable")
                edges = np.searchsorted(bucket[order], np.arange(len(files) + 1))
                for b, fh in enumerate(handles):
                    part = order[edges[b] : edges[b + 1]]
                    if len(part):
                        fh.write(
                            np.column_stack([y[part].view(np.int64), *(c[part] for c in codes)]).tobytes()
                        )
        finally:
            for fh in handles:
                fh.close()
        syy, offset = 0.0, 0
        sums = [np.zeros(len(c.values)) for c in counts]
        for f in files:
            rows = np.fromfile(f, dtype=np.int64).reshape(-1, 1 + len(columns))
            os.unlink(f)
            if not len(rows):
                continue
            ry = _average_ranks(rows[:, 0].view(np.float64)) + (offset - mean)
            offset += len(rows)
            syy += float(ry @ ry)
            for k, s in enumerate(sums):
                s += np.bincount(rows[:, 1 + k], weights=ry, minlength=len(s))
    out = []
    for c, s in zip(counts, sums, strict=True):
        cx = c.centred_ranks(mean)
        den = math.sqrt(float(c.counts @ (cx * cx)) * syy)
        out.append(float(np.clip((cx @ s) / den, -1.0, 1.0)) if den > 0 else math.nan)
    return out


def _average_ranks(y: np.ndarray) -> np.ndarray:
    from scipy.stats import rankdata

    return np.asarray(rankdata(y), dtype=float)


def _whole_spearman(blocks: Blocks, metric: str, column: str) -> float:
    """Spearman's r of an axis with too many distinct values to rank from its counts: its column and the
    metric's whole (memory grows with the variants)."""
    from scipy import stats

    xs, ys = [], []
    for block in blocks():
        ok, y = _ran(block, metric)
        xs.append(block[column].to_numpy(dtype=float)[ok])
        ys.append(y[ok])
    return float(stats.spearmanr(np.concatenate(xs), np.concatenate(ys))[0])
