"""Studies end to end (docs/studies.md, issue 3): the Python API (``run_study``, ``open_results``, the
dataset's units, coordinates and input files) and ``crashstudy summary`` (its ``--sort``).

The test model is a 1-D frontal impact: a crush spring (wall - front mass) and a linear body spring
(front - body), 20 ms at 5 kHz sampling, a few hundred steps: every run here takes milliseconds
(models.TWO_SPRING_CRUSH). What these tests share is in study_cases.py."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest
import xarray as xr
import yaml

import crashstudy
from crashstudy.cli.main import main
from study_cases import AXES

# --------------------------------------------------------------------------------------------------
# Python API and `crashstudy summary`


UNITS_SI = {
    "position": "m",
    "displacement": "m",
    "velocity": "m/s",
    "acceleration": "m/s^2",
    "spring_force": "N",
    "spring_elongation": "m",
    "kinetic_energy": "J",
    "internal_energy": "J",
    "external_work": "J",
    "wall_energy": "J",
    "peak_force": "N",
    "max_crush": "m",
    "absorbed_energy": "J",
    "peak_deceleration": "m/s^2",
    "peak_deceleration_g": "g",
    "energy_error": "1",
    "dt": "s",
    "time": "s",
}


@pytest.fixture(scope="module")
def api_run(
    work: Path, tmp_path_factory: pytest.TempPathFactory
) -> tuple[crashstudy.results.store.Results, dict[str, Any]]:
    study = {
        "name": "api-check",
        "model": str(work / "model.yaml"),
        "matrix": {"nodes.body.mass": [700.0, 900.0], "impact_velocity": [5.0, 8.0, 11.0]},
    }
    cwd = Path.cwd()
    os.chdir(tmp_path_factory.mktemp("api"))  # run_study's default folder is results/<study name>
    try:
        crashstudy.run_study(study)
        folder = Path.cwd() / "results" / "api-check"
    finally:
        os.chdir(cwd)
    assert (folder / "results.nc").exists()
    return crashstudy.open_results(folder), study


def test_run_study_dict_and_open_results_summary_table(api_run: tuple[Any, dict[str, Any]]) -> None:
    res, study = api_run
    s = res.summary
    assert isinstance(s, pd.DataFrame) and len(s) == 6
    assert list(s.columns[:3]) == ["variant", "nodes.body.mass", "impact_velocity"]
    for col in (
        "status",
        "failure_reason",
        "peak_force.crush",
        "peak_force.body",
        "max_crush.crush",
        "absorbed_energy.body",
        "peak_deceleration_g.body",
        "energy_error",
        "dt",
    ):
        assert col in s.columns, col
    np.testing.assert_array_equal(s["nodes.body.mass"], [700.0] * 3 + [900.0] * 3)
    np.testing.assert_array_equal(s["impact_velocity"], [5.0, 8.0, 11.0] * 2)
    assert (s["status"] == "ok").all() and (s["energy_error"] < 1e-3).all()
    ds = res.dataset
    np.testing.assert_array_equal(s["peak_force.crush"].values, ds["peak_force"].sel(spring="crush").values)
    g = ds["peak_deceleration"].values / 9.80665
    np.testing.assert_allclose(ds["peak_deceleration_g"].values, g, rtol=1e-14)
    # a pandas comparison works as the docs show it
    worst = s.groupby("impact_velocity")["peak_deceleration_g.body"].max()
    assert worst.is_monotonic_increasing


def test_dataset_has_units_and_the_input_files_verbatim(
    api_run: tuple[Any, dict[str, Any]], matrix_run: Path, matrix_study: Path, work: Path
) -> None:
    res, study = api_run
    ds = res.dataset
    for name, var in ds.data_vars.items():
        assert var.attrs.get("long_name"), name
        if var.dtype.kind in "fi" and name != "done":
            assert var.attrs.get("units"), name
    for name, unit in UNITS_SI.items():
        assert ds[name].attrs["units"] == unit, name
    assert ds.attrs["model_yaml"] == (work / "model.yaml").read_text()
    assert yaml.safe_load(ds.attrs["study_yaml"]) == study  # a dict study is stored as the YAML it stands for
    m = crashstudy.open_results(matrix_run).dataset
    assert m.attrs["study_yaml"] == matrix_study.read_text()
    assert m.attrs["model_yaml"] == (work / "model.yaml").read_text()


def test_plain_xarray_sees_the_study_axes_as_coordinates(matrix_run: Path) -> None:
    with xr.open_dataset(matrix_run / "results.nc") as ds:
        assert [a for a in AXES if a not in ds.coords] == []


def test_study_axis_coordinates_have_units(api_run: tuple[Any, dict[str, Any]]) -> None:
    ds = api_run[0].dataset
    assert ds["nodes.body.mass"].attrs.get("units") == "kg"
    assert ds["impact_velocity"].attrs.get("units") == "m/s"


def test_every_variable_has_units_and_long_name(api_run: tuple[Any, dict[str, Any]]) -> None:
    ds = api_run[0].dataset
    missing = [n for n, v in ds.variables.items() if "units" not in v.attrs or "long_name" not in v.attrs]
    assert missing == []


def _printed_variants(text: str) -> list[int]:
    """Variant numbers of the rows of a printed summary table (first column = pandas index)."""
    rows = []
    for ln in text.splitlines()[1:]:
        if not ln.strip():  # a wide table continues in a second block: the first one has every row
            break
        if ln.split()[0].isdigit():
            rows.append(ln.split())
    return [int(r[1]) for r in rows]


def test_summary_sort_prints_rows_in_column_order(
    api_run: tuple[Any, dict[str, Any]], capsys: pytest.CaptureFixture[str]
) -> None:
    res, _ = api_run
    s = res.summary
    col = "peak_deceleration_g.body"
    capsys.readouterr()
    assert (
        main(["summary", str(res.dir), "--sort", col, "--columns", "peak_deceleration_g", "--head", "0"]) == 0
    )
    out = capsys.readouterr().out
    assert col in out  # a header (the table wraps at the terminal width, the axes first)
    order = _printed_variants(out)
    assert order == s.sort_values(col, ascending=False)["variant"].tolist()
    assert len(order) == 6 and np.all(np.diff(s.set_index("variant").loc[order, col].values) <= 0)
    assert (
        main(
            [
                "summary",
                str(res.dir),
                "--sort",
                "impact_velocity",
                "--ascending",
                "--head",
                "0",
                "--columns",
                "impact_velocity",
            ]
        )
        == 0
    )
    order = _printed_variants(capsys.readouterr().out)
    assert np.all(np.diff(s.set_index("variant").loc[order, "impact_velocity"].values) >= 0)
    assert main(["summary", str(res.dir), "--sort", col, "--head", "2"]) == 0
    out = capsys.readouterr().out
    assert _printed_variants(out) == s.sort_values(col, ascending=False)["variant"].tolist()[:2]
    assert "4 more rows" in out


def test_summary_unknown_sort_column_exits_2_naming_similar_columns(
    api_run: tuple[Any, dict[str, Any]], capsys: pytest.CaptureFixture[str]
) -> None:
    res, _ = api_run
    capsys.readouterr()
    assert main(["summary", str(res.dir), "--sort", "peak_force"]) == 2
    err = capsys.readouterr().err
    assert "peak_force.crush" in err and "peak_force.body" in err and "Traceback" not in err


def test_summary_misspelt_sort_column_suggests_the_close_ones(
    api_run: tuple[Any, dict[str, Any]], capsys: pytest.CaptureFixture[str]
) -> None:
    res, _ = api_run
    capsys.readouterr()
    assert main(["summary", str(res.dir), "--sort", "peak_forse.crush"]) == 2
    err = capsys.readouterr().err
    assert "peak_force.crush" in err
    assert "dt_control" not in err and "final_kinetic_energy" not in err
