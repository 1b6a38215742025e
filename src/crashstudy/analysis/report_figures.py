"""The figures of ``crashstudy report`` as plain plotly figure dicts (``{"data": [...], "layout": {...}}``):
no plotly Python objects are built (fast for 10^5 variants; the page draws them with plotly.js).

Every axis title carries its unit (``[-]`` for a dimensionless quantity), as the PNG plots do.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from crashstudy.analysis.plot_style import unit_text
from crashstudy.analysis.report_limits import Check

PASS, FAIL = "#2ca02c", "#d62728"
LINE_COLOURS = (
    "#1f77b4",
    "#ff7f0e",
    "#2ca02c",
    "#d62728",
    "#9467bd",
    "#8c564b",
    "#e377c2",
    "#7f7f7f",
    "#bcbd22",
    "#17becf",
)


def label(name: str, unit: str | None) -> str:
    return f"{name}{unit_text(unit)}"


def _vals(a: Any, digits: int = 6) -> list[float | None]:
    """Numbers rounded to ``digits`` significant digits (smaller JSON), NaN as None."""
    x = np.asarray(a, dtype=float)
    out: list[float | None] = []
    for v in x.tolist():
        out.append(float(f"{v:.{digits}g}") if math.isfinite(v) else None)
    return out


def grid_layout(
    n: int,
    cols: int,
    titles: Sequence[str],
    ytitles: Sequence[str] | None = None,
    share_y: bool = False,
    gap: float = 0.07,
) -> dict[str, Any]:
    """Layout entries of ``n`` panels in ``cols`` columns: xaxisK/yaxisK with domains, titles under the x axes
    (``titles``) and optional y titles."""
    rows = max(1, math.ceil(n / cols))
    layout: dict[str, Any] = {}
    w = (1 - gap * (cols - 1)) / cols
    h = (1 - 0.12 * (rows - 1)) / rows
    for k in range(n):
        r, c = divmod(k, cols)
        x0 = c * (w + gap)
        y1 = 1 - r * (h + 0.12)
        sfx = "" if k == 0 else str(k + 1)
        layout[f"xaxis{sfx}"] = {
            "domain": [x0, x0 + w],
            "anchor": f"y{sfx}",
            "title": {"text": titles[k]},
            "automargin": True,
        }
        ya: dict[str, Any] = {"domain": [max(0.0, y1 - h), y1], "anchor": f"x{sfx}", "automargin": True}
        if ytitles is not None and (not share_y or c == 0):
            ya["title"] = {"text": ytitles[k]}
        if share_y and k:
            ya["matches"] = "y"
        layout[f"yaxis{sfx}"] = ya
    return layout


def parcoords(
    columns: Sequence[tuple[str, str, np.ndarray]],
    passed: np.ndarray | None,
    colour_by: tuple[str, np.ndarray] | None,
    title: str,
) -> dict[str, Any]:
    """Parallel coordinates: ``columns`` as (name, unit, values); lines green where ``passed``, red where not
    (else coloured by ``colour_by``)."""
    dims = []
    for name, unit, values in columns:
        v = np.asarray(values, dtype=float)
        lo, hi = (float(np.nanmin(v)), float(np.nanmax(v))) if np.isfinite(v).any() else (0.0, 1.0)
        if lo == hi:
            lo, hi = lo - 0.5 * (abs(lo) or 1.0), hi + 0.5 * (abs(hi) or 1.0)
        text = name if len(name) <= 18 or "." not in name else name.replace(".", ".<br>", 1)  # no overlap
        dims.append({"label": label(text, unit), "values": _vals(v, 5), "range": [lo, hi]})
    if passed is not None:
        line = {
            "color": [1 if p else 0 for p in passed],
            "colorscale": [[0, FAIL], [1, PASS]],
            "cmin": 0,
            "cmax": 1,
        }
    elif colour_by is not None:
        line = {
            "color": _vals(colour_by[1], 5),
            "colorscale": "Viridis",
            "showscale": True,
            "colorbar": {"title": {"text": colour_by[0]}},
        }
    else:
        line = {"color": PASS}
    return {
        "data": [{"type": "parcoords", "dimensions": dims, "line": line}],
        "layout": {
            "title": {"text": title},
            "margin": {"l": 90, "r": 90, "t": 110, "b": 40},
            "font": {"size": 11},
        },
    }


def anthill(
    axes: Sequence[tuple[str, str, np.ndarray]],
    response: tuple[str, str, np.ndarray],
    passed: np.ndarray | None,
    checks: Sequence[Check],
    title: str,
) -> dict[str, Any]:
    """One response against each axis (a panel per axis, shared y); points green/red by ``passed``; the
    response's limits as dashed lines."""
    name, unit, y = response
    data = []
    colour: Any = PASS if passed is None else [PASS if p else FAIL for p in passed]
    for k, (_, _, x) in enumerate(axes):
        sfx = "" if k == 0 else str(k + 1)
        data.append(
            {
                "type": "scatter",
                "mode": "markers",
                "x": _vals(x, 6),
                "y": _vals(y, 5),
                "xaxis": f"x{sfx}",
                "yaxis": f"y{sfx}",
                "showlegend": False,
                "marker": {"size": 5, "opacity": 0.7, "color": colour},
                "hoverinfo": "x+y",
            }
        )
    layout = grid_layout(
        len(axes),
        min(len(axes), 3),
        [label(a, u) for a, u, _ in axes],
        [label(name, unit)] * len(axes),
        share_y=True,
    )
    shapes = []
    for c in checks:
        if c.column != name:
            continue
        for k in range(len(axes)):
            sfx = "" if k == 0 else str(k + 1)
            shapes.append(
                {
                    "type": "line",
                    "xref": f"x{sfx} domain",
                    "yref": f"y{sfx}",
                    "x0": 0,
                    "x1": 1,
                    "y0": c.value,
                    "y1": c.value,
                    "line": {"color": FAIL, "dash": "dash", "width": 1},
                }
            )
    layout.update({"title": {"text": title}, "shapes": shapes})
    return {"data": data, "layout": layout}


