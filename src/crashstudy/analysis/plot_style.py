"""Looks shared by the figures of :mod:`crashstudy.analysis.plot`: layout, legends, colours and units.

- Units: a label carries the unit of its variable (the ``units`` attribute, study axes included);
  forces and energies take an engineering prefix that keeps the numbers short (N -> kN, MN);
  acceleration can be shown in g and time in ms (:func:`display_scale`).
- Variants: up to :data:`LEGEND_MAX` drawn variants get a legend whose title names the study axes
  with their units and whose entries are the axis values. More are coloured by the first study axis
  (a colour bar) and, when there is a second axis, drawn in a line style per value (or range of
  values) of it, with a legend of the styles.
- Legends sit below the panels, inside the figure (their width is checked after drawing, fewer
  columns are used until they fit); the note (failed or thinned-out variants) is a line of its own
  under them. Their heights are measured and the layout engine is given the rest of the figure
  for the panels (:func:`finish`), so nothing overlaps and nothing is cut off.
"""

from __future__ import annotations

import math
import textwrap
from collections.abc import Sequence
from typing import Any

import numpy as np
import xarray as xr
from matplotlib import colormaps
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.cm import ScalarMappable
from matplotlib.colors import Normalize
from matplotlib.figure import Figure
from matplotlib.layout_engine import ConstrainedLayoutEngine
from matplotlib.legend import Legend
from matplotlib.lines import Line2D

from crashstudy.units import UNIT_SYSTEMS

LEGEND_MAX = 10  # up to this many variants: a legend; more: a colour bar keyed to the first axis
CMAP = "viridis"
STYLES = ("-", "--", ":", "-.")  # line styles of the second study axis when there are many variants
PREFIXED = {
    "N": ("N", "kN", "MN", "GN"),
    "kN": ("kN", "MN", "GN"),
    "J": ("J", "kJ", "MJ", "GJ"),
    "kJ": ("kJ", "MJ", "GJ"),
    "mJ": ("mJ", "J", "kJ", "MJ"),
}
TIME_UNITS = {"s": 1.0, "ms": 1e-3}  # seconds per unit


def unit_text(unit: str | None) -> str:
    """`` [unit]`` for a label (``[-]`` for a dimensionless ``1``), ``""`` without a unit."""
    if not unit:
        return ""
    return " [-]" if unit == "1" else f" [{unit}]"


def axis_units(ds: xr.Dataset, axes: Sequence[str]) -> dict[str, str]:
    """The ``units`` attribute of each study axis variable (missing: ``""``)."""
    return {a: str(ds[a].attrs.get("units", "")) if a in ds.variables else "" for a in axes}


def axis_label(axis: str, units: dict[str, str] | None) -> str:
    return f"{axis}{unit_text((units or {}).get(axis))}"


def title_of(da: xr.DataArray, name: str) -> str:
    """The variable's ``long_name`` without its parenthesised remarks (``node acceleration``)."""
    return str(da.attrs.get("long_name", name)).split(" (", 1)[0]


