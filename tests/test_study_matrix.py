"""Studies end to end (docs/studies.md, issue 3): variant numbering and coordinates, a variant against the
same model run alone, and what the special axes and ``set`` do (docs/format.md).

Every check compares numbers with a stated tolerance:

- variant order and coordinates: exact (the axis values are copied, never computed);
- a variant of a study against the same model run alone with ``simulate`` (axis values written into
  its YAML by hand): peak force, relative 1e-12 (the kernel is deterministic per variant, so in
  practice they are bit-identical).

The test model is a 1-D frontal impact: a crush spring (wall - front mass) and a linear body spring
(front - body), 20 ms at 5 kHz sampling, a few hundred steps: every run here takes milliseconds
(models.TWO_SPRING_CRUSH). What these tests share is in study_cases.py."""

from __future__ import annotations

import copy
import itertools
import json
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest

import crashstudy
from crashstudy.cli.main import main
from crashstudy.errors import InputError
from crashstudy.run.runner import simulate
from crashstudy.study.plan import load_study
from models import TWO_SPRING_CRUSH as MODEL
from study_cases import (
    AXES,
    MASSES,
    SCALES,
    SPEEDS,
    ZIP_K,
    ZIP_M,
    dump,
    load_ds,
)

RTOL = 1e-12  # "to round-off": a study variant against the same model run alone


def variant_model(mass: float, scale: float, speed: float, k: float, m_front: float) -> dict[str, Any]:
    """MODEL with one variant's axis values written in by hand (what docs/format.md says each axis means)."""
    d = copy.deepcopy(MODEL)
    d["nodes"]["body"]["mass"] = mass
    d["curves"]["crush-loading"]["y"] = [y * scale for y in MODEL["curves"]["crush-loading"]["y"]]
    d["initial_velocity"] = {"front": [-speed], "body": [-speed]}  # direction -x kept
    d["springs"]["body"]["material"]["stiffness"] = k
    d["nodes"]["front"]["mass"] = m_front
    return d


def expected_variants() -> list[tuple[float, float, float, float, float]]:
    """Row-major over the matrix axes as written, then the zip group (docs/format.md), spelled out by hand."""
    out = []
    for m, s, v in itertools.product(MASSES, SCALES, SPEEDS):
        for z in range(len(ZIP_K)):
            out.append((m, s, v, ZIP_K[z], ZIP_M[z]))
    return out


# --------------------------------------------------------------------------------------------------
# numbering, coordinates, and a variant against the same model run alone


def test_matrix_crossed_with_zip_numbers_120_variants_row_major(matrix_study: Path, matrix_run: Path) -> None:
    plan = load_study(matrix_study)
    assert plan.n_variants == 120 and plan.shape == (3, 4, 5, 2)
    exp = np.array(expected_variants())
    got = plan.axis_values(0, 120)
    assert list(got) == AXES
    for j, path in enumerate(AXES):
        np.testing.assert_array_equal(got[path], exp[:, j], err_msg=path)
    # any sub-range gives the same values (how chunks get theirs)
    np.testing.assert_array_equal(plan.axis_values(37, 53)[AXES[2]], exp[37:53, 2])

    ds = load_ds(matrix_run)
    np.testing.assert_array_equal(ds["variant"].values, np.arange(120))
    csv = pd.read_csv(matrix_run / "summary.csv")
    np.testing.assert_array_equal(csv["variant"].values, np.arange(120))
    for j, path in enumerate(AXES):
        assert ds[path].dims == ("variant",), path
        assert path in ds.coords or path in json.loads(ds.attrs["crashstudy_axes"]), path
        np.testing.assert_array_equal(ds[path].values, exp[:, j], err_msg=f"results.nc {path}")
        np.testing.assert_array_equal(csv[path].values, exp[:, j], err_msg=f"summary.csv {path}")
    assert path in crashstudy.open_results(matrix_run).dataset.coords  # axes are coordinates when opened
    assert (csv["status"] == "ok").all()
    # the summary.csv metrics are the results.nc ones
    for k, spring in enumerate(["crush", "body"]):
        np.testing.assert_array_equal(csv[f"peak_force.{spring}"].values, ds["peak_force"].values[:, k])


