"""The matrix figure of a large study (more variants than ``--max-points``): the study axes and the metric as
a matrix of panels, each a 2-D histogram of two of them (variants per bin, log colour) and on the
diagonal each one's 1-D histogram, counted block by block from the summary's row groups. The bins are
fixed before the count: from the Parquet statistics (min, max of every row group) where every row group
has them, else from a first pass. Memory: one block of the columns drawn and the counts, whatever the
number of variants (a scatter of 10^8 points would hold ~0.8 GB a column and draw an ink blot)."""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field

import numpy as np
import pandas as pd
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.colors import LogNorm
from matplotlib.figure import Figure

from crashstudy.analysis.plot_style import CMAP, finish

POINTS_MAX = (
    1_000_000  #: variants up to which ``plot --kind matrix`` draws the exact figure (``--max-points``)
)
BINS = 100  #: bins along each column of a density panel


@dataclass
class Density:
    """Counts of the variants that ran (status ok, every column finite): ``counts1[i]`` over ``edges[i]``;
    ``counts2[i, j]`` (``i > j``) over ``edges[j]`` (first index) x ``edges[i]``, as
    ``numpy.histogram2d(column j, column i, bins=[edges[j], edges[i]])`` of the whole columns."""

    names: list[str]
    edges: list[np.ndarray]
    counts1: list[np.ndarray] = field(default_factory=list)
    counts2: dict[tuple[int, int], np.ndarray] = field(default_factory=dict)
    counted: int = 0  #: variants in every histogram
    skipped: int = 0  #: variants left out: failed, or a NaN in a column drawn


def bin_edges(lo: float, hi: float, bins: int = BINS) -> np.ndarray:
    """``bins`` equal bins from ``lo`` to ``hi`` (one value: a bin of width 1 around it)."""
    if not (np.isfinite(lo) and np.isfinite(hi)):
        lo, hi = 0.0, 1.0
    if hi <= lo:
        lo, hi = lo - 0.5, hi + 0.5
    return np.linspace(lo, hi, bins + 1)


def statistics_ranges(parquet: object, names: Sequence[str]) -> dict[str, tuple[float, float]] | None:
    """(min, max) of each column from the row-group statistics of a ``pyarrow.parquet.ParquetFile``; None
    when a row group lacks them (or they are not finite) for one of the columns."""
    meta = parquet.metadata  # type: ignore[attr-defined]
    schema = parquet.schema_arrow  # type: ignore[attr-defined]
    out: dict[str, tuple[float, float]] = {}
    for name in names:
        k = schema.get_field_index(name)
        lo, hi = np.inf, -np.inf
        for g in range(meta.num_row_groups):
            st = meta.row_group(g).column(k).statistics
            if meta.row_group(g).num_rows == 0:
                continue
            if st is None or not st.has_min_max:
                return None
            try:
                lo, hi = min(lo, float(st.min)), max(hi, float(st.max))
            except (TypeError, ValueError):
                return None
        if not (np.isfinite(lo) and np.isfinite(hi)):
            return None
        out[name] = (lo, hi)
    return out


def _ran(block: pd.DataFrame, names: Sequence[str]) -> tuple[np.ndarray, list[np.ndarray]]:
    """(the rows counted: status ok and every column finite, the columns as float arrays)."""
    values = [block[n].to_numpy(dtype=float) for n in names]
    ok = np.ones(len(block), dtype=bool)
    if "status" in block:
        ok &= (block["status"].astype(str) == "ok").to_numpy()
    for v in values:
        ok &= np.isfinite(v)
    return ok, values


def scan_ranges(blocks: Iterable[pd.DataFrame], names: Sequence[str]) -> dict[str, tuple[float, float]]:
    """(min, max) of each column over the rows counted (the first pass, when statistics are missing)."""
    lo = dict.fromkeys(names, np.inf)
    hi = dict.fromkeys(names, -np.inf)
    for block in blocks:
        ok, values = _ran(block, names)
        if ok.any():
            for n, v in zip(names, values, strict=True):
                lo[n], hi[n] = min(lo[n], float(v[ok].min())), max(hi[n], float(v[ok].max()))
    return {n: (lo[n], hi[n]) for n in names}


