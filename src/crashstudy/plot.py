"""Figures of a result folder: time histories, force-crush loops and study-matrix maps.

Three plain functions for notebooks, each returning a :class:`matplotlib.figure.Figure` built
without pyplot (no global state, no GUI backend)::

    plot_history(ds, quantity="spring_force", items=None, max_variants=50)
    plot_force_displacement(ds, springs=None, max_variants=50)
    plot_matrix(summary, metric=None, x=None, y=None)

and :func:`plot_command`, the ``crashstudy plot`` subcommand, which writes them as PNG files.

Conventions shared by the figures:

- Failed variants (``status != "ok"``) are never drawn; a note on the figure counts them.
- At most ``max_variants`` variants are drawn, evenly spaced through the variant numbers; the note says so.
- Few variants (up to :data:`LEGEND_MAX`) get a legend with their axis values; more are coloured by
  the value of the first study axis, with a colour bar.
- Node quantities (``position``, ``displacement``, ``velocity``, ``acceleration``) are drawn signed in
  a 1-D model; in a 2-D model the *magnitude* is drawn (consistent with ``peak_deceleration``, the
  largest acceleration magnitude), unless a component is named: ``quantity="acceleration.y"``.
"""

from __future__ import annotations

import argparse
import json
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Literal

import numpy as np
import pandas as pd
import xarray as xr
from matplotlib import colormaps
from matplotlib.cm import ScalarMappable
from matplotlib.colors import Normalize
from matplotlib.figure import Figure
from matplotlib.layout_engine import ConstrainedLayoutEngine

from crashstudy.errors import InputError, Problem
from crashstudy.safefs import clear_entry

PlotKind = Literal["history", "force-displacement", "matrix"]
Aggregate = Literal["max", "mean", "min"]

ITEMS_PER_FIGURE = 6  # subplots in one PNG written by ``crashstudy plot``
LEGEND_MAX = 10  # up to this many variants: a legend; more: a colour bar keyed to the first axis
ANNOTATE_MAX = 144  # heat maps with at most this many cells have their values written in
LINES_MAX = 8  # matrix line plot: one line per other-axis combination up to this many, else a band
CMAP = "viridis"
NODE_VARS = ("position", "displacement", "velocity", "acceleration")
ITEM_DIM = {"position": "node", "displacement": "node", "velocity": "node", "acceleration": "node",
            "spring_force": "spring", "spring_elongation": "spring", "wall_force": "wall",
            "kinetic_energy": None, "internal_energy": None, "external_work": None, "wall_energy": None}  # fmt: skip
NOT_METRICS = ("variant", "status", "failure_reason", "dt_control")


# ----------------------------------------------------------------------------------------------
# helpers


def _fail(where: str, message: str) -> InputError:
    return InputError([Problem(where, None, "", message)])


def _where(ds: xr.Dataset) -> str:
    """The result folder of ``ds`` (for error messages), or ``<dataset>``."""
    src = ds.encoding.get("source")
    return str(Path(src).parent) if src else "<dataset>"


def study_axes(ds: xr.Dataset) -> list[str]:
    """The study axes (dotted paths) of a result dataset, in the order of the study file."""
    return [a for a in json.loads(ds.attrs.get("crashstudy_axes", "[]")) if a in ds.variables]


def study_name(ds: xr.Dataset) -> str:
    """The study's ``name`` (or the model's, for ``crashstudy simulate`` results)."""
    from crashstudy.yamlio import loads_yaml

    for key in ("study_yaml", "model_yaml"):
        text = ds.attrs.get(key, "")
        if not text:
            continue
        try:
            data = loads_yaml(text, file=key).data
        except InputError:  # a stored file that no longer parses must not stop a plot
            continue
        if isinstance(data, dict) and isinstance(data.get("name"), str):
            return data["name"]
    return str(ds.attrs.get("model_name", "results"))