def test_each_variant_equals_the_model_run_alone_with_simulate(matrix_run: Path, work: Path) -> None:
    """Peak force of a variant == ``simulate`` of the model with its axis values written in (rel 1e-12).

    All 120 simulates take ~25 s on a loaded 2-core machine (each writes its own result folder), too
    long for this file's budget: checked are the two extremes (variants 0 and 119) and 12 more drawn
    at random (fixed seed).
    """
    ds = load_ds(matrix_run)
    variants = expected_variants()
    rng = np.random.default_rng(20240603)
    sample = [0, *sorted(rng.choice(np.arange(1, 119), size=12, replace=False).tolist()), 119]
    for k in sample:
        path = dump(work / f"alone-{k}.yaml", variant_model(*variants[k]))
        alone = simulate(path, work / f"alone-{k}")
        one = alone.dataset.load()
        alone.close()
        assert str(one["status"].values[0]) == "ok"
        for name in ("peak_force", "max_crush", "absorbed_energy", "peak_deceleration"):
            np.testing.assert_allclose(
                ds[name].values[k],
                one[name].values[0],
                rtol=RTOL,
                atol=0,
                err_msg=f"variant {k} {variants[k]}: {name}",
            )
        assert ds["dt"].values[k] == pytest.approx(one["dt"].values[0], rel=RTOL)
        np.testing.assert_allclose(
            ds["spring_force"].values[k],
            one["spring_force"].values[0],
            rtol=RTOL,
            atol=RTOL * np.abs(one["spring_force"].values).max(),
        )
    # the axes really change the answer (the comparison is not between copies of one run)
    assert len(np.unique(np.round(ds["peak_force"].values[:, 0], 6))) > 100


# --------------------------------------------------------------------------------------------------
# what the special axes and `set` do (docs/format.md)


def test_curve_scale_and_x_scale_axes_equal_the_curve_edited_by_hand(work: Path) -> None:
    study = {
        "name": "curve-axes",
        "model": str(work / "model.yaml"),
        "matrix": {"curves.crush-loading.scale": [0.7, 1.3], "curves.crush-loading.x_scale": [0.5, 2.0]},
    }
    out = work / "curve-axes"
    res = crashstudy.run_study(study, out)
    ds = res.dataset.load()
    base = MODEL["curves"]["crush-loading"]
    for k, (s, xs) in enumerate(itertools.product([0.7, 1.3], [0.5, 2.0])):
        assert (ds["curves.crush-loading.scale"].values[k], ds["curves.crush-loading.x_scale"].values[k]) == (
            s,
            xs,
        )
        d = copy.deepcopy(MODEL)
        d["curves"]["crush-loading"] = {"x": [x * xs for x in base["x"]], "y": [y * s for y in base["y"]]}
        one = simulate(dump(work / f"curve-{k}.yaml", d), work / f"curve-{k}").dataset.load()
        np.testing.assert_allclose(ds["peak_force"].values[k], one["peak_force"].values[0], rtol=RTOL)
        np.testing.assert_allclose(ds["max_crush"].values[k], one["max_crush"].values[0], rtol=RTOL)
        f = one["spring_force"].values[0]
        np.testing.assert_allclose(ds["spring_force"].values[k], f, rtol=RTOL, atol=RTOL * np.abs(f).max())
    # scale multiplies forces: the crush plateau (40 kN at 20 mm x x_scale) moves with it
    plateau = ds["peak_force"].sel(spring="crush").values
    assert plateau.min() > 0.7 * 40000.0 * (1 - 1e-9)
    assert not np.allclose(plateau[0], plateau[2], rtol=0.05)  # 0.7x and 1.3x differ by far more than 5 %


MODEL_2D: dict[str, Any] = {
    "name": "oblique-2d",
    "units": "SI",
    "nodes": {
        "ground": {"position": [0.0, 0.0], "fixed": True},
        "a": {"position": [0.3, 0.4], "mass": 20.0},
        "b": {"position": [0.0, 1.0], "mass": 50.0},
        "c": {"position": [0.5, 1.0], "mass": 10.0},
    },
    "springs": {
        "s1": {"nodes": ["ground", "a"], "material": {"type": "linear_elastic", "stiffness": 1.0e5}},
        "s2": {"nodes": ["a", "b"], "material": {"type": "linear_elastic", "stiffness": 2.0e5}},
        "s3": {"nodes": ["b", "c"], "material": {"type": "linear_elastic", "stiffness": 1.0e5}},
    },
    "initial_velocity": {"a": [3.0, -4.0], "b": [0.0, -2.0]},  # speeds 5 and 2; c starts at rest
    "end_time": 0.01,
    "output": {"interval": 1.0e-4},
}


