"""Property-based tests (hypothesis) of the command line on generated models, studies and corruptions.

Six properties, each through :func:`crashstudy.cli.main` in this process, as a user's command would run
(4-6 at the end: random ``set:`` paths never crash ``validate``; one invalid value among up to 1000
distinct axis values is caught at its position; random options of ``compare`` and ``summary`` exit 0,
1 or 2 without a traceback):

1. **Random valid models run or fail cleanly.** 1-D and 2-D trees of 2-6 nodes, every material type with
   valid curves, random masses, velocities, optional gravity, loads with time curves and rigid walls, all
   three unit systems, ``safety_factor`` or ``tolerance`` steps. ``simulate`` returns 0 or 1 and never
   raises; on 1 the summary says ``failed`` with a non-empty reason; on 0 ``energy_error`` is finite.
2. **Random corruptions of valid files never crash ``validate``.** A valid model or study text (generated
   or one of the examples in ``studies/``) with 1-3 corruptions (a deleted, duplicated or swapped line,
   a number turned into text, NaN, infinity or a huge number, swapped ids, random bytes, truncation, a
   broken indent) -> exit 0, 1 or 2 and no exception; on 2 stderr is ``error: invalid input`` followed by
   ``file[:line]: ...`` problem lines, no traceback.
3. **Random valid studies count their variants right.** Random axes among valid paths of a small model,
   random zip groups: the variant count equals the product of the matrix axis lengths and of the zip group
   lengths, ``run --dry-run`` prints it, ``validate`` says it, and the variants are numbered row-major.

The number of generated inputs that actually ran is counted and printed at the end of the module (run
with ``-s`` to see it); docs/robustness.md quotes it.

How many examples each property draws is :func:`strategies.examples`: few in the default profile (the same
derandomized examples on every run, so that CI never fails on a new draw and the suite stays fast; each
test's docstring says how many), and as many as docs/robustness.md's counts, new ones on every run, under
``HYPOTHESIS_PROFILE=explore``.
"""

from __future__ import annotations

import contextlib
import itertools
import math
import os
import re
import shutil
import tempfile
from collections import Counter
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from crashstudy.results.store import Results
from helpers import STUDIES, dump, run_main
from models import wall_spring
from strategies import examples, num, valid_model

COUNTS: Counter[str] = Counter()


@pytest.fixture(scope="module", autouse=True)
def _report_counts() -> Iterator[None]:
    yield
    if COUNTS:
        print(
            "\n[test_properties] generated inputs run: "
            + ", ".join(f"{k}={v}" for k, v in sorted(COUNTS.items()))
        )


# ------------------------------------------------------------------------------------------------
# 1. valid models run or fail with a clear status
# ------------------------------------------------------------------------------------------------


@contextlib.contextmanager
def _environ(**values: str) -> Iterator[None]:
    """Environment variables set for the duration (for a hypothesis test, where a function-scoped
    ``monkeypatch`` would be shared by all examples)."""
    old = {k: os.environ.get(k) for k in values}
    os.environ.update(values)
    try:
        yield
    finally:
        for k, v in old.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