def free_nodes(ds: xr.Dataset) -> list[str]:
    """Nodes of the model that can move (not fixed in every direction, no prescribed motion)."""
    from crashstudy.yamlio import loads_yaml

    nodes = [str(n) for n in ds["node"].values]
    try:
        model = loads_yaml(ds.attrs.get("model_yaml", ""), file="model_yaml").data
    except InputError:
        return nodes
    if not isinstance(model, dict) or not isinstance(model.get("nodes"), dict):
        return nodes
    dim = ds.sizes.get("axis", 1)
    driven = {str(p.get("node")) for p in model.get("prescribed_motion") or [] if isinstance(p, dict)}

    def is_free(node: str) -> bool:
        spec = model["nodes"].get(node) or {}
        fixed = spec.get("fixed", False) if isinstance(spec, dict) else False
        held = fixed is True or (isinstance(fixed, list) and len(set(fixed)) >= dim)
        return not held and node not in driven

    return [n for n in nodes if is_free(n)] or nodes


def _ok_mask(ds: xr.Dataset) -> np.ndarray:
    return np.asarray(ds["status"].values).astype(str) == "ok"


def select_variants(ds: xr.Dataset, max_variants: int = 50) -> tuple[np.ndarray, str]:
    """Variants to draw: the ``ok`` ones, thinned evenly to at most ``max_variants``.

    Returns
    -------
    index : numpy.ndarray
        Positions along ``variant`` (sorted).
    note : str
        What was left out (failed variants, thinning), ``""`` when nothing was.
    """
    ok = np.nonzero(_ok_mask(ds))[0]
    n_failed = ds.sizes["variant"] - len(ok)
    notes = []
    if n_failed:
        notes.append(f"{n_failed} failed variant{'s' if n_failed > 1 else ''} skipped")
    if max_variants < 1:
        raise _fail(_where(ds), f"max_variants must be at least 1, got {max_variants}")
    if len(ok) > max_variants:
        pick = np.unique(np.round(np.linspace(0, len(ok) - 1, max_variants)).astype(int))
        notes.append(f"showing {len(pick)} of {len(ok)} variants (evenly spaced; --max-variants)")
        ok = ok[pick]
    return ok, "; ".join(notes)


def _label(ds: xr.Dataset, k: int, axes: list[str]) -> str:
    if not axes:
        return f"variant {int(ds['variant'].values[k])}"
    return ", ".join(f"{a}={float(ds[a].values[k]):g}" for a in axes)


class _Colours:
    """Colour of each drawn variant: a legend for a few, a colour bar keyed to the first axis for many."""

    def __init__(self, ds: xr.Dataset, index: np.ndarray) -> None:
        axes = study_axes(ds)
        self.index = index
        self.labels = [_label(ds, int(k), axes) for k in index]
        self.legend = len(index) <= LEGEND_MAX
        if self.legend or not axes:
            cmap = colormaps["tab10"]
            self.colours = [cmap(i % 10) for i in range(len(index))]
            self.mappable = None
            self.legend = True
            return
        values = np.asarray(ds[axes[0]].values, dtype=float)[index]
        norm = Normalize(float(np.nanmin(values)), float(np.nanmax(values)))
        cmap = colormaps[CMAP]
        self.colours = [cmap(norm(v)) for v in values]
        self.mappable = ScalarMappable(norm=norm, cmap=cmap)
        self.mappable.set_array(values)
        self.axis = axes[0]

    def decorate(self, fig: Figure, axs: list) -> None:
        if self.mappable is not None:
            fig.colorbar(self.mappable, ax=axs, label=self.axis, shrink=0.9)
        elif len(self.index) > 1:
            handles, labels = axs[0].get_legend_handles_labels()
            ncol = 1 if len(labels) <= 3 else 2
            fig.legend(
                handles, labels, loc="outside lower center", ncols=ncol, fontsize="small", frameon=False
            )


