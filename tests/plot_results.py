"""What the plot tests (tests/test_plot_*.py) share: the small 1-D model, its study run
once per module (``small``) and opened (``opened``; both fixtures registered in conftest.py), and the plot
command's arguments."""

from __future__ import annotations

import argparse
from pathlib import Path

import pytest
import yaml

import crashstudy
import crashstudy.results.store

# Two masses on two linear springs in 1-D, dropped onto a fixed ground node.
MODEL_1D = {
    "name": "plot-two-springs",
    "units": "SI",
    "nodes": {
        "ground": {"position": [0.0], "fixed": True},
        "base": {"position": [0.2], "mass": 2.0},
        "top": {"position": [0.5], "mass": 1.0},
    },
    "springs": {
        "lower": {"nodes": ["ground", "base"], "material": {"type": "linear_elastic", "stiffness": 2.0e4}},
        "upper": {"nodes": ["base", "top"], "material": {"type": "linear_elastic", "stiffness": 1.0e4}},
    },
    "initial_velocity": {"base": [-2.0], "top": [-2.0]},
    "end_time": 0.05,
    "output": {"interval": 5.0e-4},
}
AXES = ["nodes.top.mass", "impact_velocity"]


def _run(tmp: Path, model: dict, matrix: dict, name: str, **study) -> Path:
    tmp.mkdir(parents=True, exist_ok=True)
    (tmp / "model.yaml").write_text(yaml.safe_dump(model, sort_keys=False))
    doc = {"name": name, "model": str(tmp / "model.yaml"), "matrix": matrix, **study}
    out = tmp / "results"
    crashstudy.run_study(doc, out_dir=out, force=True)
    return out


@pytest.fixture(scope="module")
def small(tmp_path_factory) -> Path:
    """2 x 3 matrix, every variant ok, all histories kept."""
    return _run(
        tmp_path_factory.mktemp("small"),
        MODEL_1D,
        {AXES[0]: [0.5, 1.0], AXES[1]: [1.0, 2.0, 3.0]},
        "plot-small",
    )


@pytest.fixture(scope="module")
def opened():
    """Open each result folder once and close it at the end.

    Many simultaneous open handles on one results.nc crash libhdf5 (its variable-length string
    variables; Unidata/netcdf4-python#1444), so tests, like notebooks, should not leak them.
    """
    cache: dict[Path, crashstudy.results.store.Results] = {}

    def open_(directory: Path) -> crashstudy.results.store.Results:
        if directory not in cache:
            cache[directory] = crashstudy.open_results(directory)
        return cache[directory]

    yield open_
    for res in cache.values():
        res.close()


def _args(directory: Path, **kw) -> argparse.Namespace:
    base = {
        "dir": str(directory),
        "kind": "history",
        "quantity": None,
        "items": None,
        "x_axis": None,
        "y_axis": None,
        "max_variants": 50,
        "output": None,
    }
    return argparse.Namespace(**{**base, **kw})


def _notes(fig) -> str:
    return " ".join(t.get_text() for t in fig.texts)
