"""Property-based tests (hypothesis) of the command line on generated studies, through
:func:`crashstudy.cli.main` in this process, as a user's command would run:

- **Random valid studies count their variants right.** Random axes among valid paths of a small model,
  random zip groups: the variant count equals the product of the matrix axis lengths and of the zip group
  lengths, ``run --dry-run`` prints it, ``validate`` says it, and the variants are numbered row-major.
- random ``set:`` paths never crash ``validate``;
- one invalid value among up to 1000 distinct axis values is caught at its position.

The number of generated inputs that actually ran is counted (property_inputs.py) and printed at the end of
the module (run with ``-s`` to see it); docs/robustness.md quotes it. How many examples each property
draws: property_inputs.py."""

from __future__ import annotations

import itertools
import math
import re
import tempfile
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from helpers import dump, run_main
from property_inputs import COUNTS, SMALL_MODEL, _report_counts  # noqa: F401 - _report_counts: autouse, prints the counts
from strategies import examples, num

# ------------------------------------------------------------------------------------------------
# 3. random valid studies: variant count and numbering
# ------------------------------------------------------------------------------------------------

# every numeric path of SMALL_MODEL a study may vary, with values that keep the model valid
AXIS_VALUES: dict[str, st.SearchStrategy[float]] = {
    "nodes.front.mass": num(1.0, 1e3),
    "nodes.body.mass": num(1.0, 1e4),
    "springs.body.material.stiffness": num(1e3, 1e8),
    "springs.crush.material.unloading_stiffness": num(1e3, 1e8),
    "springs.damper.material.damping": num(0.0, 1e4),
    "curves.crush-loading.scale": num(0.1, 10.0),
    "curves.crush-loading.x_scale": num(0.1, 10.0),
    "curves.pulse.scale": num(0.1, 10.0),
    "curves.crush-loading.y.0": num(-1e6, -5e4),
    "impact_velocity": num(0.0, 50.0),
    "initial_velocity.body.0": num(-50.0, 50.0),
    "gravity.0": num(-20.0, 20.0),
    "loads.0.force.0": num(-1e4, 1e4),
    "end_time": num(0.002, 0.05),
    "time_step.safety_factor": num(0.05, 1.0),
}


@st.composite
def valid_study(draw: st.DrawFn) -> tuple[dict[str, Any], list[int], list[list[str]]]:
    """(study dict, lengths of the dimensions in order, axis paths of each dimension)."""
    paths = draw(st.lists(st.sampled_from(sorted(AXIS_VALUES)), min_size=1, max_size=7, unique=True))
    n_matrix = draw(st.integers(0, len(paths)))
    matrix_paths, zip_paths = paths[:n_matrix], paths[n_matrix:]
    # split the zip paths into consecutive groups
    groups: list[list[str]] = []
    rest = list(zip_paths)
    while rest:
        k = draw(st.integers(1, len(rest)))
        groups.append(rest[:k])
        rest = rest[k:]
    study: dict[str, Any] = {"name": "generated-study", "model": "model.yaml"}
    lengths: list[int] = []
    dims: list[list[str]] = []
    if matrix_paths:
        study["matrix"] = {}
        for p in matrix_paths:
            n = draw(st.integers(1, 5))
            study["matrix"][p] = [round(v, 6) for v in draw(st.lists(AXIS_VALUES[p], min_size=n, max_size=n))]
            lengths.append(n)
            dims.append([p])
    if groups:
        study["zip"] = []
        for g in groups:
            n = draw(st.integers(1, 5))
            study["zip"].append(
                {p: [round(v, 6) for v in draw(st.lists(AXIS_VALUES[p], min_size=n, max_size=n))] for p in g}
            )
            lengths.append(n)
            dims.append(g)
    if draw(st.booleans()):
        study["set"] = {"end_time": 0.01}
        if "end_time" in paths:  # an axis wins over set; keep it simple: no conflict
            study.pop("set")
    return study, lengths, dims