@settings(max_examples=examples(40, 120), deadline=None, suppress_health_check=list(HealthCheck))
@given(valid_model())
def test_random_valid_model_runs_or_fails_with_a_clear_status(model: dict[str, Any]) -> None:
    """Draws 40 models (120 under ``HYPOTHESIS_PROFILE=explore``, new ones on each run). They run on the
    generic compiled kernel (``CRASHSTUDY_KERNEL=generic``; the three kernels give bitwise equal results,
    docs/kernels.md): where the generic kernel is not in the cache yet (a first ``pytest -n 0``), the
    automatic choice compiles a generated kernel per model shape, 3-10 s each, which this property is not about."""
    with tempfile.TemporaryDirectory(prefix="crashstudy-prop-") as tmp, _environ(CRASHSTUDY_KERNEL="generic"):
        path = Path(tmp) / "model.yaml"
        path.write_text(dump(model), encoding="utf-8")
        rc, out, err = run_main("validate", str(path))
        assert rc == 0, f"generated model is not valid:\n{err}\n{dump(model)}"
        rc, out, err = run_main("simulate", str(path), "-o", str(Path(tmp) / "out"))
        COUNTS["models_simulated"] += 1
        assert rc in (0, 1), (rc, out, err)
        assert "Traceback" not in err
        res = Results(Path(tmp) / "out")
        row = res.summary.iloc[0]
        res.close()
        checked = _well_posed(model)
        if rc == 1:
            COUNTS["models_failed_cleanly"] += 1
            speeds = [abs(v) for vec in model.get("initial_velocity", {}).values() for v in vec]
            kind = (
                "extreme speed"
                if any(v > 1e100 for v in speeds)
                else "at rest"
                if not any(speeds)
                else "moving"
            )
            COUNTS[f"failure ({kind}): " + str(row["failure_reason"]).split(" at t=")[0].split(" (")[0]] += 1
            assert row["status"] == "failed", row
            assert str(row["failure_reason"]).strip(), row
            assert "failed: " in err and str(row["failure_reason"]) in err
            # a well-posed model may only fail because a 2-D spring collapsed, never as "unstable"
            assert not checked or "crushed to zero length" in row["failure_reason"], (
                row["failure_reason"],
                dump(model),
            )
        else:
            COUNTS["models_ok"] += 1
            assert row["status"] == "ok", row
            assert np.isfinite(row["energy_error"]), row
            if checked:
                # the work of a kink inside a step (yield, unloading, a curve knot) is integrated to second
                # order, so not quite round-off (up to ~3e-6 seen); a damper's work is second-order accurate
                # (about 5 % at safety_factor 1). An accounting bug shows as 1e-3 ... 1 (see the xfails below)
                dampers = any(sp["material"]["type"] == "damper" for sp in model["springs"].values())
                COUNTS["models_energy_balance_checked"] += 1
                assert row["energy_error"] < (0.1 if dampers else 1e-3), (
                    row["energy_error"],
                    dump(model),
                )  # energy balance target 1e-3


def _well_posed(model: dict[str, Any]) -> bool:
    """No rigid wall and moving at the start (KE0 > 0), at most 1 km/s (preloads included: IE0 is in the balance).

    Such a model must run (or fail only by a 2-D collapse) with a small ``energy_error``. Excluded, each
    with its own test below: walls (:func:`test_energy_error_of_a_node_that_reaches_a_wall_in_the_first_step`),
    a preload released from rest (:func:`test_preloaded_spring_keeps_the_energy_balance`) and models that start
    at rest, where ``energy_error`` is relative to a tiny number (:func:`test_model_at_rest_until_a_late_load_runs`).
    """
    if model.get("rigid_walls"):
        return False
    speeds = [abs(v) for vec in model.get("initial_velocity", {}).values() for v in vec]
    return any(speeds) and all(v <= 1e3 for v in speeds)


AT_REST = """\
name: pulse-from-rest
curves:
  load: {x: [-0.097332, -0.087526, -0.009807, 0.0, 0.128734], y: [-822.644089, -822.644089, -61.823486, 0.0, 0.0]}
  unload: {x: [-0.01, 0.0, 0.01], y: [-1000.0, 0.0, 1000.0]}
  pulse: {x: [0.005, 0.01, 0.02], y: [0.0, 1.0, 0.0]}
nodes:
  a: {position: [0.0], fixed: true}
  b: {position: [1.0], mass: 10.0}
springs:
  s: {nodes: [a, b], material: {type: general_nonlinear, loading: load, unloading: unload}}
loads:
  - {node: b, force: [-1000.0], curve: pulse}
end_time: 0.05
output: {histories: none}
"""


def test_model_at_rest_until_a_late_load_runs(tmp_path: Path) -> None:
    path = tmp_path / "at-rest.yaml"
    path.write_text(AT_REST)
    rc, out, err = run_main("simulate", str(path), "-o", str(tmp_path / "out"))
    assert rc == 0, err
    res = Results(tmp_path / "out")
    row = res.summary.iloc[0]
    res.close()
    assert row["status"] == "ok" and row["energy_error"] < 1e-6


