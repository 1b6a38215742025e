"""crashstudy.analysis.plot, issue 13 item 6: legends and notes inside the figure, units and prefixes on
the axes, colours and line styles of many variants, file names carrying the items, the matrix default."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from crashstudy.analysis.plot import (
    plot_force_displacement,
    plot_history,
)
from crashstudy.cli.plot import plot_command
from plot_results import MODEL_1D, _args, _notes, _run

# --- issue 13 item 6: legends, units, file names, styles, the matrix default ------------------------

LONG_AXES = {
    "springs.lower.material.stiffness": [1.0e4, 1.0e6],
    "nodes.top.mass": [0.5, 1.0],
    "impact_velocity": [1.0, 2.0, 3.0],
}


@pytest.fixture(scope="module")
def long_names(tmp_path_factory) -> Path:
    """2 x 2 x 3 variants with long axis paths (the legend entries of issue 13 did not fit), and a
    regression block naming the top node's deceleration."""
    return _run(
        tmp_path_factory.mktemp("long"),
        MODEL_1D,
        LONG_AXES,
        "plot-long",
        regression={"peak_deceleration_g.top": {"rtol": 1e-3}},
    )


def _boxes(fig):
    """Window extents (pixels) of the figure, its legends, its note and its visible panels, after drawing."""
    if not hasattr(fig.canvas, "get_renderer"):
        from matplotlib.backends.backend_agg import FigureCanvasAgg

        FigureCanvasAgg(fig)
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    legends = [leg.get_window_extent(renderer) for leg in fig.legends]
    notes = [
        t.get_window_extent(renderer)
        for t in fig.texts
        if "showing" in t.get_text() or "failed" in t.get_text()
    ]
    panels = [
        ax.get_tightbbox(renderer) for ax in fig.axes if ax.get_visible() and ax.get_label() != "<colorbar>"
    ]
    return fig.bbox, legends, notes, panels


def _inside(box, outer, tol: float = 0.5) -> bool:
    return (
        box.x0 >= outer.x0 - tol
        and box.y0 >= outer.y0 - tol
        and box.x1 <= outer.x1 + tol
        and box.y1 <= outer.y1 + tol
    )


def _overlap(a, b) -> bool:
    return a.x0 < b.x1 and b.x0 < a.x1 and a.y0 < b.y1 and b.y0 < a.y1


@pytest.mark.parametrize("panels", [["lower", "upper"], ["lower"]])
def test_legend_and_note_lie_inside_the_figure_and_overlap_nothing(long_names, opened, panels):
    ds = opened(long_names).dataset
    fig = plot_force_displacement(ds, panels, max_variants=8)
    assert "showing 8 of 12 variants" in _notes(fig)
    whole, legends, notes, axes = _boxes(fig)
    assert len(legends) == 1 and len(notes) == 1
    for box in legends + notes:
        assert _inside(box, whole), (box, whole)  # nothing clipped at either edge
    assert not _overlap(legends[0], notes[0])
    for ax in axes:
        assert not _overlap(ax, legends[0]) and not _overlap(ax, notes[0])
    # the legend title names the axes with their units; an entry is the values (8 entries, 1e-12)
    leg = fig.legends[0]
    assert leg.get_title().get_text().replace("\n", " ") == (
        "springs.lower.material.stiffness [N/m], nodes.top.mass [kg], impact_velocity [m/s]"
    )
    k, m, v = (ds[a].values for a in LONG_AXES)
    assert [t.get_text() for t in leg.get_texts()][0] == f"{k[0]:g}, {m[0]:g}, {v[0]:g}"


def test_many_variants_get_a_colour_per_first_axis_value_and_a_line_style_per_second(long_names, opened):
    ds = opened(long_names).dataset  # 12 variants > LEGEND_MAX: colour bar + style legend
    fig = plot_history(ds, "spring_force", ["lower"])
    lines = fig.axes[0].lines
    k = ds["springs.lower.material.stiffness"].values
    m = ds["nodes.top.mass"].values
    pairs = {
        (
            line.get_color() if isinstance(line.get_color(), str) else tuple(line.get_color()),
            line.get_linestyle(),
        )
        for line in lines
    }
    assert len(pairs) == len(set(zip(k, m, strict=True))) == 4  # 2 stiffnesses x 2 masses, each its own look
    for a, b in ((0, 1), (0, 6)):  # same k, other mass: same colour, other style; other k: other colour
        assert (lines[a].get_color() == lines[b].get_color()) == (k[a] == k[b])
        assert (lines[a].get_linestyle() == lines[b].get_linestyle()) == (m[a] == m[b])
    (style_legend,) = fig.legends
    assert style_legend.get_title().get_text().startswith("nodes.top.mass [kg]")
    assert [t.get_text() for t in style_legend.get_texts()] == ["0.5 kg", "1 kg"]
    whole, legends, _, _ = _boxes(fig)
    assert _inside(legends[0], whole)


