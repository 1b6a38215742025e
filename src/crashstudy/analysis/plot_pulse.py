"""``crashstudy plot DIR --kind pulse``: the SAE J211 filtered pulse of the metric nodes beside the raw channel.

One panel per node of the ``metrics:`` block, time in ms, acceleration in g. Each drawn variant has two
lines of its colour: the raw channel (the ``acceleration`` history, resultant, thin and pale) and the
filtered resultant (``filtered_acceleration``, the signal the criteria judge). Both are the histories
as sampled (``output.interval``): a sample interval longer than the pulse's features hides its peaks
(the criteria themselves use every step).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import xarray as xr
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from crashstudy.analysis.plot import (
    _fail,
    _items,
    _need_histories,
    _where,
    select_variants,
    study_axes,
    study_name,
)
from crashstudy.analysis.plot_style import (
    TIME_UNITS,
    Variants,
    finish,
    fitting_legend,
    new_figure,
    set_xlabel,
)
from crashstudy.units import UNIT_SYSTEMS


def metric_nodes(ds: xr.Dataset) -> list[str]:
    """Nodes with a filtered pulse (those of the ``metrics:`` block), in node order."""
    filt = ds["filtered_acceleration"]
    return [str(n) for n in ds["node"].values if bool(np.isfinite(filt.sel(node=n).values).any())]


def plot_pulse(ds: xr.Dataset, nodes: Sequence[str] | None = None, max_variants: int = 50) -> Figure:
    """Filtered acceleration [g] against time [ms] beside the raw channel, one panel per metric node.

    Parameters
    ----------
    ds : xarray.Dataset
        ``open_results(dir).dataset`` of a model with ``metrics:``; needs the ``filtered_acceleration``
        and ``acceleration`` histories.
    nodes : list of str, optional
        Nodes to draw (default every node of the metrics block).
    max_variants : int, default 50
        Most variants drawn (evenly spaced through the ``ok`` variants).

    Returns
    -------
    matplotlib.figure.Figure
        ``fig.axes[i].lines[2 j]`` is the raw resultant of the j-th drawn variant at node i, ``[2 j + 1]``
        its filtered resultant, both in g against time in ms.
    """
    where = _where(ds)
    if "filtered_acceleration" not in ds.data_vars:
        raise _fail(where, "no filtered pulse in these results: the model has no metrics: block, or its "
                    "output.histories leave out filtered_acceleration")  # fmt: skip
    _need_histories(ds, ["acceleration", "filtered_acceleration"])
    panels = list(_items(ds, "node", nodes, metric_nodes(ds)))
    index, note = select_variants(ds, max_variants)
    look = Variants(ds, index, study_axes(ds))
    g = UNIT_SYSTEMS[str(ds.attrs.get("units", "SI"))].g
    t_ms = np.asarray(ds["time"].values) * TIME_UNITS[str(ds["time"].attrs.get("units", "s"))] / TIME_UNITS["ms"]
    drawn = ds.isel(variant=index)
    fig, axs = new_figure(len(panels))
    for ax, node in zip(axs, panels, strict=True):
        acc = np.asarray(drawn["acceleration"].sel(node=node).values)  # (v, time, axis)
        raw = np.sqrt(np.sum(acc * acc, axis=-1)) / g
        filt = np.asarray(drawn["filtered_acceleration"].sel(node=node).values)
        for v, r, f, colour, label in zip(index, raw, filt, look.colours, look.labels, strict=True):
            ax.plot(t_ms, r, color=colour, lw=0.7, alpha=0.35, gid=f"variant {int(v)} raw")
            ax.plot(t_ms, f, color=colour, lw=1.4, label=label, gid=f"variant {int(v)} filtered")
        ax.set_title(f"node {node}", fontsize="medium")
        ax.set_ylabel("resultant acceleration [g]")
        ax.grid(True, alpha=0.3)
    set_xlabel(axs, "time [ms]")
    look.decorate(fig, axs)
    kinds = [Line2D([], [], color="0.3", lw=0.7, alpha=0.5), Line2D([], [], color="0.3", lw=1.4)]
    fitting_legend(fig, kinds, ["raw (acceleration history)", "SAE J211 filtered (cfc of its metrics entry)"], "")
    finish(fig, f"{study_name(ds)}: filtered pulse beside the raw channel", note)
    return fig