def _new_figure(n_panels: int, width: float = 8.0, sharex: bool = True) -> tuple[Figure, list]:
    ncols = 1 if n_panels <= 3 else 2
    nrows = math.ceil(n_panels / ncols)
    fig = Figure(figsize=(width if ncols == 1 else width * 1.4, 1.2 + 2.6 * nrows), layout="constrained")
    grid = fig.subplots(nrows, ncols, squeeze=False, sharex=sharex)
    axs = list(grid.ravel())
    for ax in axs[n_panels:]:
        ax.set_visible(False)
    for ax in axs[n_panels - ncols if n_panels > ncols else 0 : n_panels]:
        ax.xaxis.set_tick_params(labelbottom=True)
    return fig, axs[:n_panels]


def _xlabel(axs: list, label: str) -> None:
    """Label the x axis of the bottom subplot of each column."""
    ncols = 1 if len(axs) <= 3 else 2
    for i, ax in enumerate(axs):
        if i + ncols >= len(axs):
            ax.set_xlabel(label)


def _finish(fig: Figure, title: str, note: str) -> None:
    fig.suptitle(title)
    if note:
        engine = fig.get_layout_engine()
        if isinstance(engine, ConstrainedLayoutEngine):  # leave a strip at the bottom for the note
            engine.set(rect=(0, 0.03, 1, 0.97))
        fig.text(0.01, 0.005, note, fontsize="small", color="0.35", ha="left", va="bottom")


def _unit(da: xr.DataArray) -> str:
    u = da.attrs.get("units", "")
    return f" [{u}]" if u else ""


def _need_histories(ds: xr.Dataset, names: Sequence[str]) -> None:
    missing = [n for n in names if n not in ds.data_vars]
    if not missing:
        return
    kept = [n for n in ITEM_DIM if n in ds.data_vars]
    raise _fail(_where(ds), f"these results have no {' or '.join(missing)} histories (kept: "
                f"{', '.join(kept) if kept else 'none; the run used output.histories: none'}); re-run the study "
                "with histories, e.g. `set: {output: {histories: all}}` in the study file and "
                "`crashstudy run STUDY.yaml --force` (the matrix plot needs only the summary)")  # fmt: skip


def _items(ds: xr.Dataset, dim: str, items: Sequence[str] | None, default: Sequence[str]) -> list[str]:
    valid = [str(v) for v in ds[dim].values]
    if items is None:
        return list(default)
    items = list(items)
    unknown = [i for i in items if i not in valid]
    if unknown:
        raise _fail(
            _where(ds), f"unknown {dim} {', '.join(map(repr, unknown))}; valid {dim}s: {', '.join(valid)}"
        )
    if not items:
        raise _fail(_where(ds), f"no {dim}s given; valid {dim}s: {', '.join(valid)}")
    return items


def _parse_quantity(ds: xr.Dataset, quantity: str) -> tuple[str, str | None]:
    """``"acceleration.y"`` -> ("acceleration", "y"); checks that the name is a history variable."""
    name, _, comp = quantity.partition(".")
    if name not in ITEM_DIM:
        raise _fail(_where(ds), f"unknown history quantity {quantity!r}; valid: {', '.join(ITEM_DIM)}"
                    f" (node quantities take a component in 2-D, e.g. acceleration.y)")  # fmt: skip
    if comp:
        axes = [str(a) for a in ds["axis"].values] if "axis" in ds.coords else ["x"]
        if name not in NODE_VARS or comp not in axes:
            raise _fail(
                _where(ds), f"{quantity!r}: only node quantities take a component, one of {', '.join(axes)}"
            )
    return name, comp or None


