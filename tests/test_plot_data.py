"""crashstudy.analysis.plot: the figures draw the result data exactly (failed variants skipped, many
variants coloured and thinned), write real PNGs from the API and the command line, and refuse bad names."""

from __future__ import annotations

from pathlib import Path

import matplotlib.image
import numpy as np
import pytest

from crashstudy.analysis.plot import (
    plot_force_displacement,
    plot_history,
    plot_matrix,
    select_variants,
)
from crashstudy.cli import main as cli_module
from crashstudy.cli.plot import plot_command
from crashstudy.errors import InputError
from plot_results import AXES, MODEL_1D, _args, _notes, _run

# One mass on one linear spring, 2-D, moving down and sideways: the magnitude differs from |y|.
MODEL_2D = {
    "name": "plot-2d",
    "units": "SI",
    "nodes": {
        "ground": {"position": [0.0, 0.0], "fixed": True},
        "mass": {"position": [0.0, 0.3], "mass": 1.0},
    },
    "springs": {
        "spring": {"nodes": ["ground", "mass"], "material": {"type": "linear_elastic", "stiffness": 1.0e4}}
    },
    "initial_velocity": {"mass": [0.5, -2.0]},
    "end_time": 0.03,
    "output": {"interval": 5.0e-4},
}


@pytest.fixture(scope="module")
def with_failures(tmp_path_factory) -> Path:
    """3 stiffnesses x 6 speeds with a fixed dt: the stiffest 6 variants exceed dt_crit and fail."""
    model = {**MODEL_1D, "time_step": {"dt": 2.0e-4}}
    return _run(
        tmp_path_factory.mktemp("failures"),
        model,
        {
            "springs.lower.material.stiffness": [1.0e4, 2.0e4, 1.0e9],
            "impact_velocity": [1.0, 1.5, 2.0, 2.5, 3.0, 3.5],
        },
        "plot-failures",
    )


@pytest.fixture(scope="module")
def no_histories(tmp_path_factory) -> Path:
    return _run(
        tmp_path_factory.mktemp("nohist"),
        MODEL_1D,
        {AXES[0]: [0.5, 1.0], AXES[1]: [1.0, 2.0]},
        "plot-nohist",
        set={"output": {"histories": "none"}},
    )


def _assert_real_png(path: Path) -> None:
    img = matplotlib.image.imread(path)
    assert img.ndim == 3 and img.shape[0] >= 300 and img.shape[1] >= 500, img.shape
    assert float(img[..., :3].std()) > 0.01  # not blank


# --- data drawn -----------------------------------------------------------------------------------


def test_history_lines_are_the_dataset_values_of_each_variant(small, opened):
    ds = opened(small).dataset
    fig = plot_history(ds, "spring_force")
    panels = [ax for ax in fig.axes if ax.get_title()]
    assert [ax.get_title() for ax in panels] == ["spring lower", "spring upper"]
    for ax, spring in zip(panels, ["lower", "upper"], strict=True):
        assert len(ax.lines) == 6  # every variant, in variant order
        assert ax.get_ylabel() == "spring force [N]"
        for v, line in enumerate(ax.lines):
            expected = ds["spring_force"].sel(spring=spring).isel(variant=v).values
            np.testing.assert_array_equal(line.get_xdata(), ds["time"].values)
            np.testing.assert_array_equal(line.get_ydata(), expected)
    # and the drawn numbers are the physics: the sampled peak |force| of the lower spring is the
    # summary's peak (computed from every step) within one sampling interval of a sine, 1e-2
    peaks = np.array([np.nanmax(np.abs(line.get_ydata())) for line in panels[0].lines])
    summary = opened(small).summary["peak_force.lower"].to_numpy()
    np.testing.assert_allclose(peaks, summary, rtol=1e-2)
    assert fig.get_suptitle().startswith("plot-small:")


def test_history_node_quantity_defaults_to_free_nodes_and_is_signed_in_1d(small, opened):
    ds = opened(small).dataset
    fig = plot_history(ds, "velocity")
    panels = [ax for ax in fig.axes if ax.get_title()]
    assert [ax.get_title() for ax in panels] == ["node base", "node top"]  # the fixed ground is left out
    v0 = panels[1].lines[2].get_ydata()[0]
    assert v0 == pytest.approx(-3.0, abs=1e-12)  # variant 2: impact_velocity 3, moving in -x
    assert panels[0].get_ylabel() == "velocity [m/s]"


def test_history_2d_node_quantity_is_the_magnitude_unless_a_component_is_named(tmp_path, opened):
    out = _run(tmp_path, MODEL_2D, {"impact_velocity": [1.0, 2.0]}, "plot-2d")
    ds = opened(out).dataset
    vel = ds["velocity"].sel(node="mass").isel(variant=1).values  # (time, axis)
    mag = plot_history(ds, "velocity", ["mass"]).axes[0]
    np.testing.assert_allclose(mag.lines[1].get_ydata(), np.hypot(vel[:, 0], vel[:, 1]), rtol=1e-14)
    assert mag.lines[1].get_ydata()[0] == pytest.approx(2.0, rel=1e-12)  # impact speed, direction kept
    assert mag.get_ylabel() == "|velocity| [m/s]"
    comp = plot_history(ds, "velocity.y", ["mass"]).axes[0]
    np.testing.assert_array_equal(comp.lines[1].get_ydata(), vel[:, 1])
    assert comp.get_ylabel() == "velocity y [m/s]"