def _assert_axis_changes_no_parameter(plan: Any, path: str) -> None:
    """Independent check of validate's "axis changes nothing": variants that differ only in ``path``
    have identical parameter vectors."""
    n = plan.n_variants
    P, values = plan.params(0, n), plan.axis_values(0, n)
    others = [v for k, v in values.items() if k != path]
    key = np.stack(others, axis=1) if others else np.zeros((n, 0))
    _, group = np.unique(key, axis=0, return_inverse=True)
    for g in np.unique(group):
        cols = P[:, group.reshape(-1) == g]
        assert np.array_equal(cols, np.repeat(cols[:, :1], cols.shape[1], axis=1)), path


@settings(max_examples=examples(50, 150), deadline=None, suppress_health_check=list(HealthCheck))
@given(valid_study())
def test_random_valid_study_counts_its_variants(
    case: tuple[dict[str, Any], list[int], list[list[str]]],
) -> None:
    """Draws 50 studies (150 under ``HYPOTHESIS_PROFILE=explore``, new ones on each run)."""
    from crashstudy.study.plan import load_study

    study, lengths, dims = case
    with tempfile.TemporaryDirectory(prefix="crashstudy-prop-") as tmp:
        d = Path(tmp)
        (d / "model.yaml").write_text(SMALL_MODEL)
        (d / "study.yaml").write_text(dump(study))
        expected = math.prod(lengths)
        rc, out, err = run_main("run", str(d / "study.yaml"), "--dry-run", "-o", str(d / "out"))
        COUNTS["studies_dry_run"] += 1
        noop = re.search(r"axis '([^']+)' changes nothing", err)
        if rc == 2 and noop:  # e.g. an initial_velocity axis that a zipped impact_velocity of 0 overrides
            _assert_axis_changes_no_parameter(load_study(d / "study.yaml"), noop.group(1))
            COUNTS["studies_refused_for_an_axis_that_changes_nothing"] += 1
            return
        assert rc == 0, err
        shape = " (" + " x ".join(str(n) for n in lengths) + ")"
        assert out.splitlines()[0] == f"study generated-study: {expected} variants{shape}", out
        assert not (d / "out").exists()
        rc, out, err = run_main("validate", str(d / "study.yaml"))
        plan = load_study(d / "study.yaml")
        assert rc == 0 and out == f"{d / 'study.yaml'}: valid study ({expected} variants)\n", (out, err)
        # row-major numbering: matrix axes first, then zip groups, the last dimension fastest
        assert plan.n_variants == expected
        got = plan.axis_values(0, expected)
        table = study.get("matrix", {}) | {p: v for g in study.get("zip", []) for p, v in g.items()}
        for k, idx in enumerate(itertools.product(*(range(n) for n in lengths))):
            for dim, paths in enumerate(dims):
                for p in paths:
                    assert got[p][k] == float(table[p][idx[dim]]), (p, k, idx)


# ------------------------------------------------------------------------------------------------
# 4. random `set:` paths, 5. an invalid value among up to 1000 distinct axis values
# ------------------------------------------------------------------------------------------------

SET_PARTS = [
    "nodes",
    "body",
    "front",
    "wall",
    "springs",
    "crush",
    "damper",
    "material",
    "stiffness",
    "damping",
    "position",
    "mass",
    "fixed",
    "name",
    "end_time",
    "output",
    "interval",
    "histories",
    "time_step",
    "dt",
    "safety_factor",
    "loads",
    "force",
    "node",
    "curves",
    "pulse",
    "x",
    "y",
    "scale",
    "gravity",
    "initial_velocity",
    "0",
    "1",
    "2",
    "7",
    "-1",
    "foo",
    "",
]
SET_VALUES = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(-10, 10),
    num(-1e3, 1e3),
    st.sampled_from(["text", "body", "none", "all", "", "1e400"]),
    st.lists(num(-1.0, 1.0), max_size=3),
    st.dictionaries(st.sampled_from(["x", "dt", "mass", "interval"]), num(1e-4, 1.0), max_size=2),
)


def _assert_invalid_lines(err: str, study: Path, model: Path) -> None:
    """``error: invalid input`` then ``file[:line]: ...`` lines of the study or its model, no traceback."""
    lines = err.splitlines()
    assert lines[0] == "error: invalid input" and len(lines) >= 2, err
    for ln in lines[1:]:
        assert ln.startswith("... and ") or ln.startswith((f"{study}:", f"{model}:")), (ln, err)


