"""Shared test helpers: run a model given as YAML text or a dict, with either kernel."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

from crashstudy.arrays.batch import build_batch
from crashstudy.kernel.output import KernelOutput
from crashstudy.schema import parse_model
from crashstudy.schema.yamlio import loads_yaml
from crashstudy.study.plan import Plan, plan_from_model

ROOT = Path(__file__).resolve().parents[1]
STUDIES = ROOT / "studies"
sys.path.insert(0, str(Path(__file__).resolve().parent))  # for `import reference_scipy`
# runs started by tests never leave a compiler running behind them (tests of it set this themselves)
os.environ["CRASHSTUDY_BACKGROUND_COMPILE"] = "0"

# property tests draw the same examples on every run (CI must not fail on a new random draw);
# HYPOTHESIS_PROFILE=explore draws new ones, as for the counts in docs/robustness.md
from hypothesis import settings  # noqa: E402

settings.register_profile("default", derandomize=True)
settings.register_profile("explore", derandomize=False)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "default"))


LINEAR_SPRING = """\
name: lin
units: SI
nodes:
  anchor: {position: [0.0], fixed: true}
  body: {position: [0.1], mass: 2.0}
springs:
  s: {nodes: [anchor, body], material: {type: linear_elastic, stiffness: 2.0e4}}
initial_velocity: {body: [1.0]}
end_time: 0.1
"""  # a 2 kg body on a 2e4 N/m spring at 1 m/s: the optimize / calibrate / block-check tests' model


def noisy_spring_force(k: float, m: float, noise: float = 0.01) -> tuple[np.ndarray, np.ndarray]:
    """(t, force) of k [N/m], m [kg] set moving at 1 m/s, integrated by scipy's RK45 (rtol 1e-10) and
    sampled at 201 points over 0.1 s, with Gaussian noise of ``noise`` x the peak force (seed 0)."""
    from scipy.integrate import solve_ivp

    sol = solve_ivp(lambda t, y: [y[1], -k / m * y[0]], (0.0, 0.1), [0.0, 1.0], rtol=1e-10, atol=1e-12,
                    dense_output=True)  # fmt: skip
    t = np.linspace(0.0, 0.1, 201)
    force = k * sol.sol(t)[0]
    return t, force + np.random.default_rng(0).normal(0.0, noise * np.abs(force).max(), t.size)


def model_plan(model: str | dict[str, Any]) -> Plan:
    """A one-variant plan from YAML text or a plain dict (validated like a file)."""
    text = model if isinstance(model, str) else yaml.safe_dump(model, sort_keys=False)
    return plan_from_model(parse_model(loads_yaml(text, file="<test model>")))


def model_batch(model: str | dict[str, Any], variants: dict[str, list[float]] | None = None) -> tuple[Any, Plan]:
    """(batch, plan) of a model with axis values per variant ({path: [v0, v1, ...]}; one variant without)."""
    from crashstudy.arrays.compiler import apply_axis

    plan = model_plan(model)
    topo = plan.topology
    n = len(next(iter(variants.values()))) if variants else 1
    P = np.repeat(plan.base[:, None], n, axis=1)
    for path, vals in (variants or {}).items():
        apply_axis(P, topo.paths[path], np.asarray(vals, dtype=float))
    batch, _ = build_batch(topo, P, plan.interval)
    return batch, plan


def run_model(model: str | dict[str, Any], kernel: str = "compiled", variants: dict[str, list[float]] | None = None
              ) -> tuple[KernelOutput, Any, Plan]:  # fmt: skip
    """Run a model (optionally with axis values per variant: {path: [v0, v1, ...]}).

    Returns (kernel output, batch, plan); histories follow the model's ``output.histories``.
    """
    from crashstudy.run.runner import run_kernel

    batch, plan = model_batch(model, variants)
    out = run_kernel(batch, plan.topology.histories, plan.n_out, kernel)
    return out, batch, plan


def run_cli(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    """Run the installed command line in a subprocess (as a user would)."""
    return subprocess.run([sys.executable, "-m", "crashstudy.cli", *args], capture_output=True, text=True,
                          cwd=cwd, timeout=600)  # fmt: skip


@pytest.fixture
def cli():
    return run_cli


def pytest_configure(config: pytest.Config) -> None:
    """Compile (or load from numba's cache) the generic kernel once, in the main process, before any
    test or xdist worker needs it: workers then load the cached machine code instead of compiling it
    again. Meanwhile a second process compiles, on the other core, the crash criteria and the slowest
    generated kernels of the twin tests (:func:`warm_other_core`), which the workers then load too."""
    if hasattr(config, "workerinput"):
        return
    other = subprocess.Popen([sys.executable, "-c", "import conftest; conftest.warm_other_core()"],
                             cwd=Path(__file__).resolve().parent)  # fmt: skip
    run_model({"name": "warm-up", "nodes": {"a": {"position": [0.0], "fixed": True},
                                            "b": {"position": [1.0], "mass": 1.0}},
               "springs": {"s": {"nodes": ["a", "b"], "material": {"type": "linear_elastic", "stiffness": 1.0}}},
               "end_time": 0.01, "output": {"histories": "none"}}, kernel="generic")  # fmt: skip
    other.wait()


WARM_RECORD_CASES = ("frontal-lane-compaction", "full-twin-2d-mixed-prescribed")  # the slowest compiles (~10 s each)


def record_case(case: str) -> tuple[Any, Plan, tuple[int, ...]]:
    """(batch, plan, record) of a tests/test_kernel_twins.py case run with the per-step record of every
    movable node (tests/test_metrics.py)."""
    from test_kernel_twins import CASES

    build, axes, _ = CASES[case]
    batch, plan = model_batch(build(), axes)
    topo = plan.topology
    record = tuple(n for n in range(topo.n_nodes) if not topo.fixed[n].all() or n in batch.pm_node)
    return batch, plan, record


def warm_other_core() -> None:
    """Compile the crash criteria and the generated kernels, with the per-step record, of
    ``WARM_RECORD_CASES`` exactly as tests/test_metrics.py runs them (the same batch: the same shape key)."""
    from crashstudy.kernel.entry import run_batch
    from crashstudy.metrics.warmup import compile_criteria

    compile_criteria()
    for case in WARM_RECORD_CASES:
        batch, plan, record = record_case(case)
        run_batch(batch, plan.topology.histories, plan.n_out, "generated", record=record)
