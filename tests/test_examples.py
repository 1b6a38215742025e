"""The shipped examples run: every study in studies/*.yaml (at small size) and every model in studies/models.

A study runs as a reduced copy written next to the test: each axis (matrix and zip) cut to its first
and last values (the corners of the design space, where a study is most likely to break: lightest
and heaviest, softest and stiffest, slowest and fastest), the model path made absolute, everything
else as shipped. Every variant must end ``ok`` with an energy balance error below 1e-3. New files in
studies/ are picked up automatically.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

from crashstudy.results.store import open_results
from crashstudy.run.runner import run_plan, simulate
from crashstudy.schema.yamlio import load_yaml
from crashstudy.study.design import n_rows
from crashstudy.study.plan import load_study

ROOT = Path(__file__).resolve().parents[1]
STUDIES = sorted((ROOT / "studies").glob("*.yaml"))
MODELS = sorted((ROOT / "studies" / "models").glob("*.yaml"))
ENERGY_TOL = 1e-3


def ends(values: list[Any]) -> list[Any]:
    return [values[0], values[-1]] if len(values) > 1 else list(values)


def reduced_copy(study: Path, folder: Path) -> Path:
    """The study with each axis cut to its first and last values and an absolute model path."""
    data = load_yaml(study).data  # YAML 1.2 numbers, as crashstudy reads them
    data["model"] = str((study.parent / data["model"]).resolve())
    if data.get("calibrate"):  # measured data beside the study (validate checks the file)
        data["calibrate"]["data"] = str((study.parent / data["calibrate"]["data"]).resolve())
    if data.get("matrix"):
        data["matrix"] = {path: ends(vals) for path, vals in data["matrix"].items()}
    if data.get("zip"):
        data["zip"] = [{path: ends(vals) for path, vals in group.items()} for group in data["zip"]]
    if data.get("design"):  # a few rows of the same design (same seed and distributions)
        data["design"]["n"] = min(int(data["design"]["n"]), 4)
    out = folder / study.name
    out.write_text(yaml.safe_dump(data, sort_keys=False))
    return out


def test_there_are_example_studies_and_models() -> None:
    names = {p.name for p in STUDIES}
    assert {"helicopter-matrix.yaml", "frontal-matrix.yaml"} <= names
    assert len(MODELS) >= 2


@pytest.mark.parametrize("study", STUDIES, ids=[p.stem for p in STUDIES])
def test_example_study_loads_and_its_corners_run(
    study: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    full = load_study(study)
    design = load_yaml(study).data.get("design")
    rows = (
        (lambda n: n_rows(design.get("method", "lhs"), n, len(design["axes"]))) if design else (lambda n: 1)
    )
    assert full.n_variants == math.prod(len(v) for v in _groups(load_yaml(study).data)) * rows(
        design and design["n"]
    )
    if study.stem == "frontal-matrix":
        assert full.n_variants >= 1000  # issue 3: the frontal example has at least 10^3 variants

    plan = load_study(reduced_copy(study, tmp_path))
    grid = full.shape[:-1] if design else full.shape
    assert plan.n_variants == 2 ** sum(1 for s in grid if s > 1) * rows(design and min(design["n"], 4))
    assert [a.path for a in plan.axes] == [a.path for a in full.axes]
    for small, big in zip(plan.axes, full.axes, strict=True):  # the corners of the shipped axes
        if design and small.path in design["axes"]:  # rows of the same distributions: inside their range
            assert (
                big.values.min() - 1e-9 <= small.values.min()
                and small.values.max() <= big.values.max() + 1e-9
            )
            continue
        np.testing.assert_array_equal(small.values, [big.values[0], big.values[-1]][: len(small.values)])
    assert plan.n_out == full.n_out and plan.topology.histories == full.topology.histories  # `set` kept

    # the generic kernel (bitwise the reference: test_kernel_twins): the automatic choice took the NumPy
    # reference for these small chunks, about 2 s a study
    monkeypatch.setenv("CRASHSTUDY_KERNEL", "generic")
    rep = run_plan(plan, tmp_path / "out", progress=False)
    s = rep.results.summary
    assert len(s) == plan.n_variants
    bad = s[(s["status"] != "ok") | ~(s["energy_error"] < ENERGY_TOL)]
    assert bad.empty, bad[
        ["variant", *[a.path for a in plan.axes], "status", "failure_reason", "energy_error"]
    ]
    assert rep.n_failed == 0
    assert (s[[c for c in s.columns if c.startswith("peak_force.")]].max(axis=1) > 0).all()


def _groups(data: dict[str, Any]) -> list[list[Any]]:
    """One value list per dimension: each matrix axis, then each zip group."""
    dims = [list(v) for v in (data.get("matrix") or {}).values()]
    dims += [list(next(iter(g.values()))) for g in data.get("zip") or []]
    return dims


@pytest.mark.parametrize("model", MODELS, ids=[p.stem for p in MODELS])
def test_example_model_runs_with_simulate(model: Path, tmp_path: Path) -> None:
    res = simulate(model, tmp_path / "out")
    s = res.summary
    assert len(s) == 1
    assert s["status"][0] == "ok", s["failure_reason"][0]
    assert s["energy_error"][0] < ENERGY_TOL
    assert open_results(tmp_path / "out").dataset.attrs["model_yaml"] == model.read_text()
