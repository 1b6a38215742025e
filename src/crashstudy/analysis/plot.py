"""Figures of a result folder: time histories, force-crush loops and study-matrix maps.

Three plain functions for notebooks, each returning a :class:`matplotlib.figure.Figure` built
without pyplot (no global state, no GUI backend)::

    plot_history(ds, quantity="spring_force", items=None, max_variants=50)
    plot_force_displacement(ds, springs=None, max_variants=50)
    plot_matrix(summary, metric=None, x=None, y=None)

and the ``crashstudy plot`` subcommand (:func:`crashstudy.cli.plot.plot_command`), which writes them as PNG
files. The matrix figure lives in :mod:`crashstudy.analysis.plot_matrix` (offered here too) and the looks
(legends, colours, units) in :mod:`crashstudy.analysis.plot_style`.

Conventions shared by the figures:

- Failed variants (``status != "ok"``) are never drawn; a note on the figure counts them.
- At most ``max_variants`` variants are drawn, evenly spaced through the variant numbers; the note says so.
- Few variants (up to ``LEGEND_MAX``) get a legend with their axis values; more are coloured by the
  value of the first study axis (a colour bar) and styled by the second (a legend), see
  :mod:`crashstudy.analysis.plot_style`. Labels carry units, study axes included; forces and energies take
  engineering prefixes (kN, MN); acceleration can be shown in g, time in ms.
- Node quantities (``position``, ``displacement``, ``velocity``, ``acceleration``) are drawn signed in
  a 1-D model; in a 2-D model the *magnitude* is drawn (consistent with ``peak_deceleration``, the
  largest acceleration magnitude), unless a component is named: ``quantity="acceleration.y"``.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr
from matplotlib.figure import Figure

from crashstudy.analysis.plot_style import (
    Variants,
    display_scale,
    finish,
    new_figure,
    set_xlabel,
    title_of,
    unit_text,
)
from crashstudy.errors import InputError, Problem

ITEMS_PER_FIGURE = 6  # subplots in one PNG written by ``crashstudy plot``
NODE_VARS = ("position", "displacement", "velocity", "acceleration")
ITEM_DIM = {
    "position": "node",
    "displacement": "node",
    "velocity": "node",
    "acceleration": "node",
    "spring_force": "spring",
    "spring_elongation": "spring",
    "wall_force": "wall",
    "kinetic_energy": None,
    "internal_energy": None,
    "external_work": None,
    "wall_energy": None,
    "filtered_acceleration": "node",
}

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
    return str(ds.attrs.get("study_name") or ds.attrs.get("model_name", "results"))


def free_nodes(ds: xr.Dataset) -> list[str]:
    """Nodes of the model that can move (not fixed in every direction, no prescribed motion), as the
    results store them (every node for results written before they did)."""
    nodes = [str(n) for n in ds["node"].values]
    free = json.loads(ds.attrs.get("free_nodes", "[]"))
    return [n for n in nodes if n in free] or nodes


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


def _need_histories(ds: xr.Dataset, names: Sequence[str]) -> None:
    missing = [n for n in names if n not in ds.data_vars]
    if not missing:
        return
    kept = [n for n in ITEM_DIM if n in ds.data_vars]
    raise _fail(
        _where(ds),
        f"these results have no {' or '.join(missing)} histories (kept: "
        f"{', '.join(kept) if kept else 'none; the run used output.histories: none'}); re-run the study "
        "with histories, e.g. `set: {output: {histories: all}}` in the study file and "
        "`crashstudy run STUDY.yaml --force` (the matrix plot needs only the summary)",
    )


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
        raise _fail(
            _where(ds),
            f"unknown history quantity {quantity!r}; valid: {', '.join(ITEM_DIM)}"
            f" (node quantities take a component in 2-D, e.g. acceleration.y)",
        )
    if comp:
        axes = [str(a) for a in ds["axis"].values] if "axis" in ds.coords else ["x"]
        if name not in NODE_VARS or comp not in axes:
            raise _fail(
                _where(ds), f"{quantity!r}: only node quantities take a component, one of {', '.join(axes)}"
            )
    return name, comp or None


def history_values(ds: xr.Dataset, quantity: str, item: str | None) -> tuple[np.ndarray, str, str]:
    """The drawn values of ``quantity`` for ``item``, shape (variant, time), their name and their unit.

    Node quantities: signed in 1-D; in 2-D the magnitude, or the component named as ``"acceleration.y"``.
    """
    name, comp = _parse_quantity(ds, quantity)
    _need_histories(ds, [name])
    da = ds[name]
    dim = ITEM_DIM[name]
    if dim is not None:
        da = da.sel({dim: item})
    unit = str(da.attrs.get("units", ""))
    if name in NODE_VARS:
        if comp is not None:
            return np.asarray(da.sel(axis=comp).values), f"{name} {comp}", unit
        if ds.sizes.get("axis", 1) == 1:
            return np.asarray(da.isel(axis=0).values), name, unit
        return np.sqrt((np.asarray(da.values) ** 2).sum(axis=-1)), f"|{name}|", unit
    return np.asarray(da.values), name.replace("_", " "), unit


# ----------------------------------------------------------------------------------------------
# the history figures (the matrix figure: crashstudy.analysis.plot_matrix)


def plot_history(
    ds: xr.Dataset,
    quantity: str = "spring_force",
    items: Sequence[str] | None = None,
    max_variants: int = 50,
    time_unit: str | None = None,
    accel_unit: str | None = None,
    test: Any = None,
) -> Figure:
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
    time_unit : {"s", "ms"}, optional
        Unit of the time axis (default the results' own).
    accel_unit : {"g"}, optional
        ``"g"``: accelerations in standard gravities (default the results' length/time^2).
    test : crashstudy.exchange.testcurve.TestCurve, optional
        A test curve in the results' units, drawn in black over the one panel (its last line).

    Returns
    -------
    matplotlib.figure.Figure
        Lines are drawn in variant order; ``fig.axes[i].lines[j]`` is the j-th drawn variant of item i,
        in the units of the axis labels (forces and energies with an engineering prefix: kN, MN, kJ).

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
    look = Variants(ds, index, study_axes(ds))
    system = str(ds.attrs.get("units", ""))
    t_factor, t_unit = display_scale(str(ds["time"].attrs.get("units", "")), time_unit=time_unit)
    t = np.asarray(ds["time"].values) * t_factor
    drawn = ds.isel(variant=index)  # read only the drawn variants' histories
    fig, axs = new_figure(len(panels))
    for ax, item in zip(axs, panels, strict=True):
        values, ylabel, unit = history_values(drawn, quantity, item)
        factor, unit = display_scale(unit, values, system=system, accel_unit=accel_unit)
        for v, row, colour, style, label in zip(
            index, values * factor, look.colours, look.styles, look.labels, strict=True
        ):
            ax.plot(t, row, color=colour, ls=style, lw=1.0, label=label, gid=f"variant {int(v)}")
        if test is not None:
            ax.plot(
                test.time * t_factor,
                test.value * factor,
                color="k",
                lw=1.6,
                label=f"test {test.label}",
                gid="test",
            )
        ax.set_title(f"{dim} {item}" if item is not None else name, fontsize="medium")
        ax.set_ylabel(ylabel + unit_text(unit))
        ax.grid(True, alpha=0.3)
    set_xlabel(axs, f"time{unit_text(t_unit)}")
    look.decorate(fig, axs)
    finish(fig, f"{study_name(ds)}: {title_of(ds[name], name)}", note)
    return fig


def plot_force_displacement(
    ds: xr.Dataset, springs: Sequence[str] | None = None, max_variants: int = 50
) -> Figure:
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
        ``fig.axes[i].lines[j]``: x = crush [length], y = force of the j-th drawn variant, in the unit
        of the y label (the force unit with an engineering prefix: kN, MN).
    """
    _need_histories(ds, ["spring_force", "spring_elongation"])
    panels = _items(ds, "spring", springs, [str(v) for v in ds["spring"].values])
    index, note = select_variants(ds, max_variants)
    look = Variants(ds, index, study_axes(ds))
    force, elong = ds["spring_force"].isel(variant=index), ds["spring_elongation"].isel(variant=index)
    fig, axs = new_figure(len(panels), sharex=False)
    for ax, spring in zip(axs, panels, strict=True):
        f = np.asarray(force.sel(spring=spring).values)
        factor, f_unit = display_scale(str(force.attrs.get("units", "")), f)
        crush = -np.asarray(elong.sel(spring=spring).values)
        for v, c, fv, colour, style, label in zip(
            index, crush, f * factor, look.colours, look.styles, look.labels, strict=True
        ):
            ax.plot(c, fv, color=colour, ls=style, lw=1.0, label=label, gid=f"variant {int(v)}")
        ax.axhline(0.0, color="0.6", lw=0.6)
        ax.axvline(0.0, color="0.6", lw=0.6)
        ax.set_title(f"spring {spring}", fontsize="medium")
        ax.set_ylabel(f"force (+ = tension){unit_text(f_unit)}")
        ax.grid(True, alpha=0.3)
    set_xlabel(axs, f"crush = -elongation{unit_text(str(elong.attrs.get('units', '')))}")
    look.decorate(fig, axs)
    finish(fig, f"{study_name(ds)}: spring force against crush", note)
    return fig


def crash_node(ds: xr.Dataset) -> str | None:
    """The node a crash engineer means by "the deceleration" of these results: the node of a
    ``peak_deceleration_g.<node>`` key in the study's ``regression:`` block when there is one, else
    the heaviest free node of the model (the survival room or occupant cell, not the bumper)."""
    nodes = free_nodes(ds)
    for key in json.loads(ds.attrs.get("regression", "{}")):
        name, _, node = str(key).partition(".")
        if name == "peak_deceleration_g" and node in nodes:
            return node
    mass = json.loads(ds.attrs.get("node_mass", "{}"))
    masses = {n: float(mass[n]) for n in nodes if n in mass}
    return max(masses, key=lambda n: masses[n]) if masses else None


def __getattr__(name: str) -> object:
    """``plot_matrix``, ``default_metric`` and ``metric_columns`` of :mod:`.plot_matrix`, imported when first
    asked for (a plain import, so that the import-cycle test sees this edge)."""
    if name in ("plot_matrix", "default_metric", "metric_columns"):
        from crashstudy.analysis import plot_matrix

        return getattr(plot_matrix, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
