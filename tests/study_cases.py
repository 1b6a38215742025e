"""What the study tests (tests/test_study_*.py) share: the 1-D frontal-impact test model, the 3 x 4 x 5
matrix crossed with a zip group of 2 (120 variants), the study's working folder and its run (the fixtures
``work``, ``matrix_study`` and ``matrix_run``, registered in conftest.py), and writing and reading files."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
import xarray as xr
import yaml

from crashstudy.run.runner import run_plan
from crashstudy.study.plan import load_study
from models import TWO_SPRING_CRUSH as MODEL

# the 3 x 4 x 5 matrix crossed with a zip group of 2 (120 variants)
MASSES = [600.0, 800.0, 1000.0]
SCALES = [0.8, 1.0, 1.2, 1.5]
SPEEDS = [4.0, 6.0, 8.0, 10.0, 12.0]
ZIP_K = [1.5e6, 3.0e6]
ZIP_M = [40.0, 60.0]
AXES = [
    "nodes.body.mass",
    "curves.crush-loading.scale",
    "impact_velocity",
    "springs.body.material.stiffness",
    "nodes.front.mass",
]


def dump(path: Path, data: dict[str, Any]) -> Path:
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def load_ds(directory: Path) -> xr.Dataset:
    with xr.open_dataset(directory / "results.nc") as ds:
        return ds.load()


@pytest.fixture(scope="module")
def work(tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = tmp_path_factory.mktemp("study")
    dump(d / "model.yaml", MODEL)
    return d


@pytest.fixture(scope="module")
def matrix_study(work: Path) -> Path:
    study = {
        "name": "order-check",
        "model": "model.yaml",
        "matrix": {AXES[0]: MASSES, AXES[1]: SCALES, AXES[2]: SPEEDS},
        "zip": [{AXES[3]: ZIP_K, AXES[4]: ZIP_M}],
    }
    return dump(work / "matrix.yaml", study)


@pytest.fixture(scope="module")
def matrix_run(matrix_study: Path, work: Path) -> Path:
    """The 120-variant study, in-process, jobs=1, in chunks of 16 (so several chunks and a short last one)."""
    out = work / "matrix-out"
    run_plan(load_study(matrix_study), out, jobs=1, chunk=16, progress=False)
    return out
