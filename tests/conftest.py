"""pytest set-up: the tests' import path, environment and hypothesis profile, the ``cli`` fixture, and the
compile warm-up of a parallel run. What the test modules share is in helpers.py (and twins.py,
twin_models.py, twin_v2_models.py, model_parts.py, strategies.py, pulses.py, models.py, stress_models.py,
folders.py). The module fixtures that the test files of one subject share are defined in their helper
modules (analysis_study.py, fault_runs.py, plot_results.py, study_cases.py) and registered here by import."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

sys.path.insert(
    0, str(Path(__file__).resolve().parent)
)  # for `import helpers`, `import reference_scipy`, ...
# runs started by tests never leave a compiler running behind them (tests of it set this themselves)
os.environ["CRASHSTUDY_BACKGROUND_COMPILE"] = "0"

# property tests draw the same examples on every run (CI must not fail on a new random draw);
# HYPOTHESIS_PROFILE=explore draws new ones, as for the counts in docs/robustness.md
from hypothesis import settings  # noqa: E402

from analysis_study import tied  # noqa: E402, F401 - the fixture of tests/test_analysis_output_*.py
from fault_runs import fault_dir, reference  # noqa: E402, F401 - fixtures of tests/test_faults_*.py
from helpers import (  # noqa: E402, F401 - re-exported: test files written against conftest import these from it
    LINEAR_SPRING,
    ROOT,
    STUDIES,
    model_batch,
    model_plan,
    noisy_spring_force,
    run_cli,
    run_model,
)
from plot_results import opened, small  # noqa: E402, F401 - fixtures of tests/test_plot_*.py
from study_cases import matrix_run, matrix_study, work  # noqa: E402, F401 - fixtures of tests/test_study_*.py
from twins import record_case  # noqa: E402, F401 - re-exported likewise

settings.register_profile("default", derandomize=True)
settings.register_profile("explore", derandomize=False)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "default"))


@pytest.fixture
def cli():
    """``crashstudy ARGS`` in this process (helpers.run_cli); helpers.run_cli_process for a real process."""
    return run_cli


def pytest_configure(config: pytest.Config) -> None:
    """In a parallel run (``-n N``), compile (or load from numba's cache) the generic kernel once, before
    any xdist worker needs it: workers then load the cached machine code instead of each compiling it.
    Meanwhile a second process compiles, on the other core, the slowest generated kernel of the twin tests,
    the generated kernel that the physics tests' side-by-side model shares and the crash criteria
    (:func:`warm_other_core`: about as long as the generic kernel alone), which the workers then load too
    (two workers would otherwise compile a shared shape at once). A run without workers (one file,
    ``-n 0``) compiles only what its tests ask for, when they ask."""
    if hasattr(config, "workerinput") or not getattr(config.option, "numprocesses", None):
        return
    other = subprocess.Popen(
        [sys.executable, "-c", "import conftest; conftest.warm_other_core()"],
        cwd=Path(__file__).resolve().parent,
    )
    run_model(
        {
            "name": "warm-up",
            "nodes": {"a": {"position": [0.0], "fixed": True}, "b": {"position": [1.0], "mass": 1.0}},
            "springs": {"s": {"nodes": ["a", "b"], "material": {"type": "linear_elastic", "stiffness": 1.0}}},
            "end_time": 0.01,
            "output": {"histories": "none"},
        },
        kernel="generic",
    )
    other.wait()


def warm_other_core() -> None:
    """Compile the generated kernels of ``twins.WARM_RECORD_CASES`` exactly as tests/test_kernel_twins.py
    runs them (the same batch and record: the same shape key; tests/test_metrics_record.py's block-record twins
    share it), the shape of ``helpers.generated_part`` (any step: the shape key has none) and the crash
    criteria."""
    from crashstudy.kernel.entry import run_batch
    from crashstudy.metrics.warmup import compile_criteria
    from helpers import generated_parts_model
    from twins import WARM_RECORD_CASES

    for case in WARM_RECORD_CASES:
        batch, plan, record = record_case(case)
        run_batch(batch, plan.topology.histories, plan.n_out, "generated", record=record)
    # in this process (run_batch without a stop check: no compile child), the shape helpers.generated_part runs
    batch, plan = model_batch(*generated_parts_model(1e-4, 1e-3, 1e-3))
    run_batch(batch, plan.topology.histories, plan.n_out, "generated")
    compile_criteria()


# The slowest tests of a parallel run on empty caches (``--durations``, 2 cores), slowest first. pyproject's
# ``--dist worksteal`` gives each worker a contiguous share of the collection, these at the head of the first
# share; a worker that runs out takes half of what is left of the other's share, from its tail. So none of
# them starts last and leaves a core idle at the end. The twin cases come before tests/test_metrics_record.py's
# block-record twins, which run the same generated kernel shapes (twins.RECORD_CASES) and then load them from
# the cache that the twin case has just written, instead of compiling them at the same time.
SLOW_FIRST = (
    "test_kernel_twins.py::test_fast_kernels_bitwise_equal_to_reference[1d-knots-constant-and-scaled-crush-rebound-reversal-v2-spring-features-and-rate-elastic]",
    "test_kernel_twins.py::test_fast_kernels_bitwise_equal_to_reference[2d-v2-spring-features-rate-elastic-and-knots]",
    "test_kernel_twins.py::test_fast_kernels_bitwise_equal_to_reference[full-twin-1d-every-material-both-ways-scaled-curves]",
    "test_scale.py::test_peak_memory_of_a_run_and_of_its_rerun_does_not_grow_with_the_variants",
    "test_kernel_twins.py::test_fast_kernels_bitwise_equal_to_reference[full-twin-2d-mixed-prescribed-helicopter-rigid-and-penalty-walls]",
    "test_kernel_twins.py::test_fast_kernels_bitwise_equal_to_reference[early-termination]",
    "test_kernel_twins.py::test_fast_kernels_bitwise_equal_to_reference",  # the other cases
    "test_invariants.py::test_a_mass_stopped_over_a_crush_d_peaks_at_least_at_v0_squared_over_2d",
    "test_stress.py::test_instability_forced_by_hand_fails_that_variant_only",
    "test_metrics_record.py::test_block_record_is_bitwise_the_references_on_the_fast_kernels",
)


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """In a parallel run, the tests of :data:`SLOW_FIRST` first, in its order (the first entry a test's
    id contains); the others keep their order. Every worker collects, so every worker sorts alike."""
    if not getattr(config.option, "numprocesses", None) and not hasattr(config, "workerinput"):
        return

    def rank(item: pytest.Item) -> int:
        return next((k for k, slow in enumerate(SLOW_FIRST) if slow in item.nodeid), len(SLOW_FIRST))

    items.sort(key=rank)  # stable: the order of the rest is kept