def history_values(ds: xr.Dataset, quantity: str, item: str | None) -> tuple[np.ndarray, str]:
    """The drawn values of ``quantity`` for ``item``, shape (variant, time), and their axis label.

    Node quantities: signed in 1-D; in 2-D the magnitude, or the component named as ``"acceleration.y"``.
    """
    name, comp = _parse_quantity(ds, quantity)
    _need_histories(ds, [name])
    da = ds[name]
    dim = ITEM_DIM[name]
    if dim is not None:
        da = da.sel({dim: item})
    if name in NODE_VARS:
        if comp is not None:
            return np.asarray(da.sel(axis=comp).values), f"{name} {comp}{_unit(da)}"
        if ds.sizes.get("axis", 1) == 1:
            return np.asarray(da.isel(axis=0).values), f"{name}{_unit(da)}"
        return np.sqrt((np.asarray(da.values) ** 2).sum(axis=-1)), f"|{name}|{_unit(da)}"
    return np.asarray(da.values), f"{name.replace('_', ' ')}{_unit(da)}"


# ----------------------------------------------------------------------------------------------
# the three figures


def plot_history(ds: xr.Dataset, quantity: str = "spring_force", items: Sequence[str] | None = None,
                 max_variants: int = 50) -> Figure:  # fmt: skip
    """Time histories of one quantity, one subplot per node, spring or wall, one line per variant.

    Parameters
    ----------
    ds : xarray.Dataset
        ``open_results(dir).dataset``.
    quantity : str, default ``"spring_force"``
        A history variable: ``position``, ``displacement``, ``velocity``, ``acceleration`` (node;
        signed in 1-D, magnitude in 2-D, or a component: ``"acceleration.y"``), ``spring_force``,
        ``spring_elongation`` (spring), ``wall_force`` (wall), ``kinetic_energy``,
        ``internal_energy``, ``external_work``, ``wall_energy`` (one panel).
    items : list of str, optional
        Nodes, springs or walls to draw; default all springs / walls, or the free nodes.
    max_variants : int, default 50
        Most variants drawn (evenly spaced through the ``ok`` variants).

    Returns
    -------
    matplotlib.figure.Figure
        Lines are drawn in variant order; ``fig.axes[i].lines[j]`` is the j-th drawn variant of item i.

    Raises
    ------
    crashstudy.errors.InputError
        Unknown quantity or item (the message lists the valid names), or no histories in the results.
    """
    name, _ = _parse_quantity(ds, quantity)
    _need_histories(ds, [name])
    dim = ITEM_DIM[name]
    if dim is None:
        if items:
            raise _fail(_where(ds), f"{name} is one value per variant and has no items (drop --items)")
        panels: list[str | None] = [None]
    else:
        default = free_nodes(ds) if dim == "node" else [str(v) for v in ds[dim].values]
        panels = list(_items(ds, dim, items, default))
        if not panels:
            raise _fail(_where(ds), f"the model has no {dim}s, so there is no {name} to plot")
    index, note = select_variants(ds, max_variants)
    colours = _Colours(ds, index)
    t = ds["time"]
    drawn = ds.isel(variant=index)  # read only the drawn variants' histories
    fig, axs = _new_figure(len(panels))
    for ax, item in zip(axs, panels, strict=True):
        values, ylabel = history_values(drawn, quantity, item)
        for v, row, colour, label in zip(index, values, colours.colours, colours.labels, strict=True):
            ax.plot(t.values, row, color=colour, lw=1.0, label=label, gid=f"variant {int(v)}")
        ax.set_title(f"{dim} {item}" if item is not None else name, fontsize="medium")
        ax.set_ylabel(ylabel)
        ax.grid(True, alpha=0.3)
    _xlabel(axs, f"time{_unit(t)}")
    colours.decorate(fig, axs)
    _finish(fig, f"{study_name(ds)}: {ds[name].attrs.get('long_name', name)}", note)
    return fig


