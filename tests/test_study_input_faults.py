"""Fault testing, issue 14 items 4, 5, 6, 7, 13 and 17: each test failed before its fix.

- 4: ``run --resume`` into a finished folder recomputes what changed (or refuses another study).
- 5: a study over 2,000,000 variants gets its axis coordinates written (they were all 0.0).
- 6: every distinct value of an axis is validated (only the first ~200 were).
- 7: a step count that overflows is an input error or a failed variant with its reason.
- 13: ``compare`` refuses bad tolerances and fails a baseline that lost variants.
- 17: ``set:`` paths into a scalar or past a list's end, a tiny output interval, a NUL byte or a
  symbolic-link loop in the model path: exit 2 with a message, never a traceback.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import netCDF4
import numpy as np
import pandas as pd
import pytest

from crashstudy.errors import InputError
from crashstudy.study.plan import load_study
from helpers import MASSES, TINY_MODEL, TINY_STUDY, Cli, K, assert_exit_2, peak_force, reseal

GENERAL_MODEL = """\
name: general
curves:
  load: {x: [-0.1, 0.0, 0.1], y: [-2000.0, 0.0, 2000.0]}
  unload: {x: [-0.1, 0.0, 0.1], y: [-2000.0, 0.0, 2000.0]}
nodes:
  anchor: {position: [0.0], fixed: true}
  body:   {position: [0.1], mass: 2.0}
springs:
  spring:
    nodes: [anchor, body]
    material: {type: general_nonlinear, loading: load, unloading: unload, tension_yield: 1500.0}