@pytest.mark.parametrize("kernel", ["reference", "generic", "generated"])
@pytest.mark.parametrize("wall", ["1.0", "0.99996"], ids=["starts-on-the-wall", "wall-within-first-step"])
def test_energy_error_of_a_node_that_reaches_a_wall_in_the_first_step(
    tmp_path: Path, wall: str, kernel: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A 1 kg mass at 10 m/s (dt = 1e-5 s, 1e-4 m per step) hits a stonewall at once: all 50 J go into
    ``wall_energy``, KE + IE + E_wall - W_ext must stay 50 J at every sample and ``energy_error`` be round-off.
    (Found by the model generator: the t = 0 balance and record held that first impact's wall energy
    while the kinetic energy was still KE0, energy_error 1 - gap / (v dt): 1.0 on the plane, 0.4 for
    the wall at 0.99996. The t = 0 state is now the one before any impact, on every kernel.)
    The run lasts 10 steps (1e-4 s; 1000 before): the node rests on the wall after the first step, and
    the bug shows at the t = 0 sample. Planted (the reference's t = 0 record keeping the first impact's
    wall energy): fails at 10 steps as at 1000."""
    monkeypatch.setenv("CRASHSTUDY_KERNEL", kernel)
    path = tmp_path / "wall-start.yaml"
    path.write_text(wall_spring(wall, end_time=1.0e-4))
    rc, out, err = run_main("simulate", str(path), "-o", str(tmp_path / "out"))
    assert rc == 0, err
    res = Results(tmp_path / "out")
    ds = res.dataset
    balance = (ds["kinetic_energy"] + ds["internal_energy"] + ds["wall_energy"] - ds["external_work"]).values[
        0
    ]
    final_wall = float(ds["wall_energy"][0, -1])
    err_value = float(ds["energy_error"][0])
    res.close()
    assert final_wall == pytest.approx(50.0)
    assert np.abs(balance - 50.0).max() < 1e-6, f"KE + IE + E_wall - W_ext over time: {balance[:3]} ..."
    assert err_value < 1e-6, f"energy_error {err_value} for a run that conserves energy"


PRELOADED = """\
name: preloaded
nodes:
  a: {position: [0.0], fixed: true}
  b: {position: [0.5], mass: 10.0}
curves:
  constant-pull: {x: [0.0, 0.001, 1.0], y: [0.0, 1000.0, 1000.0]}
springs:
  s: {nodes: [a, b], material: {type: nonlinear_elastic, curve: constant-pull}, initial_elongation: 0.5}
SPEED
end_time: 0.05
time_step: {dt: 1.0e-3}
output: {interval: 1.0e-3, histories: all}
"""


@pytest.mark.parametrize("speed", [None, 0.1], ids=["released-from-rest", "slow-start"])
def test_preloaded_spring_keeps_the_energy_balance(tmp_path: Path, speed: float | None) -> None:
    """A constant 1000 N pull on 10 kg (a preload on the flat part of the curve, e = 0.5 ... 0.375 m):
    x(t) = 0.5 + v0 t - 50 t^2, which central difference integrates exactly; the energy balance must hold
    to round-off and the variant must not fail.

    Formerly a BUG (found by the model generator), written as a curve with C(0) = 1000 N: the force present
    at t = 0 was left out of the first half step's work (KE + IE - KE0 - W_ext off by F0^2 dt^2 / (8 m),
    0.0125 J here), which released from rest (KE0 = W_ext = 0) failed as 'numerical instability' and at
    0.1 m/s gave energy_error = 0.25. Such a curve is now an input error; with initial_elongation the first
    half step books F0 on the mean rate and IE0 is in the balance."""
    path = tmp_path / "preloaded.yaml"
    path.write_text(
        PRELOADED.replace("SPEED", "" if speed is None else f"initial_velocity: {{b: [{speed}]}}")
    )
    rc, out, err = run_main("simulate", str(path), "-o", str(tmp_path / "out"))
    res = Results(tmp_path / "out")
    ds = res.dataset
    x_end = float(ds["position"][0, -1, 1, 0])
    balance = (ds["kinetic_energy"] + ds["internal_energy"] - ds["external_work"]).values[0]
    err_value = float(ds["energy_error"][0])
    res.close()
    assert rc == 0, err
    v0 = speed or 0.0
    assert x_end == pytest.approx(0.5 + v0 * 0.05 - 50.0 * 0.05**2, abs=1e-12)
    assert np.abs(balance - balance[0]).max() < 1e-9, balance[:3] - balance[0]
    assert err_value < 1e-6


# ------------------------------------------------------------------------------------------------
# 2. corrupted files: validate exits 0, 1 or 2 and never raises
# ------------------------------------------------------------------------------------------------

EXAMPLE_MODELS = sorted((STUDIES / "models").glob("*.yaml"))
EXAMPLE_STUDIES = sorted(STUDIES.glob("*.yaml"))
NUMBER = re.compile(r"(?<![\w.])-?\d+(?:\.\d*)?(?:[eE][-+]?\d+)?(?![\w.])")
ID_WORD = re.compile(r"\b[a-z][a-z0-9_]*(?:-[a-z0-9_]+)*\b")
BAD_NUMBERS = [
    ".nan",
    ".inf",
    "-.inf",
    "1e400",
    "-1e400",
    "1.0e308",
    "9" * 40,
    "9" * 5000,
    "0",
    "-0.0",
    "1e-320",
    "0x7f",
    "0o17",
    "'1.0'",
    "1_000",
    "NaN",
    "inf",
    "12abc",
    "~",
    "[]",
    "{}",
    "true",
]


@st.composite
def corrupt(draw: st.DrawFn, text: str) -> bytes:
    """``text`` with 1-3 random corruptions, as bytes (some corruptions are not valid UTF-8)."""
    data = text.encode("utf-8")
    for _ in range(draw(st.integers(1, 3))):
        s = data.decode("utf-8", "surrogateescape")
        lines = s.splitlines(keepends=True) or [""]
        op = draw(
            st.sampled_from(
                [
                    "delete-line",
                    "number-to-text",
                    "bad-number",
                    "duplicate-line",
                    "swap-lines",
                    "swap-ids",
                    "random-bytes",
                    "truncate",
                    "indent",
                    "replace-char",
                ]
            )
        )
        COUNTS[f"corruption:{op}"] += 1
        if op == "delete-line":
            del lines[draw(st.integers(0, len(lines) - 1))]
            s = "".join(lines)
        elif op in ("number-to-text", "bad-number"):
            nums = list(NUMBER.finditer(s))
            if not nums:
                continue
            m = draw(st.sampled_from(nums))
            new = (
                draw(st.sampled_from(["heavy", "x", "one", "1.0.0", "1,5", "12 kg", "'3'"]))
                if op == "number-to-text"
                else draw(st.sampled_from(BAD_NUMBERS))
            )
            s = s[: m.start()] + new + s[m.end() :]
        elif op == "duplicate-line":
            k = draw(st.integers(0, len(lines) - 1))
            lines.insert(k, lines[k])
            s = "".join(lines)
        elif op == "swap-lines":
            i, j = draw(st.integers(0, len(lines) - 1)), draw(st.integers(0, len(lines) - 1))
            lines[i], lines[j] = lines[j], lines[i]
            s = "".join(lines)
        elif op == "swap-ids":
            words = sorted({m.group() for m in ID_WORD.finditer(s)})
            if len(words) < 2:
                continue
            a, b = draw(st.sampled_from(words)), draw(st.sampled_from(words))
            s = re.sub(rf"\b{re.escape(a)}\b", "\0", s)
            s = re.sub(rf"\b{re.escape(b)}\b", a, s).replace("\0", b)
        elif op == "random-bytes":
            raw = s.encode("utf-8", "surrogateescape")
            k = draw(st.integers(0, len(raw)))
            raw = raw[:k] + draw(st.binary(min_size=1, max_size=8)) + raw[k:]
            s = raw.decode("utf-8", "surrogateescape")
        elif op == "truncate":
            s = s[: draw(st.integers(0, len(s)))]
        elif op == "indent":
            k = draw(st.integers(0, len(lines) - 1))
            lines[k] = draw(st.sampled_from([" ", "   ", "\t", ""])) + lines[k].lstrip(" ")
            s = "".join(lines)
        else:
            if not s:
                continue
            k = draw(st.integers(0, len(s) - 1))
            s = s[:k] + draw(st.sampled_from(list(":-[]{},&*!#'\"|>%@`"))) + s[k + 1 :]
        data = s.encode("utf-8", "surrogateescape")
    return data


@pytest.fixture(scope="module")
def studies_copy(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A copy of ``studies/`` so that corrupted study files find their models."""
    dst = tmp_path_factory.mktemp("studies") / "studies"
    shutil.copytree(STUDIES, dst)
    return dst


