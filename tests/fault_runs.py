"""What the fault tests (tests/test_faults_*.py) share: the fault study, a ``crashstudy run`` in the
background that reads its progress line, the checks of an unfinished or resumed result, and the fixtures
``fault_dir`` and ``reference`` (registered in conftest.py).

The contract under test (docs/studies.md, issue 5): an interrupted or failed run never leaves a ``results.nc`` (only
``results.nc.partial``, which ``crashstudy summary`` and ``open_results`` refuse), says what happened in a
short message without a traceback, and ``crashstudy run --resume`` then completes with results identical to
an uninterrupted run, variable by variable (NaN where the reference has NaN) and attribute by attribute.

The interrupted study (``FAULT_STUDY``) is 500 variants of a one-spring model with ``histories: none`` and
a 2e-5 s history interval over 2 s: the kernel's per-variant energy buffer (100 001 samples) keeps chunks
at 83 variants, so the run writes 7 chunks in a few seconds and a signal can land between chunks. Each
test waits for the progress line (``--progress on``) to show finished chunks before it strikes.

Outcomes, including the ones marked ``xfail(strict=True)`` (bugs, see their reasons), are tabulated in
docs/robustness.md."""

from __future__ import annotations

from pathlib import Path

import pandas as pd
import pytest
import xarray as xr

from helpers import run_cli as cli  # the command line in this process (helpers.run_cli)

FAULT_MODEL = """\
name: fault-model
description: one linear spring and a mass; many history samples so that chunks are small
units: SI
nodes:
  anchor: {position: [0.0], fixed: true}
  body:   {position: [0.1], mass: 2.0}
springs:
  spring:
    nodes: [anchor, body]
    material: {type: linear_elastic, stiffness: 2.0e4}
initial_velocity: {body: [1.0]}
end_time: 2.0
time_step: {dt: 4.0e-6}  # 500,000 steps: a run long enough to be stopped midway on a fast machine
output: {interval: 2.0e-5, histories: none}
"""

FAULT_STUDY = """\
name: fault-study
model: models/fault-model.yaml
matrix:
  nodes.body.mass: [1.0, 1.5, 2.0, 2.5, 3.0, 3.5, 4.0, 4.5, 5.0, 5.5]
  springs.spring.material.stiffness: [1.0e4, 1.5e4, 2.0e4, 2.5e4, 3.0e4, 3.5e4, 4.0e4, 4.5e4, 5.0e4, 5.5e4]
  impact_velocity: [1.0, 2.0, 3.0, 4.0, 5.0]
"""

SMALL_STUDY = """\
name: small-study
model: models/fault-model.yaml
matrix:
  nodes.body.mass: [1.0, 2.0]
  impact_velocity: [1.0, 2.0, 3.0]
set: {end_time: 0.05, output: {interval: 1.0e-3, histories: all}}
"""


def load(out: Path) -> xr.Dataset:
    with xr.open_dataset(out / "results.nc") as ds:
        return ds.load()


def assert_identical(got: xr.Dataset, ref: xr.Dataset, got_dir: Path, ref_dir: Path) -> None:
    """Every variable and attribute equal (NaN where the reference has NaN), and the same summary.csv."""
    assert set(got.variables) == set(ref.variables)
    for name in ref.variables:
        assert got[name].dims == ref[name].dims, name
        assert got[name].equals(ref[name]), f"{name} differs from the uninterrupted run"
    assert got.attrs == ref.attrs
    a, b = pd.read_csv(got_dir / "summary.csv"), pd.read_csv(ref_dir / "summary.csv")
    pd.testing.assert_frame_equal(a, b, check_exact=True)


def assert_no_complete_result(out: Path) -> None:
    """Nothing that looks like a finished result: no results.nc, no summary.csv; `summary` refuses."""
    assert not (out / "results.nc").exists(), sorted(p.name for p in out.iterdir())
    assert not (out / "summary.csv").exists()
    p = cli("summary", out)
    assert p.returncode != 0 and "Traceback" not in p.stderr
    assert "unfinished" in p.stderr or "no results.nc" in p.stderr, p.stderr


def assert_clean_message(err: str) -> None:
    """An error message a user can read: no traceback, a few lines, an ``error:`` or ``interrupted:`` line."""
    assert "Traceback" not in err, err
    lines = [ln for ln in err.replace("\r", "\n").splitlines() if ln.strip() and "variants/s" not in ln]
    assert 1 <= len(lines) <= 5, lines
    assert any(ln.startswith(("error:", "interrupted:")) for ln in lines), lines


def files_under(root: Path) -> set[str]:
    return {str(p.relative_to(root)) for p in root.rglob("*")}


@pytest.fixture(scope="session")  # read only: one per worker, shared by the tests/test_faults_*.py modules
def fault_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = tmp_path_factory.mktemp("fault")
    (d / "models").mkdir()
    (d / "models" / "fault-model.yaml").write_text(FAULT_MODEL)
    (d / "study.yaml").write_text(FAULT_STUDY)
    (d / "small.yaml").write_text(SMALL_STUDY)
    return d


@pytest.fixture(scope="session")
def reference(fault_dir: Path) -> tuple[xr.Dataset, Path]:
    """The uninterrupted run: the truth every resumed run must reproduce."""
    out = fault_dir / "reference"
    p = cli("run", fault_dir / "study.yaml", "-o", out, "--progress", "off")
    assert p.returncode == 0, p.stderr
    return load(out), out
