"""The report's sections of what the variants respond: the crash criteria over the ok variants (a table against
their usual limits, histograms) and the histories of the chosen variants (``--variants``).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from crashstudy.analysis import report_figures as rf
from crashstudy.analysis.plot import crash_node, free_nodes
from crashstudy.analysis.report_limits import LIMITS, NO_LIMIT
from crashstudy.analysis.report_page import column_unit, esc, html_table, shown_unit

if TYPE_CHECKING:
    from crashstudy.analysis.report import Report

HISTORY_PLOTS = 3  # history figures (one per metric node)


def criteria_section(rep: Report) -> str:
    """The crash criteria over the ok variants: a table against their usual limits and histograms."""
    rows, panels = [], []
    s = rep.summary
    variant = s["variant"].to_numpy()
    for c in rep.criteria:
        name, _, node = c.partition(".")
        if name.endswith(("_t1", "_t2")):
            continue
        v = np.where(rep.ok, s[c].to_numpy(dtype=float), np.nan)
        if not np.isfinite(v).any():
            continue
        unit = column_unit(rep.ds, c)
        lim = LIMITS.get(name)
        over = int(np.nansum(v > lim.value)) if lim else 0
        std = str(rep.ds[name].attrs.get("standard", "")) if name in rep.ds.variables else ""
        rows.append(
            (
                name,
                node,
                shown_unit(unit),
                f"{np.nanmin(v):.4g}",
                f"{np.nanmedian(v):.4g}",
                f"{np.nanmax(v):.4g}",
                int(variant[np.nanargmax(v)]),
                f"{lim.value:g}" if lim else "-",
                f"{over} of {int(np.isfinite(v).sum())}" if lim else "-",
                lim.source if lim else NO_LIMIT.get(name, "-"),
                std,
            )
        )
        panels.append((c, unit, v, lim.value if lim else None))
    if not rows:
        return ""
    head = [
        "criterion",
        "node",
        "unit",
        "min",
        "median",
        "max",
        "max in variant",
        "usual limit",
        "variants above",
        "limit from",
        "computed per",
    ]
    out = html_table(head, rows, text_cols=(0, 1, 2, 9, 10))
    cols = min(len(panels), 3)
    out += rep.figures.div(
        rf.criteria_histograms(panels, "criteria over the ok variants (red: usual limit)"),
        280 * ((len(panels) + cols - 1) // cols) + 80,
    )
    return out


def history_section(rep: Report) -> str:
    """The chosen variants' histories (filtered acceleration of the metric nodes, else the crash node's)."""
    from crashstudy.analysis.plot import history_values

    ds = rep.ds
    plots: list[tuple[str, str]] = []
    if "filtered_acceleration" in ds.data_vars:
        fa = ds["filtered_acceleration"]
        first = fa.isel(variant=0)
        plots = [
            ("filtered_acceleration", str(n))
            for n in ds["node"].values
            if np.isfinite(first.sel(node=n).values).any()
        ]
    if not plots and "acceleration" in ds.data_vars:
        plots = [("acceleration", crash_node(ds) or free_nodes(ds)[0])]
    if not plots and "spring_force" in ds.data_vars:
        plots = [("spring_force", str(ds["spring"].values[0]))]
    if not plots or not rep.chosen:
        return ""
    pos = {int(v): i for i, v in enumerate(rep.summary["variant"].to_numpy())}
    t = np.asarray(ds["time"].values, dtype=float) * 1e3
    label_of = {v: k for k, v in rep.named.items() if v is not None}
    corr = getattr(rep, "correlation", None)
    labels = []
    for v in rep.chosen:
        lab = f"variant {v}" + (f" ({label_of[v]})" if v in label_of else "")
        lab += ", " + ", ".join(f"{a.rsplit('.', 1)[-1]} {rep.summary[a].iloc[pos[v]]:.4g}" for a in rep.axes)
        if corr is not None and v in corr.index:
            lab += f", R {corr.loc[v, 'R']:.3f} ({corr.loc[v, 'grade']})"
        if rep.summary["status"].iloc[pos[v]] != "ok":
            lab += " FAILED"
        labels.append(lab)
    chosen = ds.isel(variant=[pos[v] for v in rep.chosen])
    test = (rep.test[0] * 1e3, rep.test[1]) if rep.test is not None else None
    out = (
        f'<p class="note">Variants {", ".join(map(str, rep.chosen))} (--variants to choose; worst/best by '
        f"{esc(rep.key)}){'; dashed black: the --test curve' if test is not None else ''}.</p>"
    )
    for quantity, item in plots[:HISTORY_PLOTS]:
        values, name, unit = history_values(chosen, quantity, item)
        curves = [(lab, t, values[k]) for k, lab in enumerate(labels)]
        fig = rf.histories(
            curves,
            "time [ms]",
            rf.label(f"{name} {item}", shown_unit(unit)),
            f"{name} of {item}: chosen variants",
            test,
        )
        out += rep.figures.div(fig, 460)
    return out