def histories(
    curves: Sequence[tuple[str, np.ndarray, np.ndarray]],
    xlabel: str,
    ylabel: str,
    title: str,
    test: tuple[np.ndarray, np.ndarray] | None = None,
) -> dict[str, Any]:
    """Lines over time: ``curves`` as (legend, t, y); ``test`` drawn black and dashed."""
    data = [
        {
            "type": "scatter",
            "mode": "lines",
            "name": n,
            "x": _vals(t, 6),
            "y": _vals(y, 5),
            "line": {"color": LINE_COLOURS[k % len(LINE_COLOURS)], "width": 1.5},
        }
        for k, (n, t, y) in enumerate(curves)
    ]
    if test is not None:
        data.append(
            {
                "type": "scatter",
                "mode": "lines",
                "name": "test",
                "x": _vals(test[0], 6),
                "y": _vals(test[1], 5),
                "line": {"color": "#000", "dash": "dash", "width": 2},
            }
        )
    return {
        "data": data,
        "layout": {
            "title": {"text": title},
            "xaxis": {"title": {"text": xlabel}},
            "yaxis": {"title": {"text": ylabel}},
            "legend": {"orientation": "h", "y": -0.2},
        },
    }


def criteria_histograms(
    panels: Sequence[tuple[str, str, np.ndarray, float | None]], title: str
) -> dict[str, Any]:
    """A histogram per criterion (name, unit, values, usual limit or None), the limit as a red line."""
    data, shapes = [], []
    for k, (_, _, v, lim) in enumerate(panels):
        sfx = "" if k == 0 else str(k + 1)
        data.append(
            {
                "type": "histogram",
                "x": _vals(v[np.isfinite(v)], 5),
                "xaxis": f"x{sfx}",
                "yaxis": f"y{sfx}",
                "showlegend": False,
                "marker": {"color": "#1f77b4"},
            }
        )
        if lim is not None:
            shapes.append(
                {
                    "type": "line",
                    "xref": f"x{sfx}",
                    "yref": f"y{sfx} domain",
                    "x0": lim,
                    "x1": lim,
                    "y0": 0,
                    "y1": 1,
                    "line": {"color": FAIL, "dash": "dash", "width": 2},
                }
            )
    layout = grid_layout(
        len(panels),
        min(len(panels), 3),
        [label(n, u) + (f" (limit {lim:g})" if lim is not None else "") for n, u, _, lim in panels],
        ["variants [-]"] * len(panels),
    )
    layout.update({"title": {"text": title}, "shapes": shapes, "bargap": 0.05})
    return {"data": data, "layout": layout}


def bars(
    names: Sequence[str],
    values: np.ndarray,
    errors: np.ndarray | None,
    xlabel: str,
    title: str,
    group: Sequence[str] | None = None,
) -> dict[str, Any]:
    """Horizontal bars (one trace per distinct ``group``), error bars = ``errors`` (half-widths)."""
    groups = list(dict.fromkeys(group)) if group is not None else [""]
    data = []
    for gi, g in enumerate(groups):
        idx = [i for i in range(len(names)) if group is None or group[i] == g]
        bar: dict[str, Any] = {
            "type": "bar",
            "orientation": "h",
            "name": g or "index",
            "y": [names[i] for i in idx],
            "x": _vals(np.asarray(values)[idx], 5),
            "marker": {"color": LINE_COLOURS[gi % len(LINE_COLOURS)]},
        }
        if errors is not None:
            bar["error_x"] = {"type": "data", "array": _vals(np.asarray(errors)[idx], 4), "visible": True}
        data.append(bar)
    return {
        "data": data,
        "layout": {
            "title": {"text": title},
            "barmode": "group",
            "xaxis": {"title": {"text": xlabel}},
            "yaxis": {"automargin": True},
            "showlegend": group is not None,
        },
    }


def optimisation_history(
    x: np.ndarray, y: np.ndarray, feasible: np.ndarray, best: np.ndarray, xlabel: str, ylabel: str, title: str
) -> dict[str, Any]:
    """Each candidate's objective (green feasible, red not) and the best feasible so far (a line)."""
    return {
        "data": [
            {
                "type": "scatter",
                "mode": "markers",
                "name": "candidate",
                "x": _vals(x),
                "y": _vals(y, 5),
                "marker": {"size": 4, "color": [PASS if f else FAIL for f in feasible]},
            },
            {
                "type": "scatter",
                "mode": "lines",
                "name": "best feasible so far",
                "x": _vals(x),
                "y": _vals(best, 5),
                "line": {"color": "#000", "width": 2},
            },
        ],
        "layout": {
            "title": {"text": title},
            "xaxis": {"title": {"text": xlabel}},
            "yaxis": {"title": {"text": ylabel}},
            "legend": {"orientation": "h", "y": -0.2},
        },
    }