def _check_validate(path: Path, model_path: Path | None = None) -> None:
    rc, out, err = run_main("validate", str(path))
    COUNTS["corrupted_files_validated"] += 1
    COUNTS[f"validate_exit_{rc}"] += 1
    assert rc in (0, 1, 2), (rc, out, err)
    assert "Traceback" not in err and "Traceback" not in out
    if rc == 2:
        lines = err.splitlines()
        assert lines[0] == "error: invalid input", err
        files = [str(path)] + ([str(model_path)] if model_path else [])
        assert len(lines) >= 2
        for ln in lines[1:]:
            assert ln.startswith("... and ") or any(ln.startswith(f + ":") for f in files), (ln, err)
        with_line = [ln for ln in lines[1:] if any(re.match(re.escape(f) + r":\d+: ", ln) for f in files)]
        if with_line:
            COUNTS["invalid_with_line_number"] += 1
        else:  # only a problem with the file as a whole has no line (encoding, size, missing model)
            assert any(w in err for w in ("not UTF-8", "too large", "not found", "cannot read")), err
    elif rc == 0:
        assert re.search(r": valid (model|study) \(", out), out


@settings(max_examples=examples(100, 250), deadline=None, suppress_health_check=list(HealthCheck))
@given(st.data())
def test_corrupted_model_text_never_crashes_validate(studies_copy: Path, data: st.DataObject) -> None:
    """Draws 100 corrupted models (250 under ``HYPOTHESIS_PROFILE=explore``, new ones on each run)."""
    source = data.draw(st.sampled_from(["generated"] + [p.name for p in EXAMPLE_MODELS]), label="source")
    text = (
        dump(data.draw(valid_model(), label="model"))
        if source == "generated"
        else (STUDIES / "models" / source).read_text(encoding="utf-8")
    )
    raw = data.draw(corrupt(text), label="corrupted")
    path = studies_copy / "models" / "corrupted-model.yaml"
    path.write_bytes(raw)
    _check_validate(path)


