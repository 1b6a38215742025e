"""The matrix figure: a summary metric over the study axes (a heat map over two, lines over one)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Literal

import numpy as np
import pandas as pd
from matplotlib import colormaps
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from crashstudy.analysis.plot_style import CMAP, axis_label, display_scale, finish, fitting_legend, unit_text
from crashstudy.errors import InputError, Problem

ANNOTATE_MAX = 144  # heat maps with at most this many cells have their values written in
LINES_MAX = 8  # matrix line plot: one line per other-axis combination up to this many, else a band
NOT_METRICS = ("variant", "status", "failure_reason", "dt_control")
Aggregate = Literal["max", "mean", "min"]


def _fail(where: str, message: str) -> InputError:
    return InputError([Problem(where, None, "", message)])


def check_axes(axes: Sequence[str], x: str, y: str | None, where: str = "<summary>") -> None:
    """A matrix plot's ``x`` and ``y`` (None: none) must be two different study axes (the exact heat map
    and the density matrix of a large study check them alike)."""
    for name, value in (("x", x), ("y", y)):
        if value is not None and value not in axes:
            raise _fail(where, f"unknown study axis {value!r} for {name}; valid axes: {', '.join(axes)}")
    if y is not None and y == x:
        raise _fail(where, f"x and y are the same axis {x!r}; choose two different axes")


def _axis_columns(summary: pd.DataFrame) -> list[str]:
    """Study-axis columns of a summary table: those between ``variant`` and ``status``."""
    cols = list(summary.columns)
    if "variant" in cols and "status" in cols:
        return cols[cols.index("variant") + 1 : cols.index("status")]
    return []


def metric_columns(summary: pd.DataFrame, axes: Sequence[str] | None = None) -> list[str]:
    """Numeric summary columns that can be plotted over the matrix."""
    skip = set(NOT_METRICS) | set(axes if axes is not None else _axis_columns(summary))
    return [c for c in summary.columns if c not in skip and pd.api.types.is_numeric_dtype(summary[c])]


def default_metric(
    summary: pd.DataFrame, nodes: Sequence[str] | None = None, prefix: str = "peak_deceleration_g"
) -> str:
    """The ``<prefix>.<item>`` column with the largest values (items restricted to ``nodes`` when given).

    With the default prefix this is the peak deceleration of the free node that decelerates most
    (a fixed node's column is all zeros). Without such columns: the first metric column.
    """
    cols = [c for c in summary.columns if c.startswith(prefix + ".")]
    if nodes is not None:
        cols = [c for c in cols if c.split(".", 1)[1] in set(nodes)] or cols
    if not cols:
        metrics = metric_columns(summary)
        if not metrics:
            raise _fail("<summary>", "the summary has no metric columns")
        return metrics[0]
    peaks = [np.nanmax(summary[c].to_numpy(dtype=float), initial=-np.inf) for c in cols]
    return cols[int(np.argmax(peaks))]


def plot_matrix(
    summary: pd.DataFrame,
    metric: str | None = None,
    x: str | None = None,
    y: str | None = None,
    agg: Aggregate = "max",
    axes: Sequence[str] | None = None,
    units: str | None = None,
    title: str | None = None,
    axis_units: dict[str, str] | None = None,
    factors: dict[str, list[str]] | None = None,
) -> Figure:
    """A summary metric over the study matrix: a line plot over one axis or a heat map over two.

    Parameters
    ----------
    summary : pandas.DataFrame
        ``open_results(dir).summary`` (one row per variant).
    metric : str, optional
        A summary column, e.g. ``"peak_force.cabin"``; default :func:`default_metric` (the command
        line takes ``peak_deceleration_g`` of :func:`crash_node`).
    x : str, optional
        Study axis along the horizontal axis (default the first).
    y : str or None, optional
        Second study axis: a heat map of ``metric`` over ``x`` and ``y``. ``None`` (default): a line
        plot of ``metric`` against ``x``, one line per combination of the other axes (up to
        :data:`LINES_MAX`), else their mean with a min-max band.
    agg : {"max", "mean", "min"}, default ``"max"``
        Heat map only: how variants that share a cell (other axes, zip groups) are combined.
    axes : list of str, optional
        The study axes (default: the columns between ``variant`` and ``status``).
    units : str, optional
        Unit of the metric for the labels (``plot_command`` takes it from the dataset); forces and
        energies are shown with an engineering prefix (N -> kN, MN), the drawn values scaled to it.
    axis_units : dict of str to str, optional
        Unit of each study axis for the labels (``plot_command``: the axis variables' ``units``).
    title : str, optional
        Figure title (default the metric).
    factors : dict of str to list of str, optional
        First path -> paths of each factor (:func:`crashstudy.analysis.factors.factors`: a zip group is
        one factor); default every axis its own. The paths that move with ``x`` or ``y`` are not "other"
        axes, and the others are named once per factor.

    Returns
    -------
    matplotlib.figure.Figure
        Heat map: ``fig.axes[0].images[0].get_array()`` holds the cell values, rows = ``y`` values
        ascending, columns = ``x`` values ascending (``summary.pivot_table(metric, y, x, agg)``).
    """
    axes = list(axes) if axes is not None else _axis_columns(summary)
    if not axes:
        raise _fail(
            "<summary>", "these results have no study axes (a single model run); a matrix plot needs a study"
        )
    metrics = metric_columns(summary, axes)
    metric = metric or default_metric(summary)
    if metric not in metrics:
        raise _fail("<summary>", f"unknown metric {metric!r}; valid metrics: {', '.join(metrics)}")
    x = x or axes[0]
    check_axes(axes, x, y)
    if agg not in ("max", "mean", "min"):
        raise _fail("<summary>", f"unknown agg {agg!r}; valid: max, mean, min")
    ok = (
        summary["status"].astype(str) == "ok" if "status" in summary else pd.Series(True, index=summary.index)
    )
    n_failed = int((~ok).sum())
    df = summary[ok]
    factor, units = display_scale(units or "", df[metric].to_numpy(dtype=float))
    if factor != 1.0:
        df = df.assign(**{metric: df[metric] * factor})
    label = f"{metric}{unit_text(units)}"
    note = f"{n_failed} failed variant{'s' if n_failed > 1 else ''} skipped" if n_failed else ""
    from crashstudy.analysis.factors import factor_name

    groups = factors or {a: [a] for a in axes}
    with_x = next((m for m in groups.values() if x in m), [x])
    if y is not None and y in with_x:
        raise _fail(
            "<summary>",
            f"x {x!r} and y {y!r} move together (one zip group); choose an axis of another factor",
        )
    others = [first for first, m in groups.items() if x not in m and (y is None or y not in m)]
    fnames = {a: factor_name(groups.get(a, [a])) for a in others}
    moved = [
        f"{a} moves with {', '.join(p for p in m if p != a)} (one zip group)"
        for a in (x, y)
        if a is not None
        for m in groups.values()
        if a in m and len(m) > 1
    ]
    if y is None:
        fig = Figure(figsize=(8.0, 5.0), layout="constrained")
        FigureCanvasAgg(fig)
        ax = fig.subplots()
        _matrix_lines(ax, df, metric, x, others, axis_units or {}, fnames)
        handles, names = ax.get_legend_handles_labels()
        if len(handles) > 1:  # below the panel, as in the other figures
            fitting_legend(fig, handles, names, "")
        ax.set_xlabel(axis_label(x, axis_units))
        ax.set_ylabel(label)
        ax.grid(True, alpha=0.3)
    else:
        fig = Figure(figsize=(8.0, 6.0), layout="constrained")
        FigureCanvasAgg(fig)
        ax = fig.subplots()
        table = df.pivot_table(index=y, columns=x, values=metric, aggfunc=agg, dropna=False)
        table = table.reindex(index=np.unique(summary[y]), columns=np.unique(summary[x]))
        _heat_map(fig, ax, table, label)
        ax.set_xlabel(axis_label(x, axis_units))
        ax.set_ylabel(axis_label(y, axis_units))
        if others:
            note = "; ".join(
                filter(None, [f"each cell: {agg} over {', '.join(fnames[a] for a in others)}", note])
            )
    note = "; ".join(filter(None, [*moved, note]))
    finish(fig, title or f"{metric} over the study matrix", note)
    return fig


def _matrix_lines(
    ax, df: pd.DataFrame, metric: str, x: str, others: list[str], units: dict[str, str], names: dict[str, str]
) -> None:
    if not others:
        d = df.sort_values(x)
        ax.plot(d[x].to_numpy(), d[metric].to_numpy(), "o-", label=metric)
        return
    groups = list(df.groupby(others, sort=True))
    if len(groups) <= LINES_MAX:
        cmap = colormaps["tab10"]
        for i, (key, d) in enumerate(groups):
            key = key if isinstance(key, tuple) else (key,)
            d = d.groupby(x)[metric].mean()  # zip groups may repeat an x; one point per x
            name = ", ".join(
                f"{names[a]}={float(v):g}{_plain(units.get(a))}" for a, v in zip(others, key, strict=True)
            )
            ax.plot(d.index.to_numpy(), d.to_numpy(), "o-", color=cmap(i % 10), label=name)
        return
    stats = df.groupby(x)[metric].agg(["mean", "min", "max"])
    xs = stats.index.to_numpy()
    ax.fill_between(
        xs,
        stats["min"].to_numpy(),
        stats["max"].to_numpy(),
        alpha=0.25,
        label=f"min-max over {len(groups)} combinations of {', '.join(names[a] for a in others)}",
    )
    ax.plot(xs, stats["mean"].to_numpy(), "o-", label="mean")


def _plain(unit: str | None) -> str:
    return f" {unit}" if unit and unit != "1" else ""


def _heat_map(fig: Figure, ax, table: pd.DataFrame, label: str) -> None:
    values = table.to_numpy(dtype=float)
    im = ax.imshow(
        np.ma.masked_invalid(values), origin="lower", aspect="auto", cmap=CMAP, interpolation="nearest"
    )
    fig.colorbar(im, ax=ax, label=label)
    ny, nx = values.shape
    for axis, labels, n in ((ax.xaxis, table.columns, nx), (ax.yaxis, table.index, ny)):
        step = max(1, math.ceil(n / 15))
        ticks = np.arange(0, n, step)
        axis.set_ticks(ticks, [f"{float(labels[i]):g}" for i in ticks])
    if values.size <= ANNOTATE_MAX:
        norm = im.norm
        size = "medium" if values.size <= 36 else "small" if values.size <= 80 else "x-small"
        for (i, j), v in np.ndenumerate(values):
            if np.isfinite(v):
                dark = norm(v) < 0.6  # viridis is dark at the low end
                ax.text(
                    j,
                    i,
                    f"{v:.3g}",
                    ha="center",
                    va="center",
                    fontsize=size,
                    color="white" if dark else "black",
                )
            else:
                ax.text(j, i, "failed", ha="center", va="center", fontsize="x-small", color="0.4")
