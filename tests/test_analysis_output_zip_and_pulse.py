"""Issue 23 items 9-10: what the analysis commands show: a zip group is one factor (heat map footnote,
legend, sensitivity and compare), and the pulse is signed along the direction of travel.

The study of most tests is described in analysis_study.py."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from crashstudy.results.store import open_results

# ---- item 9: a zip group is one factor -----------------------------------------------------------------------------

SIX = [f"springs.rail{i}.material.stiffness" for i in range(6)]


def _six_zip() -> tuple[object, dict[str, str], list[str]]:
    """A summary over impact_velocity (3) x nodes.m.mass (4) x a zip group of six stiffnesses (3): 36 variants,
    metric = v * m * (first stiffness), and the attributes a results file would hold."""
    import itertools
    import json

    import pandas as pd

    axes = ["impact_velocity", "nodes.m.mass", *SIX]
    rows = []
    for i, (v, m, z) in enumerate(
        itertools.product([10.0, 12.0, 14.0], [1.0, 2.0, 3.0, 4.0], [1.0, 2.0, 3.0])
    ):
        rows.append(
            {
                "variant": i,
                "impact_velocity": v,
                "nodes.m.mass": m,
                **{p: z * (k + 1) for k, p in enumerate(SIX)},
                "status": "ok",
                "peak_force.rail0": v * m * z,
            }
        )
    zipped = {p: [1.0 * (k + 1), 2.0 * (k + 1), 3.0 * (k + 1)] for k, p in enumerate(SIX)}
    attrs = {
        "study_yaml": yaml.safe_dump({"name": "z", "model": "m.yaml", "zip": [zipped]}),
        "crashstudy_axes": json.dumps(axes),
        "units": "SI",
    }
    return pd.DataFrame(rows), attrs, axes


def test_heat_map_footnote_names_the_zip_group_once_and_fits_the_image(tmp_path: Path) -> None:
    """Before: 'each cell: max over' all six paths, cut off at the right edge of the image."""
    from crashstudy.analysis.factors import factors
    from crashstudy.analysis.plot_matrix import plot_matrix

    df, attrs, axes = _six_zip()
    fig = plot_matrix(
        df, "peak_force.rail0", "impact_velocity", "nodes.m.mass", axes=axes, factors=factors(attrs, axes)
    )
    fig.savefig(tmp_path / "heat.png")
    note = next(t for t in fig.texts if "each cell" in t.get_text())
    text = note.get_text()
    assert "zip: springs.rail0.material.stiffness" in text and "(6 paths)" in text and SIX[3] not in text
    assert note.get_window_extent(fig.canvas.get_renderer()).x1 <= fig.bbox.width  # type: ignore[attr-defined]
    cells = fig.axes[0].images[0].get_array()
    assert float(cells.max()) == pytest.approx(14.0 * 4.0 * 3.0)  # max over the zip factor's three values
    fig = plot_matrix(
        df, "peak_force.rail0", SIX[2], "impact_velocity", axes=axes, factors=factors(attrs, axes)
    )
    moved = " ".join(t.get_text().replace("\n", " ") for t in fig.texts)
    assert f"{SIX[2]} moves with" in moved and "each cell: max over nodes.m.mass" in moved
    with pytest.raises(Exception, match="move together"):
        plot_matrix(df, "peak_force.rail0", SIX[0], SIX[1], axes=axes, factors=factors(attrs, axes))


def test_legend_names_the_zip_group_once_and_labels_hold_one_value_per_factor() -> None:
    """Before: 'lines differing only in' the six paths that cannot differ; labels of eight numbers."""
    import xarray as xr
    from matplotlib.figure import Figure

    from crashstudy.analysis.plot_style import Variants

    df, attrs, axes = _six_zip()
    ds = xr.Dataset(
        {a: ("variant", df[a].to_numpy(), {"units": "N/m" if "rail" in a else "m/s"}) for a in axes},
        coords={"variant": df["variant"].to_numpy()},
        attrs=attrs,
    )
    look = Variants(ds, np.arange(36), axes)
    fig = Figure()
    look.decorate(fig, [fig.subplots()])
    title = fig._crashstudy_legends[0].get_title().get_text().replace("\n", " ")  # type: ignore[attr-defined]
    assert (
        "differing only in zip: springs.rail0.material.stiffness, springs.rail1.material.stiffness, ... (6 paths)"
        in title
    )
    assert SIX[4] not in title
    few = Variants(ds, np.arange(3), axes)
    assert few.labels == ["10, 1, 1", "10, 1, 2", "10, 1, 3"]


def test_sensitivity_has_one_row_per_factor_and_compare_one_parameter_per_factor() -> None:
    """Before: six identical correlation rows, one per zipped path, and a 330-character parameter column."""
    from crashstudy.analysis.compare import Comparison
    from crashstudy.analysis.factors import factors
    from crashstudy.analysis.sensitivity import indices

    df, attrs, axes = _six_zip()
    t = indices(df, attrs, "peak_force.rail0", "correlation")
    assert sorted(set(t["axis"])) == sorted(
        [
            "impact_velocity",
            "nodes.m.mass",
            "zip: springs.rail0.material.stiffness, springs.rail1.material.stiffness, ... (6 paths)",
        ]
    )
    assert len(t) == 3 * 2
    from scipy import stats

    rho = t.set_index(["axis", "index"])["value"]
    zip_name = next(a for a in t["axis"] if a.startswith("zip:"))
    assert rho[(zip_name, "spearman")] == pytest.approx(
        stats.spearmanr(df[SIX[5]], df["peak_force.rail0"])[0], abs=1e-12
    )
    cmp = Comparison.__new__(Comparison)
    cmp.axes, cmp.factors = axes, factors(attrs, axes)
    text = cmp._params(df.iloc[5])
    assert text == "impact_velocity=10 nodes.m.mass=2 springs.rail0.material.stiffness=3 (+5 zipped)"


# ---- item 10: the pulse is signed along the direction of travel ---------------------------------------------------


def test_pulse_plot_draws_the_signed_deceleration_along_the_travel(tied: Path) -> None:
    """The body travels in -x; its acceleration is the spring forces over its mass, a_x = -(F_pad + F_ep) / m
    (second implementation: the spring_force history), so the deceleration along the travel is
    -a . (-x) = a_x. Before: the resultant |a| (never negative), so the pull-back after 70 ms looked like more
    deceleration. After: the raw line is -(F_pad + F_ep) / (m g) to 1e-9, negative once the springs stretch,
    and the filtered line has the magnitude of the filtered_acceleration history and that sign."""
    from crashstudy.analysis.plot_pulse import plot_pulse

    res = open_results(tied)
    try:
        ds = res.dataset
        fig = plot_pulse(ds)
        f = ds["spring_force"].values  # (variant, time, spring)
        mass = ds["nodes.body.mass"].values
        stored = ds["filtered_acceleration"].sel(node="body").values
        t_ms = ds["time"].values * 1e3
    finally:
        res.close()
    lines = fig.axes[0].lines
    for j in range(4):
        raw, filt = lines[2 * j].get_ydata(), lines[2 * j + 1].get_ydata()
        truth = -(f[j, :, 0] + f[j, :, 1]) / mass[j] / 9.80665
        assert np.allclose(raw, truth, rtol=1e-9, atol=1e-9 * np.abs(truth).max())
        late = t_ms > 100.0
        assert np.all(raw[late] < -3.0) and np.all(filt[late] < -3.0)  # pulled back along the travel
        assert np.allclose(np.abs(filt), stored[j], rtol=1e-12, equal_nan=True)
        assert filt[np.argmin(np.abs(t_ms - 30.0))] > 5.0  # decelerating while the springs compress


def test_sensitivity_over_time_has_one_curve_per_factor(tied: Path) -> None:
    """--history: the zip group of three paths is one curve (before: three identical ones)."""
    from crashstudy.analysis.sensitivity import over_time

    res = open_results(tied)
    try:
        da = over_time(res.dataset, "spring_force", "pad")
    finally:
        res.close()
    assert list(da["axis_path"].values) == [
        "impact_velocity",
        "zip: springs.ep.material.yield_force, springs.ep.material.tangent_stiffness, ... (3 paths)",
    ]