def test_impact_velocity_sets_every_initial_speed_keeping_each_direction(work: Path) -> None:
    """impact_velocity: the speed given to every node with an initial velocity, direction kept (2-D, two
    different directions and speeds; a node without an initial velocity stays at rest)."""
    model = dump(work / "oblique.yaml", MODEL_2D)
    out = work / "oblique-out"
    res = crashstudy.run_study(
        {"name": "speed", "model": str(model), "matrix": {"impact_velocity": [1.0, 7.5]}}, out
    )
    ds = res.dataset.load()
    for k, speed in enumerate([1.0, 7.5]):
        d = copy.deepcopy(MODEL_2D)
        d["initial_velocity"] = {"a": [0.6 * speed, -0.8 * speed], "b": [0.0, -speed]}
        one = simulate(dump(work / f"oblique-{k}.yaml", d), work / f"oblique-{k}").dataset.load()
        for name in ("velocity", "displacement", "spring_force"):
            ref = one[name].values[0]
            np.testing.assert_allclose(
                ds[name].values[k],
                ref,
                rtol=1e-12,
                atol=1e-12 * np.abs(ref).max(),
                err_msg=f"speed {speed}: {name}",
            )
        np.testing.assert_allclose(ds["peak_force"].values[k], one["peak_force"].values[0], rtol=RTOL)
        v0 = ds["velocity"].values[k, 0]  # (node, axis) at t = 0
        np.testing.assert_allclose(
            v0, [[0, 0], [0.6 * speed, -0.8 * speed], [0, -speed], [0, 0]], rtol=1e-14, atol=1e-14 * speed
        )


def test_set_overrides_apply_to_every_variant(work: Path) -> None:
    study = {
        "name": "set-check",
        "model": str(work / "model.yaml"),
        "matrix": {"impact_velocity": [5.0, 9.0]},
        "set": {"end_time": 0.012, "output": {"interval": 4.0e-4}, "nodes.front.mass": 45.0},
    }
    ds = crashstudy.run_study(study, work / "set-out").dataset.load()
    np.testing.assert_allclose(ds["time"].values, np.arange(31) * 4.0e-4, rtol=0, atol=1e-15)
    assert ds["time"].values[-1] == pytest.approx(0.012, rel=1e-12)
    np.testing.assert_allclose(ds["t_end"].values, [0.012, 0.012], rtol=1e-12)
    assert ds.attrs["history_interval"] == pytest.approx(4.0e-4, rel=1e-12)
    for k, speed in enumerate([5.0, 9.0]):
        d = copy.deepcopy(MODEL)
        d.update(
            end_time=0.012,
            output={"interval": 4.0e-4},
            initial_velocity={"front": [-speed], "body": [-speed]},
        )
        d["nodes"]["front"]["mass"] = 45.0
        one = simulate(dump(work / f"set-{k}.yaml", d), work / f"set-{k}").dataset.load()
        np.testing.assert_allclose(ds["peak_force"].values[k], one["peak_force"].values[0], rtol=RTOL)
        f = one["spring_force"].values[0]
        np.testing.assert_allclose(ds["spring_force"].values[k], f, rtol=RTOL, atol=RTOL * np.abs(f).max())


def test_unknown_axis_is_an_input_error_naming_the_closest_paths(work: Path) -> None:
    with pytest.raises(InputError) as exc:
        load_study(
            {"name": "typo", "model": str(work / "model.yaml"), "matrix": {"nodes.body.mas": [1.0, 2.0]}}
        )
    assert "nodes.body.mass" in exc.value.format()


def test_dry_run_prints_the_variant_count_and_runs_nothing(
    matrix_study: Path, work: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = work / "dry"
    assert main(["run", str(matrix_study), "-o", str(out), "--dry-run"]) == 0
    text = capsys.readouterr().out
    assert "120 variants (3 x 4 x 5 x 2)" in text
    assert "impact_velocity: 5 values" in text
    assert not out.exists()