def plot_force_displacement(ds: xr.Dataset, springs: Sequence[str] | None = None,
                            max_variants: int = 50) -> Figure:  # fmt: skip
    """Spring force against crush (``-spring_elongation``), one subplot per spring, one line per variant.

    Each line follows the spring through loading, unloading and reloading, so hysteresis loops
    of plastic materials show as they happen. Force keeps the results' sign (positive = tension),
    so a crushed spring's path runs to the right (crush > 0) and down (compression < 0).

    Parameters
    ----------
    ds : xarray.Dataset
        ``open_results(dir).dataset``; needs ``spring_force`` and ``spring_elongation`` histories.
    springs : list of str, optional
        Springs to draw (default all).
    max_variants : int, default 50
        Most variants drawn (evenly spaced through the ``ok`` variants).

    Returns
    -------
    matplotlib.figure.Figure
        ``fig.axes[i].lines[j]``: x = crush [length], y = force [force] of the j-th drawn variant.
    """
    _need_histories(ds, ["spring_force", "spring_elongation"])
    panels = _items(ds, "spring", springs, [str(v) for v in ds["spring"].values])
    index, note = select_variants(ds, max_variants)
    colours = _Colours(ds, index)
    force, elong = ds["spring_force"].isel(variant=index), ds["spring_elongation"].isel(variant=index)
    fig, axs = _new_figure(len(panels), sharex=False)
    for ax, spring in zip(axs, panels, strict=True):
        f = np.asarray(force.sel(spring=spring).values)
        crush = -np.asarray(elong.sel(spring=spring).values)
        for v, c, fv, colour, label in zip(index, crush, f, colours.colours, colours.labels, strict=True):
            ax.plot(c, fv, color=colour, lw=1.0, label=label, gid=f"variant {int(v)}")
        ax.axhline(0.0, color="0.6", lw=0.6)
        ax.axvline(0.0, color="0.6", lw=0.6)
        ax.set_title(f"spring {spring}", fontsize="medium")
        ax.set_ylabel(f"force (+ = tension){_unit(force)}")
        ax.grid(True, alpha=0.3)
    _xlabel(axs, f"crush = -elongation{_unit(elong)}")
    colours.decorate(fig, axs)
    _finish(fig, f"{study_name(ds)}: spring force against crush", note)
    return fig


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


def default_metric(summary: pd.DataFrame, nodes: Sequence[str] | None = None,
                   prefix: str = "peak_deceleration_g") -> str:  # fmt: skip
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


