"""Provenance and reuse: hashes recorded, unchanged variants reused bit for bit, changed ones recomputed."""

from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from crashstudy.cli.main import main
from crashstudy.results.store import open_results

MODEL = """\
name: reuse-model
nodes:
  wall: {position: [0.0], fixed: true}
  body: {position: [1.0], mass: 2.0}
springs:
  s: {nodes: [wall, body], material: {type: linear_elastic, stiffness: 2.0e4}}
initial_velocity: {body: [-3.0]}
end_time: 0.05
"""


def _study(tmp: Path, masses: str, name: str = "reuse") -> Path:
    (tmp / "model.yaml").write_text(MODEL)
    study = tmp / "study.yaml"
    study.write_text(
        f"name: {name}\nmodel: model.yaml\nmatrix:\n  nodes.body.mass: {masses}\n  impact_velocity: [1.0, 2.0]\n"
    )
    return study


def _identical(a: xr.Dataset, b: xr.Dataset) -> None:
    for name in a.variables:
        if name == "input_hash" or a[name].dtype.kind in "OSU":
            assert (a[name].values == b[name].values).all(), name
        else:
            np.testing.assert_array_equal(a[name].values, b[name].values, err_msg=name)


@pytest.mark.parametrize("store", ["netcdf", "zarr"])
def test_rerun_reuses_unchanged_variants_and_recomputes_changed_ones(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], store: str
) -> None:
    study = _study(tmp_path, "[1.0, 2.0, 3.0]")
    out = tmp_path / "out"
    assert main(["run", str(study), "-o", str(out), "--store", store]) == 0
    first = capsys.readouterr().out
    assert "6 variants computed" in first
    assert main(["run", str(study), "-o", str(out)]) == 0
    assert "0 variants computed" in capsys.readouterr().out  # unchanged study: everything reused

    study.write_text(study.read_text().replace("[1.0, 2.0, 3.0]", "[1.0, 2.5, 3.0]"))
    assert main(["run", str(study), "-o", str(out)]) == 0
    assert "2 variants computed" in capsys.readouterr().out  # only the two variants with the new mass
    reused = open_results(out).dataset.load()

    assert open_results(out).final == f"results.{'zarr' if store == 'zarr' else 'nc'}"
    fresh_dir = tmp_path / "fresh"
    assert main(["run", str(study), "-o", str(fresh_dir)]) == 0  # netCDF: the same numbers in either store
    fresh = open_results(fresh_dir).dataset.load()
    _identical(fresh, reused)  # reuse gives exactly the numbers a fresh run gives
    assert np.allclose(fresh["nodes.body.mass"].values, [1.0, 1.0, 2.5, 2.5, 3.0, 3.0])


def test_results_record_version_content_hashes_and_per_variant_hashes(tmp_path: Path) -> None:
    study = _study(tmp_path, "[1.0, 2.0]")
    assert main(["run", str(study), "-o", str(tmp_path / "out")]) == 0
    ds = open_results(tmp_path / "out").dataset
    assert ds.attrs["crashstudy_version"]
    assert ds.attrs["study_sha256"] == hashlib.sha256(study.read_text().encode()).hexdigest()
    assert ds.attrs["model_sha256"] == hashlib.sha256(MODEL.encode()).hexdigest()
    hashes = ds["input_hash"].values
    assert hashes.shape == (4, 2) and hashes.dtype == np.uint64
    assert len({tuple(h) for h in hashes}) == 4  # 128-bit hashes of the four different variants


def test_force_recomputes_and_another_study_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    study = _study(tmp_path, "[1.0, 2.0]")
    out = tmp_path / "out"
    assert main(["run", str(study), "-o", str(out)]) == 0
    assert main(["run", str(study), "-o", str(out), "--force"]) == 0
    assert "4 variants computed" in capsys.readouterr().out
    other = _study(tmp_path, "[1.0, 2.0]", name="other")
    assert main(["run", str(other), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert "holds the results of 'reuse'" in err and "--force" in err


def test_adding_accuracy_check_in_set_recomputes_every_variant_with_its_estimate(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Everything that changes results is in the reuse key (issue 14 item 11): a re-run with
    ``accuracy_check: true`` added in ``set:`` recomputes all 4 variants, and each gets an error
    estimate; for this linear spring the estimate is that of a second-order method, below 1e-3."""
    study = _study(tmp_path, "[1.0, 2.0]")
    out = tmp_path / "out"
    assert main(["run", str(study), "-o", str(out)]) == 0
    assert open_results(out).summary["error_estimate"].isna().all()
    study.write_text(study.read_text() + "set: {accuracy_check: true}\n")
    assert main(["run", str(study), "-o", str(out)]) == 0
    assert "4 variants computed" in capsys.readouterr().out
    est = open_results(out).summary["error_estimate"].to_numpy()
    assert np.all(np.isfinite(est)) and np.all(est < 1e-3)
