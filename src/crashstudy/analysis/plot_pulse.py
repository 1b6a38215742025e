"""``crashstudy plot DIR --kind pulse``: the SAE J211 filtered pulse of the metric nodes beside the raw channel.

One panel per node of the ``metrics:`` block, time in ms, in g, drawn as test pulses are: the signed
deceleration along the node's direction of travel (the ``direction`` of its metrics entry, else its initial
velocity direction, else x), ``-a . d``: positive while the node is slowed, negative when it is pushed or
pulled along its travel (a rebound, a tied node pulled back), never folded up as a resultant would be.
Each drawn variant has two lines of its colour: the raw channel (the ``acceleration`` history, thin and
pale) and the filtered one: the same component through the SAE J211 filter of the metrics entry's class,
applied to the history samples; in 1-D its magnitude is the ``filtered_acceleration`` history (the signal
the criteria judge, filtered at every step) and only its sign comes from the samples. Both are the
histories as sampled (``output.interval``): a sample interval longer than the pulse's features hides its
peaks (the criteria themselves use every step).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

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


def _metric_entry(ds: xr.Dataset, node: str) -> dict[str, Any]:
    """The first ``metrics:`` entry of ``node`` in the model stored with the results ({} without one)."""
    import yaml

    try:
        model = yaml.safe_load(str(ds.attrs.get("model_yaml", "")) or "{}") or {}
    except yaml.YAMLError:
        return {}
    entries = model.get("metrics") if isinstance(model, dict) else None
    return next((dict(e) for e in entries or [] if isinstance(e, dict) and e.get("node") == node), {})


def travel_direction(ds: xr.Dataset, node: str, index: np.ndarray) -> np.ndarray:
    """(v, D) unit direction of travel of ``node`` in the drawn variants: the metrics entry's ``direction``,
    else the node's initial velocity (the ``velocity`` history at t = 0, else the model's), else x."""
    dim = int(ds.sizes.get("axis", 1))
    given = _metric_entry(ds, node).get("direction")
    if isinstance(given, str):
        d = np.zeros(dim)
        d["xy".index(given)] = 1.0
        return np.broadcast_to(d, (len(index), dim)).copy()
    if isinstance(given, list):
        d = np.asarray(given, dtype=float)
        return np.broadcast_to(d / np.linalg.norm(d), (len(index), dim)).copy()
    if "velocity" in ds.data_vars:
        v0 = np.asarray(ds["velocity"].sel(node=node).isel(time=0).values, dtype=float)[index]  # (v, D)
    else:
        import yaml

        model = yaml.safe_load(str(ds.attrs.get("model_yaml", "")) or "{}") or {}
        v = ((model.get("initial_velocity") or {}) if isinstance(model, dict) else {}).get(node) or [
            0.0
        ] * dim
        v0 = np.broadcast_to(np.asarray(v, dtype=float), (len(index), dim))
    speed = np.linalg.norm(v0, axis=1)
    x = np.eye(dim)[0]
    return np.where(speed[:, None] > 0, v0 / np.where(speed > 0, speed, 1.0)[:, None], x[None, :])


def signed_pulse(ds: xr.Dataset, node: str, index: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(raw, filtered) deceleration along the direction of travel [g], (v, time), of the drawn variants."""
    from crashstudy.metrics.criteria import j211_filter

    g = UNIT_SYSTEMS[str(ds.attrs.get("units", "SI"))].g
    acc = np.asarray(ds["acceleration"].sel(node=node).values, dtype=float)[index]  # (v, time, axis)
    raw = -np.einsum("vtd,vd->vt", acc, travel_direction(ds, node, index)) / g
    ok = np.isfinite(raw)
    count = np.where(ok.all(axis=1), raw.shape[1], np.argmin(ok, axis=1))
    t = np.asarray(ds["time"].values, dtype=float)
    second = 1.0 / TIME_UNITS[str(ds["time"].attrs.get("units", "s"))]
    dt = np.full(len(index), float(t[1] - t[0]) if len(t) > 1 else 1.0)
    cfc = int(_metric_entry(ds, node).get("cfc", 180))
    filt = j211_filter(np.where(ok, raw, 0.0), count, dt, cfc, second=second)
    stored = np.asarray(ds["filtered_acceleration"].sel(node=node).values, dtype=float)[index]
    if acc.shape[2] == 1:  # 1-D: the stored filtered pulse (every step) with the sign of the filtered samples
        filt = np.sign(filt) * stored
    return raw, np.where(ok, filt, np.nan)


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
        ``fig.axes[i].lines[2 j]`` is the raw deceleration along the direction of travel of the j-th drawn
        variant at node i, ``[2 j + 1]`` its filtered one, both in g against time in ms (the last line: zero).
    """
    where = _where(ds)
    if "filtered_acceleration" not in ds.data_vars:
        raise _fail(
            where,
            "no filtered pulse in these results: the model has no metrics: block, or its "
            "output.histories leave out filtered_acceleration",
        )
    _need_histories(ds, ["acceleration", "filtered_acceleration"])
    panels = list(_items(ds, "node", nodes, metric_nodes(ds)))
    index, note = select_variants(ds, max_variants)
    look = Variants(ds, index, study_axes(ds))
    t_ms = (
        np.asarray(ds["time"].values) * TIME_UNITS[str(ds["time"].attrs.get("units", "s"))] / TIME_UNITS["ms"]
    )
    fig, axs = new_figure(len(panels))
    for ax, node in zip(axs, panels, strict=True):
        raw, filt = signed_pulse(ds, node, index)
        for v, r, f, colour, label in zip(index, raw, filt, look.colours, look.labels, strict=True):
            ax.plot(t_ms, r, color=colour, lw=0.7, alpha=0.35, gid=f"variant {int(v)} raw")
            ax.plot(t_ms, f, color=colour, lw=1.4, label=label, gid=f"variant {int(v)} filtered")
        ax.set_title(f"node {node}", fontsize="medium")
        ax.axhline(0.0, color="0.6", lw=0.8)
        ax.set_ylabel("deceleration along travel [g]")
        ax.grid(True, alpha=0.3)
    set_xlabel(axs, "time [ms]")
    look.decorate(fig, axs)
    kinds = [Line2D([], [], color="0.3", lw=0.7, alpha=0.5), Line2D([], [], color="0.3", lw=1.4)]
    fitting_legend(
        fig,
        kinds,
        ["raw (acceleration history)", "SAE J211 filtered (cfc of its metrics entry)"],
        "deceleration along the direction of travel: > 0 slows the node, < 0 pushes it along",
    )
    finish(fig, f"{study_name(ds)}: filtered pulse beside the raw channel", note)
    return fig