def plot_matrix(summary: pd.DataFrame, metric: str | None = None, x: str | None = None, y: str | None = None,
                agg: Aggregate = "max", axes: Sequence[str] | None = None, units: str | None = None,
                title: str | None = None) -> Figure:  # fmt: skip
    """A summary metric over the study matrix: a line plot over one axis or a heat map over two.

    Parameters
    ----------
    summary : pandas.DataFrame
        ``open_results(dir).summary`` (one row per variant).
    metric : str, optional
        A summary column, e.g. ``"peak_force.cabin"``; default :func:`default_metric`.
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
        Unit of the metric for the labels (``plot_command`` takes it from the dataset).
    title : str, optional
        Figure title (default the metric).

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
    for name, value in (("x", x), ("y", y)):
        if value is not None and value not in axes:
            raise _fail(
                "<summary>", f"unknown study axis {value!r} for {name}; valid axes: {', '.join(axes)}"
            )
    if y is not None and y == x:
        raise _fail("<summary>", f"x and y are the same axis {x!r}; choose two different axes")
    if agg not in ("max", "mean", "min"):
        raise _fail("<summary>", f"unknown agg {agg!r}; valid: max, mean, min")
    ok = (
        summary["status"].astype(str) == "ok" if "status" in summary else pd.Series(True, index=summary.index)
    )
    n_failed = int((~ok).sum())
    df = summary[ok]
    label = f"{metric}{f' [{units}]' if units else ''}"
    note = f"{n_failed} failed variant{'s' if n_failed > 1 else ''} skipped" if n_failed else ""
    others = [a for a in axes if a not in (x, y)]
    if y is None:
        fig = Figure(figsize=(8.0, 5.0), layout="constrained")
        ax = fig.subplots()
        _matrix_lines(ax, df, metric, x, others)
        ax.set_xlabel(x)
        ax.set_ylabel(label)
        ax.grid(True, alpha=0.3)
    else:
        fig = Figure(figsize=(8.0, 6.0), layout="constrained")
        ax = fig.subplots()
        table = df.pivot_table(index=y, columns=x, values=metric, aggfunc=agg, dropna=False)
        table = table.reindex(index=np.unique(summary[y]), columns=np.unique(summary[x]))
        _heat_map(fig, ax, table, label)
        ax.set_xlabel(x)
        ax.set_ylabel(y)
        if others:
            note = "; ".join(filter(None, [f"each cell: {agg} over {', '.join(others)}", note]))
    _finish(fig, title or f"{metric} over the study matrix", note)
    return fig


def _matrix_lines(ax, df: pd.DataFrame, metric: str, x: str, others: list[str]) -> None:
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
            name = ", ".join(f"{a}={float(v):g}" for a, v in zip(others, key, strict=True))
            ax.plot(d.index.to_numpy(), d.to_numpy(), "o-", color=cmap(i % 10), label=name)
        ax.legend(fontsize="small", title=None)
        return
    stats = df.groupby(x)[metric].agg(["mean", "min", "max"])
    xs = stats.index.to_numpy()
    ax.fill_between(xs, stats["min"].to_numpy(), stats["max"].to_numpy(), alpha=0.25,
                    label=f"min-max over {len(groups)} combinations of {', '.join(others)}")  # fmt: skip
    ax.plot(xs, stats["mean"].to_numpy(), "o-", label="mean")
    ax.legend(fontsize="small")


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
                ax.text(j, i, f"{v:.3g}", ha="center", va="center", fontsize=size,
                        color="white" if dark else "black")  # fmt: skip
            else:
                ax.text(j, i, "failed", ha="center", va="center", fontsize="x-small", color="0.4")


# ----------------------------------------------------------------------------------------------
# command line


def _safe(name: str) -> str:
    return "".join(c if c.isalnum() or c in "._-" else "_" for c in name)


def _matrix_metrics(summary: pd.DataFrame, axes: list[str], quantity: str | None, items: Sequence[str] | None,
                    nodes: list[str], where: str) -> list[str]:  # fmt: skip
    """Metric columns named by ``--quantity`` (a column, or a metric name with optional ``--items``)."""
    metrics = metric_columns(summary, axes)
    if quantity in metrics and not items:
        return [quantity]
    base = quantity or "peak_deceleration_g"
    with_items = [c for c in metrics if c.startswith(base + ".")]
    if not with_items:
        bases = sorted({c.split(".", 1)[0] for c in metrics})
        raise _fail(
            where, f"unknown metric {base!r}; valid: {', '.join(bases)} (or a column: {', '.join(metrics)})"
        )
    if not items:
        return [default_metric(summary, nodes, prefix=base)]
    valid = [c.split(".", 1)[1] for c in with_items]
    unknown = [i for i in items if i not in valid]
    if unknown:
        raise _fail(
            where, f"{base} has no item {', '.join(map(repr, unknown))}; valid items: {', '.join(valid)}"
        )
    return [f"{base}.{i}" for i in items]


PLOT_TAG = "crashstudy-plot-of"  #: PNG text key naming the result a figure of ``crashstudy plot`` shows


def is_crashstudy_plot(path: Path) -> bool:
    """Whether the PNG at ``path`` was written by ``crashstudy plot`` (it carries :data:`PLOT_TAG`).

    Reads the PNG's chunks up to the image data; a file that is not a PNG is not ours."""
    import struct

    try:
        with open(path, "rb") as fh:
            if fh.read(8) != b"\x89PNG\r\n\x1a\n":
                return False
            while True:
                head = fh.read(8)
                if len(head) < 8:
                    return False
                size, kind = struct.unpack(">I4s", head)
                if kind in (b"IDAT", b"IEND") or size > 1 << 20:
                    return False
                body = fh.read(size + 4)[:size]
                if kind in (b"tEXt", b"iTXt") and body.split(b"\x00", 1)[0] == PLOT_TAG.encode():
                    return True
    except OSError:
        return False