initial_velocity: {body: [1.0]}
end_time: 0.05
output: {histories: none}
"""


def write(folder: Path, study: str, model: str = TINY_MODEL) -> Path:
    (folder / "model.yaml").write_text(model)
    path = folder / "study.yaml"
    path.write_text(study)
    return path


# ------------------------------------------------------------------------------------------------
# item 4: --resume into a finished folder
# ------------------------------------------------------------------------------------------------


def test_resume_into_a_finished_folder_recomputes_the_variants_whose_model_changed(
    tmp_path: Path, cli: Cli
) -> None:
    study, out = write(tmp_path, TINY_STUDY), tmp_path / "out"
    assert cli("run", study, "-o", out, "--progress", "off").returncode == 0
    again = cli("run", study, "-o", out, "--resume", "--progress", "off")  # nothing changed: all reused
    assert again.returncode == 0 and "(0 variants computed" in again.stdout, again.stdout
    k2 = 3.0 * K
    (tmp_path / "model.yaml").write_text(TINY_MODEL.replace(f"stiffness: {K}", f"stiffness: {k2}"))
    p = cli("run", study, "-o", out, "--resume", "--progress", "off")
    assert p.returncode == 0, p.stderr
    assert "(3 variants computed" in p.stdout, p.stdout  # was "(0 variants computed", old results kept
    df = pd.read_csv(out / "summary.csv")
    expect = [peak_force(k2, m) for m in MASSES]
    np.testing.assert_allclose(df["peak_force.spring"], expect, rtol=2e-3)  # tolerance mode 1e-3


def test_resume_into_the_finished_folder_of_another_study_exits_2_and_keeps_it(
    tmp_path: Path, cli: Cli
) -> None:
    study, out = write(tmp_path, TINY_STUDY), tmp_path / "out"
    assert cli("run", study, "-o", out, "--progress", "off").returncode == 0
    before = (out / "results.nc").read_bytes()
    other = tmp_path / "other.yaml"
    other.write_text(TINY_STUDY.replace("name: tiny-study", "name: other-study"))
    p = cli("run", other, "-o", out, "--resume", "--progress", "off")
    assert_exit_2(p, "tiny-study", "other-study", "--force")
    assert (out / "results.nc").read_bytes() == before


# ------------------------------------------------------------------------------------------------
# item 5: studies over 2,000,000 variants
# ------------------------------------------------------------------------------------------------


def test_axis_coordinates_of_a_study_over_two_million_variants_are_written(tmp_path: Path) -> None:
    from crashstudy.results.store import ResultWriter

    (tmp_path / "model.yaml").write_text(TINY_MODEL)
    masses = [1.0 + 0.001 * i for i in range(1500)]
    ends = [0.01 + 1e-5 * j for j in range(1401)]
    plan = load_study(
        {
            "name": "big",
            "model": str(tmp_path / "model.yaml"),
            "matrix": {"nodes.body.mass": masses, "end_time": ends},
        }
    )
    assert plan.n_variants == 1500 * 1401 > 2_000_000
    writer = ResultWriter(tmp_path / "out", plan)
    writer.abort()
    with netCDF4.Dataset(tmp_path / "out" / "results.nc.partial") as nc:
        for v in (0, 1, 1400, 1401, 2_000_000, 2_000_001, plan.n_variants - 1):  # row-major: mass slowest
            assert nc.variables["nodes.body.mass"][v] == masses[v // 1401], v
            assert nc.variables["end_time"][v] == ends[v % 1401], v
        np.testing.assert_array_equal(nc.variables["end_time"][-1401:], ends)


# ------------------------------------------------------------------------------------------------
# item 6: every distinct axis value is validated
# ------------------------------------------------------------------------------------------------


def _values(n: int, first: float, step: float, bad_at: int, bad: float) -> list[float]:
    vals = [first + step * i for i in range(n)]
    vals[bad_at] = bad
    return vals


AXIS_CASES = [  # id, model, axis, values, expected message part
    (
        "negative-stiffness",
        TINY_MODEL,
        "springs.spring.material.stiffness",
        _values(300, 1e3, 1.0, 250, -5.0),
        "greater than 0",
    ),
    (
        "negative-tension-yield",
        GENERAL_MODEL,
        "springs.spring.material.tension_yield",
        _values(300, 1e3, 1.0, 230, -3.0),
        "greater than 0",
    ),
    (
        "curve-knot-out-of-order",
        GENERAL_MODEL,
        "curves.load.x.2",
        _values(300, 0.05, 1e-4, 260, -0.5),
        "strictly increasing",
    ),
    (
        "safety-factor-above-1",
        TINY_MODEL.replace("end_time", "time_step: {safety_factor: 0.5}\nend_time"),
        "time_step.safety_factor",
        _values(300, 0.5, 1e-3, 299, 2.0),
        "less than or equal to 1",
    ),
    (
        "curve-scaled-to-infinity",
        GENERAL_MODEL,
        "curves.load.scale",
        _values(300, 0.5, 1e-3, 270, 1e306),
        "not finite",
    ),
]


@pytest.mark.parametrize("case", AXIS_CASES, ids=[c[0] for c in AXIS_CASES])
def test_an_invalid_axis_value_after_the_first_200_is_refused_at_its_line(
    case: tuple[Any, ...], tmp_path: Path
) -> None:
    _, model, axis, values, expect = case
    bad_at = next(k for k, v in enumerate(values) if v in (-5.0, -3.0, -0.5, 2.0, 1e306))
    text = (
        "name: s6\nmodel: model.yaml\nmatrix:\n  " + axis + ":\n" + "".join(f"    - {v!r}\n" for v in values)
    )
    study = write(tmp_path, text, model)
    with pytest.raises(InputError) as exc:
        load_study(study)
    [p] = exc.value.problems
    assert p.file == str(study) and p.line == 5 + bad_at and p.field == f"matrix.{axis}.{bad_at}"
    assert repr(values[bad_at]) in p.message and expect in p.message, p.message


def test_validate_names_the_study_file_axis_line_and_value_of_the_251st_distinct_value(
    tmp_path: Path, cli: Cli
) -> None:
    values = _values(300, 1e3, 1.0, 250, -5.0)
    text = "name: s6\nmodel: model.yaml\nmatrix:\n  springs.spring.material.stiffness:\n"
    study = write(tmp_path, text + "".join(f"    - {v!r}\n" for v in values))
    p = cli("validate", study)
    assert_exit_2(
        p, f"{study}:255: matrix.springs.spring.material.stiffness.250: value -5.0 makes the model invalid"
    )


# ------------------------------------------------------------------------------------------------
# item 7: step counts that overflow
# ------------------------------------------------------------------------------------------------

OVERFLOW_MODEL = (
    TINY_MODEL.replace("mass: 2.0", "mass: 1.0e-40")
    .replace(f"stiffness: {K}", "stiffness: 1.0e300")
    .replace("end_time: 0.05", "end_time: 1.0e300")
)


def test_a_model_whose_step_count_overflows_is_refused_by_validate_and_simulate(
    tmp_path: Path, cli: Cli
) -> None:
    model = tmp_path / "model.yaml"
    model.write_text(OVERFLOW_MODEL)
    line = OVERFLOW_MODEL.splitlines().index("end_time: 1.0e300") + 1
    assert_exit_2(cli("validate", model), f"{model}:{line}: end_time:", "time steps")
    p = cli("simulate", model, "-o", tmp_path / "out")
    assert_exit_2(p, "time steps")
    assert "RuntimeWarning" not in p.stderr
    assert not (tmp_path / "out" / "results.nc").exists()


def test_variants_whose_step_count_overflows_fail_with_the_reason_and_the_others_run(
    tmp_path: Path, cli: Cli
) -> None:
    # each value alone is fine (1e12 and 2e7 steps); together 2e17 steps (dt 4e-14 s over 1e4 s)
    study = write(
        tmp_path,
        "name: s7\nmodel: model.yaml\nzip:\n  - {nodes.body.mass: [2.0, 1.0e-20], end_time: [0.05, 1.0e4]}\n",
    )
    p = cli("run", study, "-o", tmp_path / "out", "--progress", "off")
    assert p.returncode == 1, p.stderr
    assert "1 of 2 variants failed" in p.stderr and "Warning" not in p.stderr, p.stderr
    df = pd.read_csv(tmp_path / "out" / "summary.csv")
    assert list(df["status"]) == ["ok", "failed"]
    assert "time steps" in df["failure_reason"][1]
    assert df["peak_force.spring"][0] == pytest.approx(peak_force(K, 2.0), rel=2e-3)


# ------------------------------------------------------------------------------------------------
# item 13: compare options and a damaged baseline
# ------------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def two_results(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    from crashstudy.run.runner import run_plan

    root = tmp_path_factory.mktemp("compare")
    study = write(root, TINY_STUDY.replace(f"{MASSES}", "[1.0, 1.5, 2.0, 2.5, 3.0, 3.5]"))
    plan = load_study(study)
    run_plan(plan, root / "new", progress=False)
    run_plan(plan, root / "base", progress=False)
    return root / "new", root / "base"


@pytest.mark.parametrize(
    "option", [("--rtol", "-1"), ("--rtol", "nan"), ("--rtol", "inf"), ("--atol", "-1e-3"), ("--atol", "nan")]
)
def test_compare_refuses_a_tolerance_that_is_negative_or_not_finite(
    two_results: tuple[Path, Path], cli: Cli, option: tuple[str, str]
) -> None:
    new, base = two_results
    assert cli("compare", new, base).returncode == 0  # identical results pass with the defaults
    p = cli("compare", new, base, f"{option[0]}={option[1]}")
    assert_exit_2(p, f"{option[0]}:", "a finite number >= 0")


def test_compare_fails_a_baseline_whose_summary_lost_variants(
    two_results: tuple[Path, Path], cli: Cli, tmp_path: Path
) -> None:
    import shutil

    new, base = two_results
    damaged = tmp_path / "base"
    shutil.copytree(base, damaged)
    df = pd.read_csv(damaged / "summary.csv")
    df.iloc[:3].to_csv(damaged / "summary.csv", index=False)
    pd.read_parquet(damaged / "summary.parquet").iloc[:3].to_parquet(damaged / "summary.parquet", index=False)
    reseal(damaged)  # as if the run had written them so (edited files are refused: test_write_read.py)
    p = cli("compare", new, damaged)
    assert p.returncode == 1, p.stdout
    verdict = p.stdout.strip().splitlines()[-1]
    assert verdict.startswith("FAILED") and "summary.parquet lists 3 of the 6 variants" in verdict, verdict
    (damaged / "summary.parquet").unlink()  # an older folder without parquet: its summary.csv is read
    verdict = cli("compare", new, damaged).stdout.strip().splitlines()[-1]
    assert verdict.startswith("FAILED") and "summary.csv lists 3 of the 6 variants" in verdict, verdict


# ------------------------------------------------------------------------------------------------
# item 17: tracebacks
# ------------------------------------------------------------------------------------------------

SET_CASES = [
    ("end_time.foo", "1.0", "end_time is a number"),
    ("name.x", "1.0", "name is text"),
    ("nodes.body.position.0.x", "1.0", "nodes.body.position.0 is a number"),
    ("nodes.body.position.5", "1.0", "nodes.body.position has 1 item"),
    ("springs.spring.nodes.7", "a", "springs.spring.nodes has 2 items"),
    ("springs.spring.nodes.x", "a", "springs.spring.nodes is a list"),
]


@pytest.mark.parametrize("key,value,expect", SET_CASES, ids=[c[0] for c in SET_CASES])
def test_a_set_path_into_a_scalar_or_past_a_list_exits_2_at_its_line(
    tmp_path: Path, cli: Cli, key: str, value: str, expect: str
) -> None:
    study = write(tmp_path, f"name: s17\nmodel: model.yaml\nset:\n  {key}: {value}\n")
    assert_exit_2(cli("validate", study), f"{study}:4: set.{key}:", expect)


@pytest.mark.parametrize("interval", ["1.0e-300", "1.0e-12"])
def test_a_tiny_output_interval_exits_2_in_validate_and_run(tmp_path: Path, cli: Cli, interval: str) -> None:
    study = write(tmp_path, f"name: s17\nmodel: model.yaml\nset:\n  output: {{interval: {interval}}}\n")
    assert_exit_2(cli("validate", study), f"{study}:4: set.output:", "history samples")
    p = cli("run", study, "-o", tmp_path / "out", "--progress", "off")
    assert_exit_2(p, "history samples")
    assert not (tmp_path / "out").exists()


def test_a_nul_byte_in_the_model_path_exits_2(tmp_path: Path, cli: Cli) -> None:
    study = write(tmp_path, 'name: s17\nmodel: "model\\0.yaml"\n')
    assert_exit_2(cli("validate", study), f"{study}:2: model:", "NUL")


def test_a_model_path_that_is_a_symbolic_link_loop_exits_2(tmp_path: Path, cli: Cli) -> None:
    (tmp_path / "loop.yaml").symlink_to("loop.yaml")
    study = write(tmp_path, "name: s17\nmodel: loop.yaml\n")
    p = cli("validate", study)
    assert_exit_2(p, f"{study}:2: model:")
    assert re.search(r"symbolic link|Too many levels", p.stderr), p.stderr


RICH_MODEL = """\
name: rich
curves:
  nl: {x: [-0.1, 0.0, 0.1], y: [-100.0, 0.0, 100.0]}
  gl: {x: [-0.1, 0.0, 0.1], y: [-200.0, 0.0, 200.0]}
  gu: {x: [-0.1, 0.0, 0.1], y: [-300.0, 0.0, 300.0]}
  cr: {x: [-0.2, -0.1, 0.0], y: [-500.0, -400.0, 0.0]}
  pulse: {x: [0.0, 0.01, 0.02], y: [0.0, 1.0, 0.0]}