def test_force_displacement_lines_are_force_against_crush(small, opened):
    ds = opened(small).dataset
    fig = plot_force_displacement(ds, ["upper"])
    ax = fig.axes[0]
    assert ax.get_title() == "spring upper"
    for v, line in enumerate(ax.lines[:6]):
        sel = {"spring": "upper", "variant": v}
        np.testing.assert_array_equal(line.get_xdata(), -ds["spring_elongation"].sel(sel).values)
        np.testing.assert_array_equal(line.get_ydata(), ds["spring_force"].sel(sel).values)
        # a linear spring: every point on F = -k * crush, k = 1e4 N/m, to round-off
        np.testing.assert_allclose(line.get_ydata(), -1.0e4 * line.get_xdata(), rtol=1e-9, atol=1e-9)
    assert ax.get_xlabel() == "crush = -elongation [m]"


def test_matrix_heat_map_cells_equal_the_summary_pivot(small, opened):
    summary = opened(small).summary
    fig = plot_matrix(summary, y="impact_velocity")  # default metric: the worst free node; x: first axis
    ax = fig.axes[0]
    pivot = summary.pivot(index="impact_velocity", columns="nodes.top.mass", values="peak_deceleration_g.top")
    cells = np.ma.filled(ax.images[0].get_array(), np.nan)
    np.testing.assert_array_equal(cells, pivot.to_numpy())
    assert cells.shape == (3, 2)
    assert ax.get_xlabel() == "nodes.top.mass" and ax.get_ylabel() == "impact_velocity"
    assert [t.get_text() for t in ax.get_xticklabels()] == ["0.5", "1"]
    assert len(ax.texts) == 6  # small map: every cell annotated
    # linear springs: peak deceleration is proportional to the impact speed (exact scaling), 1e-9
    np.testing.assert_allclose(cells / cells[0], [[1, 1], [2, 2], [3, 3]], rtol=1e-9)


def test_matrix_default_metric_is_the_free_node_that_decelerates_most(small, opened):
    summary = opened(small).summary
    from crashstudy.analysis.plot import default_metric

    assert summary["peak_deceleration_g.top"].max() > summary["peak_deceleration_g.base"].max()
    assert default_metric(summary) == "peak_deceleration_g.top"


def test_matrix_one_axis_draws_one_line_per_value_of_the_other(small, opened):
    summary = opened(small).summary
    ax = plot_matrix(summary, "peak_force.lower", x="impact_velocity").axes[0]
    assert len(ax.lines) == 2
    for line, mass in zip(ax.lines, [0.5, 1.0], strict=True):
        rows = summary[summary["nodes.top.mass"] == mass].sort_values("impact_velocity")
        np.testing.assert_array_equal(line.get_xdata(), [1.0, 2.0, 3.0])
        np.testing.assert_array_equal(line.get_ydata(), rows["peak_force.lower"].to_numpy())
        assert line.get_label() == f"nodes.top.mass={mass:g}"


# --- failed variants, many variants, thinning ---------------------------------------------------------


def test_failed_variants_are_skipped_and_counted(with_failures, opened):
    res = opened(with_failures)
    status = res.summary["status"].to_numpy()
    assert (status != "ok").sum() == 6 and (status == "ok").sum() == 12
    fig = plot_history(res.dataset, "spring_force", ["lower"])
    ax = fig.axes[0]
    assert len(ax.lines) == 12
    assert {line.get_gid() for line in ax.lines} == {f"variant {v}" for v in np.nonzero(status == "ok")[0]}
    assert "6 failed variants skipped" in _notes(fig)
    heat = plot_matrix(res.summary, "peak_force.lower", y="impact_velocity")
    assert "6 failed variants skipped" in _notes(heat)
    cells = np.ma.filled(heat.axes[0].images[0].get_array(), np.nan)
    assert np.isnan(cells[:, 2]).all() and np.isfinite(cells[:, :2]).all()  # stiffest column: failed


def test_many_variants_are_coloured_by_the_first_axis_with_a_colour_bar(with_failures, opened):
    ds = opened(with_failures).dataset
    fig = plot_history(ds, "spring_force", ["lower"])
    bars = [ax for ax in fig.axes if ax.get_label() == "<colorbar>"]
    assert (
        len(bars) == 1 and bars[0].get_ylabel() == "springs.lower.material.stiffness [N/m]"
    )  # with its unit
    colours = {line.get_gid(): line.get_color() for line in fig.axes[0].lines}
    k = ds["springs.lower.material.stiffness"].values
    same = [f"variant {v}" for v in range(18) if k[v] == 1.0e4]
    assert len({colours[g] for g in same}) == 1  # one axis value, one colour
    assert colours["variant 0"] != colours["variant 6"]  # k = 1e4 vs 2e4