def plot_command(args: argparse.Namespace) -> list[Path]:
    """``crashstudy plot DIR``: write the figures of ``args.kind`` as PNGs; return their paths.

    ``args`` carries ``dir``, ``kind``, ``quantity``, ``items``, ``x_axis``, ``y_axis``,
    ``max_variants`` and ``output`` (default ``DIR/plots``). History figures hold at most
    :data:`ITEMS_PER_FIGURE` subplots; more items are spread over several files.
    """
    from crashstudy.results import open_results

    where = str(args.dir)
    try:
        res = open_results(args.dir)
    except FileNotFoundError as exc:
        raise _fail(where, str(exc)) from None
    ds = res.dataset
    out = Path(args.output) if args.output else Path(args.dir) / "plots"
    figures: list[tuple[str, Figure]] = []
    try:
        if args.kind == "matrix":
            summary = res.summary
            axes = study_axes(ds)
            if not axes:
                raise _fail(
                    where,
                    "these results have no study axes (a single model run); a matrix plot needs a study",
                )
            x = args.x_axis or axes[0]
            if args.y_axis is not None:
                y = None if args.y_axis.lower() == "none" else args.y_axis  # --y none: line plot
            else:
                y = next((a for a in axes if a != x), None)
            for metric in _matrix_metrics(summary, axes, args.quantity, args.items, free_nodes(ds), where):
                units = (
                    ds[metric.split(".", 1)[0]].attrs.get("units") if metric.split(".", 1)[0] in ds else None
                )
                fig = plot_matrix(
                    summary, metric, x, y, axes=axes, units=units, title=f"{study_name(ds)}: {metric}"
                )
                suffix = f"-{x}" + (f"-{y}" if y else "") if args.x_axis or args.y_axis else ""
                figures.append((f"matrix-{metric}{suffix}", fig))
        elif args.kind == "force-displacement":
            if args.quantity:
                raise _fail(
                    where, "force-displacement draws spring_force against crush; --quantity does not apply"
                )
            _need_histories(ds, ["spring_force", "spring_elongation"])
            springs = _items(ds, "spring", args.items, [str(v) for v in ds["spring"].values])
            for n, lo in enumerate(range(0, len(springs), ITEMS_PER_FIGURE)):
                fig = plot_force_displacement(ds, springs[lo : lo + ITEMS_PER_FIGURE], args.max_variants)
                figures.append((f"force-displacement{f'-{n + 1}' if n else ''}", fig))
        else:
            quantity = args.quantity or "spring_force"
            name, _ = _parse_quantity(ds, quantity)
            _need_histories(ds, [name])
            dim = ITEM_DIM[name]
            if dim is None:
                groups: list[list[str] | None] = [None if not args.items else list(args.items)]
            else:
                default = free_nodes(ds) if dim == "node" else [str(v) for v in ds[dim].values]
                chosen = _items(ds, dim, args.items, default)
                groups = [
                    chosen[lo : lo + ITEMS_PER_FIGURE] for lo in range(0, len(chosen), ITEMS_PER_FIGURE)
                ]
            for n, group in enumerate(groups):
                fig = plot_history(ds, quantity, group, args.max_variants)
                figures.append((f"history-{quantity}{f'-{n + 1}' if n else ''}", fig))
        out.mkdir(parents=True, exist_ok=True)
        paths = []
        for stem, fig in figures:
            path = out / f"{_safe(stem)}.png"
            clear_entry(path)  # a planted link is removed, never written through
            fig.savefig(path, dpi=100, metadata={PLOT_TAG: str(res.path)})
            paths.append(path)
        return paths
    except InputError as exc:  # name the folder as the user typed it
        raise InputError([Problem(where, p.line, p.field, p.message) for p in exc.problems]) from None
    finally:
        res.close()