def count(
    blocks: Iterable[pd.DataFrame],
    names: Sequence[str],
    ranges: dict[str, tuple[float, float]],
    bins: int = BINS,
) -> Density:
    """The histograms of ``names`` (a pair for each two of them, one for each) counted block by block."""
    edges = [bin_edges(*ranges[n], bins) for n in names]
    d = Density(list(names), edges, [np.zeros(bins, dtype=np.int64) for _ in names])
    n = len(names)
    d.counts2 = {(i, j): np.zeros((bins, bins), dtype=np.int64) for i in range(n) for j in range(i)}
    for block in blocks:
        ok, values = _ran(block, names)
        v = [a[ok] for a in values]
        d.counted += int(ok.sum())
        d.skipped += int((~ok).sum())
        for i in range(n):
            d.counts1[i] += np.histogram(v[i], edges[i])[0].astype(np.int64)
            for j in range(i):
                d.counts2[i, j] += np.histogram2d(v[j], v[i], bins=[edges[j], edges[i]])[0].astype(np.int64)
    return d


def plot_density(
    d: Density,
    labels: Sequence[str],
    title: str,
    rows: int,
    limit: int,
    scales: Sequence[float] | None = None,
) -> Figure:
    """The matrix of panels of ``d``: row ``i``, column ``j`` (``i > j``) the variants per bin of column ``j``
    (across) and column ``i`` (up) on one log colour scale, the diagonal each column's histogram; ``labels``
    name the columns (with their units), ``scales`` multiply their values for display (kN for N ...).
    ``rows``: variants in the summary; ``limit``: the ``--max-points`` they exceed."""
    n = len(d.names)
    scales = list(scales) if scales is not None else [1.0] * n
    edges = [e * s for e, s in zip(d.edges, scales, strict=True)]
    fig = Figure(figsize=(2.2 + 2.6 * n, 1.6 + 2.5 * n), layout="constrained")
    FigureCanvasAgg(fig)
    grid = fig.subplots(n, n, squeeze=False)
    top = max([int(c.max()) for c in d.counts2.values()] + [1])
    norm = LogNorm(vmin=1, vmax=max(top, 10))
    mesh = None
    for i in range(n):
        for j in range(n):
            ax = grid[i, j]
            if j > i:
                ax.set_visible(False)
                continue
            if i == j:
                ax.stairs(d.counts1[i], edges[i], fill=True, alpha=0.6)
                ax.set_ylabel("variants per bin" if i == 0 else "")
                ax.ticklabel_format(axis="y", style="sci", scilimits=(-3, 4))
            else:
                c = np.ma.masked_equal(d.counts2[i, j].T, 0)  # rows: column i, across: column j
                mesh = ax.pcolormesh(edges[j], edges[i], c, norm=norm, cmap=CMAP)
                if j == 0:
                    ax.set_ylabel(labels[i])
            if i == n - 1:
                ax.set_xlabel(labels[j])
    if mesh is not None:
        fig.colorbar(mesh, ax=list(grid.ravel()), shrink=0.6, label="variants per bin")  # right of all panels
    bins = len(d.counts1[0]) if d.counts1 else 0
    note = (
        f"2-D density, not a scatter: {d.counted:,} variants in {bins} x {bins} bins per panel (log colour), "
        f"each column's histogram on the diagonal; the summary has {rows:,} rows, more than --max-points "
        f"{limit:,} drawn one by one"
    )
    if d.skipped:
        note += f"; {d.skipped:,} failed variant{'s' if d.skipped > 1 else ''} (or NaN values) skipped"
    finish(fig, f"{title} (density of {d.counted:,} variants)", note)
    return fig