SET_PATHS = st.one_of(
    st.lists(st.sampled_from(SET_PARTS), min_size=1, max_size=5).map(".".join),
    st.sampled_from(
        [
            "end_time",
            "nodes.body.mass",
            "springs.body.material.stiffness",
            "output.interval",
            "time_step.safety_factor",
            "gravity.0",
            "nodes.front.position.0",
            "loads.0.force.0",
            "curves.pulse.scale",
        ]
    ),
)


@settings(max_examples=examples(60, 150), deadline=None, suppress_health_check=list(HealthCheck))
@given(st.dictionaries(SET_PATHS, st.one_of(SET_VALUES, num(1e-3, 1.0)), min_size=1, max_size=3))
def test_random_set_paths_never_crash_validate(overrides: dict[str, Any]) -> None:
    """Draws 60 ``set:`` blocks (150 under ``HYPOTHESIS_PROFILE=explore``, new ones on each run)."""
    with tempfile.TemporaryDirectory(prefix="crashstudy-prop-") as tmp:
        d = Path(tmp)
        (d / "model.yaml").write_text(SMALL_MODEL)
        study = {
            "name": "set-study",
            "model": "model.yaml",
            "set": overrides,
            "matrix": {"nodes.body.mass": [800.0, 900.0]},
        }
        (d / "study.yaml").write_text(dump(study))
        rc, out, err = run_main("validate", str(d / "study.yaml"))
    COUNTS["set_paths_validated"] += 1
    COUNTS[f"set_paths_exit_{rc}"] += 1
    assert rc in (0, 2), (rc, out, err)
    assert "Traceback" not in err
    if rc == 2:
        _assert_invalid_lines(err, d / "study.yaml", d / "model.yaml")
        # a problem of a `set:` entry is at its line in the study (line 3 holds `set:`)
        set_lines = [ln for ln in err.splitlines() if ln.startswith(f"{d / 'study.yaml'}:") and ": set" in ln]
        assert all(re.match(re.escape(str(d / "study.yaml")) + r":\d+: set", ln) for ln in set_lines), err
    else:
        assert out.startswith(f"{d / 'study.yaml'}: valid study (2 variants)"), out


INVALID_AXIS_VALUES = {  # path -> (a valid value, invalid values)
    "springs.body.material.stiffness": (2.0e6, [0.0, -1.0, -5.0e6]),
    "nodes.front.mass": (50.0, [0.0, -50.0]),
    "time_step.safety_factor": (0.5, [0.0, 1.5, 2.0]),
    "springs.damper.material.damping": (100.0, [-1.0, -1e-3]),
}


@settings(max_examples=examples(20, 60), deadline=None, suppress_health_check=list(HealthCheck))
@given(st.sampled_from(sorted(INVALID_AXIS_VALUES)), st.integers(2, 1000), st.data())
def test_an_invalid_value_anywhere_among_up_to_1000_distinct_axis_values_is_caught(
    path: str, n: int, data: st.DataObject
) -> None:
    """Draws 20 axes (60 under ``HYPOTHESIS_PROFILE=explore``, new ones on each run)."""
    from crashstudy.errors import InputError
    from crashstudy.study.plan import load_study

    good, bad_values = INVALID_AXIS_VALUES[path]
    at = data.draw(st.integers(0, n - 1), label="position")
    bad = data.draw(st.sampled_from(bad_values), label="invalid value")
    step = 1e-6 if path == "time_step.safety_factor" else 1e-4
    values = [round(good * (1.0 + step * k), 12) for k in range(n)]  # distinct and valid
    values[at] = bad
    with tempfile.TemporaryDirectory(prefix="crashstudy-prop-") as tmp:
        d = Path(tmp)
        (d / "model.yaml").write_text(SMALL_MODEL)
        (d / "study.yaml").write_text(f"name: axis\nmodel: model.yaml\nmatrix:\n  {path}: {values}\n")
        with pytest.raises(InputError) as info:
            load_study(d / "study.yaml")
    COUNTS["axis_values_checked"] += n
    COUNTS["axis_studies_with_one_invalid_value"] += 1
    problems = info.value.problems
    assert [(p.line, p.field) for p in problems] == [(4, f"matrix.{path}.{at}")], problems
    assert f"value {bad!r} makes the model invalid" in problems[0].message