def test_max_variants_thins_evenly_and_says_so(with_failures, opened):
    ds = opened(with_failures).dataset
    index, note = select_variants(ds, 4)
    assert list(index) == [0, 4, 7, 11]  # of the 12 ok variants 0..11, evenly spaced
    assert "showing 4 of 12 variants" in note and "6 failed" in note
    fig = plot_force_displacement(ds, ["lower"], max_variants=4)
    drawn = [line.get_gid() for line in fig.axes[0].lines if line.get_gid()]  # not the zero lines
    assert drawn == ["variant 0", "variant 4", "variant 7", "variant 11"]


# --- errors ---------------------------------------------------------------------------------------


def test_missing_histories_ask_for_a_rerun_but_matrix_still_works(no_histories, capsys, opened):
    ds = opened(no_histories).dataset
    with pytest.raises(InputError, match="re-run the study with histories"):
        plot_history(ds)
    for kind in ("history", "force-displacement"):
        assert cli_module.main(["plot", str(no_histories), "--kind", kind]) == 2
        assert "re-run the study with histories" in capsys.readouterr().err
    paths = plot_command(_args(no_histories, kind="matrix"))
    assert len(paths) == 1
    _assert_real_png(paths[0])


@pytest.mark.parametrize(
    ("kw", "valid"),
    [
        ({"quantity": "spring_forse"}, "valid: position, displacement"),
        ({"items": ["middle"]}, "valid springs: lower, upper"),
        ({"quantity": "acceleration", "items": ["ground", "roof"]}, "valid nodes: ground, base, top"),
        ({"kind": "force-displacement", "items": ["nope"]}, "valid springs: lower, upper"),
        ({"kind": "matrix", "x_axis": "mass"}, "valid axes: nodes.top.mass, impact_velocity"),
        ({"kind": "matrix", "quantity": "peak_forse"}, "valid: absorbed_energy"),
        ({"kind": "matrix", "quantity": "peak_force", "items": ["middle"]}, "valid items: lower, upper"),
    ],
)
def test_unknown_names_are_input_errors_listing_the_valid_ones(small, tmp_path, kw, valid):
    with pytest.raises(InputError) as exc:
        plot_command(_args(small, output=str(tmp_path), **kw))
    assert valid in str(exc.value)
    assert str(small) in str(exc.value)


# --- files and command line -----------------------------------------------------------------------------


@pytest.mark.parametrize("kind", ["history", "force-displacement", "matrix"])
def test_each_kind_writes_a_real_png(small, tmp_path, kind):
    paths = plot_command(_args(small, kind=kind, output=str(tmp_path / "png")))
    assert len(paths) == 1 and paths[0].parent == tmp_path / "png" and paths[0].suffix == ".png"
    _assert_real_png(paths[0])


def test_matrix_by_metric_name_and_items_writes_one_png_per_item(small, tmp_path):
    paths = plot_command(
        _args(small, kind="matrix", quantity="peak_force", items=["lower", "upper"], output=str(tmp_path))
    )
    assert [p.name for p in paths] == ["matrix-peak_force.lower.png", "matrix-peak_force.upper.png"]


def test_energy_history_is_one_panel_and_takes_no_items(small, tmp_path, opened):
    ds = opened(small).dataset
    fig = plot_history(ds, "kinetic_energy")
    assert len(fig.axes[0].lines) == 6 and fig.axes[0].get_ylabel() == "kinetic energy [J]"
    # 0.5 * (m_base + m_top) * v^2 at t = 0: variant 5 has m_top = 1 kg, v = 3 m/s
    assert fig.axes[0].lines[5].get_ydata()[0] == pytest.approx(0.5 * 3.0 * 3.0**2, rel=1e-12)
    with pytest.raises(InputError, match="has no items"):
        plot_command(_args(small, quantity="kinetic_energy", items=["top"], output=str(tmp_path)))


def test_cli_main_matrix_returns_0_and_prints_the_paths(small, capsys):
    assert cli_module.main(["plot", str(small), "--kind", "matrix"]) == 0
    out = capsys.readouterr().out.strip().splitlines()
    # the heaviest free node (base, 2 kg; top: 0.5 or 1 kg), not the one that decelerates most
    assert out == [f"wrote {small / 'plots' / 'matrix-peak_deceleration_g.base.png'}"]
    _assert_real_png(small / "plots" / "matrix-peak_deceleration_g.base.png")


def test_real_command_line_writes_history_png(small, tmp_path, cli):
    proc = cli(
        "plot",
        str(small),
        "--kind",
        "history",
        "--items",
        "upper",
        "--max-variants",
        "3",
        "-o",
        str(tmp_path),
    )
    assert proc.returncode == 0, proc.stderr
    path = tmp_path / "history-spring_force-upper.png"  # the items are part of the name
    assert proc.stdout.strip() == f"wrote {path}"
    _assert_real_png(path)
    bad = cli("plot", str(small), "--quantity", "nonsense", "-o", str(tmp_path))
    assert bad.returncode == 2 and "Traceback" not in bad.stderr and "valid:" in bad.stderr