@settings(max_examples=examples(60, 150), deadline=None, suppress_health_check=list(HealthCheck))
@given(st.data())
def test_corrupted_study_text_never_crashes_validate(studies_copy: Path, data: st.DataObject) -> None:
    """Draws 60 corrupted studies (150 under ``HYPOTHESIS_PROFILE=explore``, new ones on each run)."""
    source = data.draw(st.sampled_from([p.name for p in EXAMPLE_STUDIES]), label="source")
    text = (STUDIES / source).read_text(encoding="utf-8")
    raw = data.draw(corrupt(text), label="corrupted")
    path = studies_copy / "corrupted-study.yaml"
    path.write_bytes(raw)
    model = re.search(rb"^model:\s*(\S+)", raw, re.M)
    model_path = (studies_copy / model.group(1).decode("utf-8", "replace")).resolve() if model else None
    _check_validate(path, model_path)


# ------------------------------------------------------------------------------------------------
# 3. random valid studies: variant count and numbering
# ------------------------------------------------------------------------------------------------

SMALL_MODEL = """\
name: small
units: SI
curves:
  crush-loading: {x: [-0.2, -0.02, 0.0], y: [-60000.0, -40000.0, 0.0]}
  pulse: {x: [0.0, 0.005, 0.01], y: [0.0, 1.0, 0.0]}
nodes:
  wall:  {position: [0.0], fixed: true}
  front: {position: [0.3], mass: 50.0}
  body:  {position: [0.9], mass: 800.0}
springs:
  crush:
    nodes: [wall, front]
    material: {type: crush, loading: crush-loading, unloading_stiffness: 5.0e6}
  body:
    nodes: [front, body]
    material: {type: linear_elastic, stiffness: 2.0e6}
  damper:
    nodes: [front, body]
    material: {type: damper, damping: 100.0}
initial_velocity: {front: [-10.0], body: [-10.0]}
gravity: [0.0]
loads:
  - {node: body, force: [-100.0], curve: pulse}
end_time: 0.02
time_step: {safety_factor: 0.9}
output: {interval: 1.0e-3, histories: none}
"""

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
# 4. random `set:` paths, 5. an invalid value among up to 1000 distinct axis values,
# 6. random options of `compare` and `summary`
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