def test_history_labels_carry_units_and_convert_to_g_and_ms(long_names, opened):
    ds = opened(long_names).dataset
    fig = plot_history(ds, "acceleration", ["top"], time_unit="ms", accel_unit="g")
    ax = fig.axes[0]
    assert ax.get_ylabel() == "acceleration [g]" and ax.get_xlabel() == "time [ms]"
    assert fig._suptitle.get_text() == "plot-long: node acceleration"  # not the internal description
    line = ax.lines[3]
    k = int(line.get_gid().split()[1])
    np.testing.assert_allclose(line.get_xdata(), ds["time"].values * 1e3, rtol=1e-12)
    np.testing.assert_allclose(
        line.get_ydata(),
        ds["acceleration"].sel(node="top").isel(variant=k, axis=0).values / 9.80665,
        rtol=1e-12,
    )


def test_forces_take_an_engineering_prefix():
    from crashstudy.analysis.plot_style import display_scale

    assert display_scale("N", [12.0, -999.0]) == (1.0, "N")
    assert display_scale("N", [1.0, -2.5e3]) == (1e-3, "kN")
    assert display_scale("N", [3.0e6]) == (1e-6, "MN")
    assert display_scale("kN", [2.0e3]) == (1e-3, "MN")  # mm-ms-kg-kN results
    assert display_scale("m/s^2", [1.0], system="SI", accel_unit="g") == (1 / 9.80665, "g")
    assert display_scale("s", time_unit="ms") == (1e3, "ms") and display_scale("ms", time_unit="ms") == (
        1.0,
        "ms",
    )


def test_force_displacement_draws_kilonewtons_when_forces_pass_1000_newtons(long_names, opened):
    ds = opened(long_names).dataset
    f = ds["spring_force"].sel(spring="lower").isel(variant=[0, 11]).values
    assert np.abs(f).max() >= 1e3  # the stiffer spring (1e6 N/m) at 3 m/s: kilonewtons
    ax = plot_force_displacement(ds, ["lower"]).axes[0]
    assert ax.get_ylabel() == "force (+ = tension) [kN]"
    np.testing.assert_allclose(ax.lines[11].get_ydata(), f[1] / 1e3, rtol=1e-12)


def test_matrix_axes_carry_units(long_names, opened):
    res = opened(long_names)
    paths = plot_command(_args(long_names, kind="matrix", output=None))
    assert [p.name for p in paths] == ["matrix-peak_deceleration_g.top.png"]  # named in regression:
    from crashstudy.analysis.plot_matrix import plot_matrix as pm
    from crashstudy.analysis.plot_style import axis_units

    axes = list(LONG_AXES)
    fig = pm(
        res.summary,
        "peak_force.lower",
        x=axes[0],
        y=axes[2],
        axes=axes,
        units="N",
        axis_units=axis_units(res.dataset, axes),
    )
    ax = fig.axes[0]
    assert (
        ax.get_xlabel() == "springs.lower.material.stiffness [N/m]"
        and ax.get_ylabel() == "impact_velocity [m/s]"
    )
    assert fig.axes[1].get_ylabel() == "peak_force.lower [kN]"
    cells = np.ma.filled(ax.images[0].get_array(), np.nan)
    truth = res.summary.pivot_table(index=axes[2], columns=axes[0], values="peak_force.lower", aggfunc="max")
    np.testing.assert_allclose(cells, truth.to_numpy() / 1e3, rtol=1e-12)


def test_matrix_default_is_the_regression_node_else_the_heaviest_free_node(long_names, small, opened):
    from crashstudy.analysis.plot import crash_node

    assert crash_node(opened(long_names).dataset) == "top"  # regression: peak_deceleration_g.top
    assert crash_node(opened(small).dataset) == "base"  # 2 kg; top is 0.5 or 1 kg; ground is fixed


def test_file_names_carry_the_items_so_later_plots_do_not_overwrite_earlier_ones(small, tmp_path):
    first = plot_command(_args(small, items=["lower"], output=str(tmp_path)))
    second = plot_command(_args(small, items=["upper"], output=str(tmp_path)))
    fd = plot_command(_args(small, kind="force-displacement", items=["upper"], output=str(tmp_path)))
    names = [p.name for p in first + second + fd]
    assert names == [
        "history-spring_force-lower.png",
        "history-spring_force-upper.png",
        "force-displacement-upper.png",
    ]
    assert all(p.exists() for p in first + second + fd)


def test_matrix_line_plot_legend_lies_below_the_panel_inside_the_figure(long_names, opened):
    from crashstudy.analysis.plot_matrix import plot_matrix as pm

    fig = pm(opened(long_names).summary, "peak_force.lower", x="impact_velocity")
    whole, legends, _, axes = _boxes(fig)
    assert len(legends) == 1 and len(fig.legends[0].get_texts()) == 4  # 2 stiffnesses x 2 masses
    assert _inside(legends[0], whole) and not _overlap(legends[0], axes[0])