def display_scale(
    unit: str,
    values: Any = None,
    *,
    system: str | None = None,
    accel_unit: str | None = None,
    time_unit: str | None = None,
) -> tuple[float, str]:
    """(factor, unit) to show ``values`` of ``unit`` in: ``g`` for an acceleration when ``accel_unit``
    is ``"g"`` (standard gravity of the unit ``system``), ``s``/``ms`` for a time when ``time_unit``
    names one, and for forces and energies the largest engineering prefix that keeps the largest
    magnitude of ``values`` at or above 1 (N -> kN at 1e3 N, MN at 1e6 N)."""
    if time_unit and unit in TIME_UNITS:
        return TIME_UNITS[unit] / TIME_UNITS[time_unit], time_unit
    if accel_unit == "g" and system in UNIT_SYSTEMS and unit == UNIT_SYSTEMS[system].acceleration:
        return 1.0 / UNIT_SYSTEMS[system].g, "g"
    if unit in PREFIXED and values is not None:
        arr = np.asarray(values, dtype=float)
        top = float(np.nanmax(np.abs(arr), initial=0.0)) if arr.size else 0.0
        names = PREFIXED[unit]
        step = 0 if not np.isfinite(top) or top < 1e3 else min(int(math.log10(top) // 3), len(names) - 1)
        return 10.0 ** (-3 * step), names[step]
    return 1.0, unit


def new_figure(n_panels: int, width: float = 8.0, sharex: bool = True) -> tuple[Figure, list]:
    ncols = 1 if n_panels <= 3 else 2
    nrows = math.ceil(n_panels / ncols)
    fig = Figure(figsize=(width if ncols == 1 else width * 1.4, 1.6 + 2.6 * nrows), layout="constrained")
    FigureCanvasAgg(fig)  # a renderer, so legends can be measured (still no pyplot)
    grid = fig.subplots(nrows, ncols, squeeze=False, sharex=sharex)
    axs = list(grid.ravel())
    for ax in axs[n_panels:]:
        ax.set_visible(False)
    for ax in axs[n_panels - ncols if n_panels > ncols else 0 : n_panels]:
        ax.xaxis.set_tick_params(labelbottom=True)
    return fig, axs[:n_panels]


def set_xlabel(axs: list, label: str) -> None:
    """Label the x axis of the bottom subplot of each column."""
    ncols = 1 if len(axs) <= 3 else 2
    for i, ax in enumerate(axs):
        if i + ncols >= len(axs):
            ax.set_xlabel(label)


def _renderer(fig: Figure) -> Any:
    """The figure's Agg renderer (an Agg canvas is attached when the figure has none)."""
    canvas = fig.canvas if isinstance(fig.canvas, FigureCanvasAgg) else FigureCanvasAgg(fig)
    return canvas.get_renderer()


PAD = 0.01  # [figure fraction] between the note, the legends and the panels


def finish(fig: Figure, title: str, note: str) -> None:
    """Title on top; at the bottom the note, above it the legends of :func:`fitting_legend`, above
    them the panels (the layout engine is confined to the space the measured legends leave)."""
    fig.suptitle(title)
    renderer = _renderer(fig)
    height = fig.bbox.height
    bottom = PAD / 2
    if note:
        text = _wrapped_note(fig, note, renderer)
        bottom += text.get_window_extent(renderer).height / height + PAD / 2
    for leg in getattr(fig, "_crashstudy_legends", []):
        leg.set_bbox_to_anchor((0.5, bottom), transform=fig.transFigure)
        bottom += leg.get_window_extent(renderer).height / height + PAD / 2
    if bottom > PAD / 2:
        engine = fig.get_layout_engine()
        if isinstance(engine, ConstrainedLayoutEngine):
            engine.set(rect=(0.0, bottom, 1.0, 1.0 - bottom))


def _wrapped_note(fig: Figure, note: str, renderer: Any) -> Any:
    """The note at the bottom left, wrapped at word boundaries to the figure's width (never cut off)."""
    width = fig.bbox.width
    chars = max(20, int(width / 6.5))
    while True:
        wrapped = "\n".join(textwrap.fill(part, chars, break_long_words=True) for part in note.split("\n"))
        text = fig.text(0.01, PAD / 2, wrapped, fontsize="small", color="0.35", ha="left", va="bottom")
        if text.get_window_extent(renderer).x1 <= width - 2 or chars <= 20:
            return text
        text.remove()
        chars = int(chars * 0.9)


def fitting_legend(fig: Figure, handles: list, labels: list[str], title: str, max_cols: int = 4) -> Legend:
    """A legend below the panels with as many columns (up to ``max_cols``) as fit the figure's width."""
    width = fig.bbox.width
    chars = max(20, int(width / 6.5))  # small font: ~6.5 px per character at 100 dpi
    title = "\n".join(textwrap.wrap(title, chars)) if title else title
    labels = [
        "\n".join(textwrap.wrap(lb, chars - 6)) or lb for lb in labels
    ]  # a long label wraps, never cut off
    for ncols in range(min(max_cols, max(len(labels), 1)), 0, -1):
        leg = fig.legend(
            handles,
            labels,
            loc="lower center",
            bbox_to_anchor=(0.5, 0.0),
            ncols=ncols,
            fontsize="small",
            title=title or None,
            title_fontsize="small",
            frameon=False,
        )
        box = leg.get_window_extent(_renderer(fig))
        if box.width <= width - 10 or ncols == 1:
            fig._crashstudy_legends = [*getattr(fig, "_crashstudy_legends", []), leg]  # type: ignore[attr-defined]
            return leg
        leg.remove()
    raise AssertionError("unreachable")  # pragma: no cover


def _style_groups(values: np.ndarray, unit: str) -> tuple[np.ndarray, list[str]]:
    """A line style index per variant for one axis: one per distinct value when there are at most
    ``len(STYLES)``, else ``len(STYLES)`` ranges of the distinct values; and the legend labels."""
    distinct = np.unique(values)
    u = f" {unit}" if unit and unit != "1" else ""
    if len(distinct) <= len(STYLES):
        return np.searchsorted(distinct, values), [f"{v:g}{u}" for v in distinct]
    parts = np.array_split(distinct, len(STYLES))
    edges = np.array([p[-1] for p in parts])
    return np.searchsorted(edges, values), [f"{p[0]:g} – {p[-1]:g}{u}" for p in parts]


class Variants:
    """How each drawn variant looks: colour, line style and label (see the module docstring)."""

    def __init__(self, ds: xr.Dataset, index: np.ndarray, axes: list[str]) -> None:
        from crashstudy.analysis.factors import factor_name, factors

        groups = factors(dict(ds.attrs), axes)  # a zip group is one factor, shown by its first path
        axes = list(groups)
        self.index = index
        self.axes = axes
        self.units = axis_units(ds, axes)
        self.names = {a: factor_name(groups[a]) for a in axes}
        self.mappable: ScalarMappable | None = None
        self.style_axis: str | None = None
        values = {a: np.asarray(ds[a].values, dtype=float)[index] for a in axes}
        if not axes:
            self.labels = [f"variant {int(ds['variant'].values[k])}" for k in index]
        else:
            self.labels = [", ".join(f"{values[a][i]:g}" for a in axes) for i in range(len(index))]
        self.styles = ["-"] * len(index)
        if len(index) <= LEGEND_MAX or not axes:
            cmap = colormaps["tab10"]
            self.colours = [cmap(i % 10) for i in range(len(index))]
            return
        first = values[axes[0]]
        norm = Normalize(float(np.nanmin(first)), float(np.nanmax(first)))
        cmap = colormaps[CMAP]
        self.colours = [cmap(norm(v)) for v in first]
        self.mappable = ScalarMappable(norm=norm, cmap=cmap)
        self.mappable.set_array(first)
        if len(axes) > 1:
            self.style_axis = axes[1]
            group, self.style_labels = _style_groups(values[axes[1]], self.units[axes[1]])
            self.styles = [STYLES[g] for g in group]

    @property
    def legend(self) -> bool:
        return self.mappable is None

    def decorate(self, fig: Figure, axs: list) -> None:
        if self.mappable is not None:
            fig.colorbar(self.mappable, ax=axs, label=self._label(self.axes[0]), shrink=0.9)
            if self.style_axis is not None:
                handles = [Line2D([], [], color="0.2", ls=s) for s in STYLES[: len(self.style_labels)]]
                rest = [self.names[a] for a in self.axes if a not in (self.axes[0], self.style_axis)]
                title = self._label(self.style_axis)
                if rest:
                    title += f" (lines differing only in {', '.join(rest)} look alike)"
                fitting_legend(fig, handles, self.style_labels, title)
        elif len(self.index) > 1:
            handles, labels = axs[0].get_legend_handles_labels()
            title = ", ".join(self._label(a) for a in self.axes)
            fitting_legend(fig, handles, labels, title)

    def _label(self, axis: str) -> str:
        """The factor's name with the unit of its first path."""
        return f"{self.names[axis]}{unit_text(self.units.get(axis))}"