@pytest.fixture(scope="module")
def two_results(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    root = tmp_path_factory.mktemp("options")
    (root / "model.yaml").write_text(SMALL_MODEL)
    (root / "study.yaml").write_text(
        "name: opts\nmodel: model.yaml\nmatrix:\n  nodes.body.mass: [800.0, 900.0, "
        "1000.0]\n  impact_velocity: [5.0, 10.0]\n"
    )
    for name in ("new", "base"):
        rc, _, err = run_main("run", str(root / "study.yaml"), "-o", str(root / name), "--progress", "off")
        assert rc == 0, err
    return root / "new", root / "base"


WORDS = st.sampled_from(
    [
        "peak",
        "peak_force",
        "crush",
        "body",
        "variant",
        "status",
        "nodes.body.mass",
        "x",
        "",
        "energy_error",
        "dt",
        "-1",
        "nan",
        "impact_velocity",
        "failure_reason",
        "zzz",
    ]
)
NUMBERS = st.sampled_from(
    ["0", "1", "-1", "1e-6", "0.5", "nan", "inf", "-inf", "1e308", "abc", "", "5", "100", "-3", "2.5"]
)


@st.composite
def options(draw: st.DrawFn, command: str) -> list[str]:
    picked = draw(
        st.lists(
            st.sampled_from(
                {
                    "summary": ["--sort", "--ascending", "--head", "--columns", "--variant"],
                    "compare": ["--rtol", "--atol", "--junit"],
                }[command]
            ),
            unique=True,
            max_size=4,
        )
    )
    args: list[str] = []
    for opt in picked:
        if opt == "--ascending":
            args.append(opt)
        elif opt == "--columns":
            args += [opt, *draw(st.lists(WORDS, min_size=1, max_size=3))]
        elif opt in ("--sort",):
            args += [opt, draw(WORDS)]
        elif opt == "--junit":
            args += [
                opt,
                draw(st.sampled_from(["report.xml", "summary.csv", "results.nc", "sub/none/r.xml"])),
            ]
        else:
            args.append(f"{opt}={draw(NUMBERS)}")
    return args


@settings(max_examples=examples(40, 120), deadline=None, suppress_health_check=list(HealthCheck))
@given(st.sampled_from(["summary", "compare"]), st.data())
def test_random_options_of_compare_and_summary_exit_0_1_or_2_without_a_traceback(
    two_results: tuple[Path, Path], command: str, data: st.DataObject
) -> None:
    """Draws 40 command lines (120 under ``HYPOTHESIS_PROFILE=explore``, new ones on each run)."""
    new, base = two_results
    args = data.draw(options(command), label="options")
    with tempfile.TemporaryDirectory(prefix="crashstudy-prop-") as tmp, contextlib.chdir(tmp):
        # argparse's exit (a value that is not a number, an option without its value) is run_main's exit code
        rc, out, err = run_main(command, str(new), *((str(base),) if command == "compare" else ()), *args)
    COUNTS[f"{command}_options_run"] += 1
    COUNTS[f"{command}_options_exit_{rc}"] += 1
    assert rc in ((0, 2) if command == "summary" else (0, 1, 2)), (args, rc, out, err)
    assert "Traceback" not in err
    if (
        rc == 2 and err
    ):  # ours, or argparse's usage line for a value that is no number / an option without one
        assert err.startswith(("error: invalid input\n", "usage: crashstudy ")), (args, err)
    if rc == 1:  # compare only (two runs of one study): a verdict, never a crash
        assert out.splitlines()[-1].startswith("FAILED"), out
