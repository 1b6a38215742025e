"""Planted symbolic links in a result folder never make a run write outside it (issue 14 item 2)."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import xarray as xr
import yaml

from helpers import run_cli

MODEL = {
    "name": "link-probe",
    "units": "SI",
    "nodes": {"a": {"position": [0.0], "fixed": True}, "b": {"position": [1.0], "mass": 1.0}},
    "springs": {"s": {"nodes": ["a", "b"], "material": {"type": "linear_elastic", "stiffness": 100.0}}},
    "initial_velocity": {"b": [1.0]},
    "end_time": 0.05,
    "output": {"histories": "none"},
}


def _study(tmp: Path) -> Path:
    (tmp / "model.yaml").write_text(yaml.safe_dump(MODEL, sort_keys=False))
    study = tmp / "study.yaml"
    study.write_text(
        yaml.safe_dump(
            {"name": "links", "model": "model.yaml", "matrix": {"nodes.b.mass": [1.0, 4.0]}}, sort_keys=False
        )
    )
    return study


def _peak_forces_are_right(out: Path) -> None:
    """F(t) = v0 sqrt(k m) sin(t sqrt(k/m)), rising until the end time 0.05 s for both masses."""
    with xr.open_dataset(out / "results.nc") as ds:
        got = ds["peak_force"].values.ravel()
    m = np.array([1.0, 4.0])
    np.testing.assert_allclose(got, np.sqrt(100.0 * m) * np.sin(0.05 * np.sqrt(100.0 / m)), rtol=2e-3)


def test_link_at_summary_partial_does_not_overwrite_its_target(tmp_path: Path) -> None:
    study = _study(tmp_path)
    victim = tmp_path / "victim.txt"
    victim.write_text("precious\n")
    out = tmp_path / "out"
    out.mkdir()
    (out / "summary.csv.partial").symlink_to(victim)
    done = run_cli("run", str(study), "-o", str(out))
    assert done.returncode == 0, done.stderr
    assert victim.read_text() == "precious\n"
    assert not os.path.islink(out / "summary.csv") and (out / "summary.csv").read_text().count("\n") == 3
    _peak_forces_are_right(out)


def test_dangling_link_at_results_partial_is_refused_or_removed_never_followed(tmp_path: Path) -> None:
    study = _study(tmp_path)
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    out = tmp_path / "out"
    out.mkdir()
    (out / "results.nc.partial").symlink_to(elsewhere / "stolen.nc")
    plain = run_cli(
        "run", str(study), "-o", str(out)
    )  # looks like an unfinished run: refused, nothing written
    assert plain.returncode == 2 and "unfinished run" in plain.stderr and "Traceback" not in plain.stderr
    resume = run_cli("run", str(study), "-o", str(out), "--resume")
    assert resume.returncode == 2 and "symbolic link" in resume.stderr and "Traceback" not in resume.stderr
    assert list(elsewhere.iterdir()) == []
    forced = run_cli("run", str(study), "-o", str(out), "--force")
    assert forced.returncode == 0, forced.stderr
    assert list(elsewhere.iterdir()) == []
    assert not os.path.islink(out / "results.nc") and (out / "results.nc").is_file()
    assert not os.path.lexists(out / "results.nc.partial")
    _peak_forces_are_right(out)