nodes:
  anchor: {position: [0.0], fixed: true}
  a: {position: [0.1], mass: 1.0}
  b: {position: [0.2], mass: 2.0}
  c: {position: [0.3], mass: 1.5}
  d: {position: [0.4], mass: 1.0}
springs:
  lin: {nodes: [anchor, a], material: {type: linear_elastic, stiffness: 1.0e4}}
  nle: {nodes: [a, b], material: {type: nonlinear_elastic, curve: nl}}
  gen: {nodes: [b, c], material: {type: general_nonlinear, loading: gl, unloading: gu, tension_yield: 150.0,
                                  compression_yield: -150.0}}
  cru: {nodes: [c, d], material: {type: crush, loading: cr, unloading_stiffness: 1.0e5}}
  dmp: {nodes: [anchor, d], material: {type: damper, damping: 10.0}}
initial_velocity: {anchor: [0.0], d: [1.0]}
gravity: [-9.81]
loads: [{node: a, force: [10.0], curve: pulse}]
rigid_walls: [{id: w, point: [-1.0], normal: [1.0]}]
end_time: 0.1
time_step: {safety_factor: 0.9}
output: {interval: 0.01, histories: none}
termination: {kinetic_energy_fraction: 0.01, min_time: 0.02}
"""


def test_the_vectorised_parameter_check_agrees_with_the_model_validation_on_every_field() -> None:
    """check_parameters (what every distinct axis value now goes through) against the schema (the truth) on
    each numeric field of a model with all five materials, a wall, a load curve and termination."""
    from crashstudy.arrays.compiler import apply_axis
    from crashstudy.arrays.parameter_checks import check_parameters
    from crashstudy.schema.yamlio import loads_yaml
    from crashstudy.study.values import model_message
    from helpers import model_plan

    plan = model_plan(RICH_MODEL)
    data = loads_yaml(RICH_MODEL).data
    topo, compared, invalid = plan.topology, 0, 0
    for path, ref in topo.paths.items():
        if ref.op != "set":
            continue
        base = float(plan.base[ref.slots[0]])
        probes = sorted(
            {-1.0, 0.0, 1e-3, 0.05, 0.5, 1.0, 2.0, 10.0, base, -base, 2 * base, base + 1e-3, base - 1e-3}
        )
        if (
            path == "nodes.anchor.mass"
        ):  # a fixed node without mass compiles to 0.0 ("no mass"): 0 is not refused
            probes.remove(0.0)
        if not np.isfinite(
            base
        ):  # an absent failure threshold compiles to +-inf ("never"): inf is not refused
            probes = sorted(p for p in probes if np.isfinite(p))
        P = np.repeat(plan.base[:, None], len(probes), axis=1)
        apply_axis(P, ref, np.asarray(probes))
        check = check_parameters(topo, P, plan.interval)
        for c, val in enumerate(probes):
            schema_says = model_message(data, path, val)
            assert bool(schema_says) == bool(check.bad[c]), (path, val, schema_says, check.reason(c))
            compared += 1
            invalid += bool(schema_says)
    assert compared > 400 and invalid > 100, (compared, invalid)  # every rule kind was exercised
