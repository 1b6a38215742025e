"""The kernel choice counts a kernel already loaded in the process as free to start: a short run that the
NumPy reference would finish before a compiled kernel could be loaded still goes to that kernel once it is
loaded (the reference then only loses time). The expected times are the cost model's own
(crashstudy.kernel.choice): the truth here is its arithmetic, written out."""

from __future__ import annotations

import numpy as np
import pytest

from crashstudy.arrays.batch import build_batch
from crashstudy.kernel import choice
from helpers import model_plan

MODEL = {
    "name": "one-spring",
    "nodes": {"a": {"position": [0.0], "fixed": True}, "b": {"position": [0.1], "mass": 1.0}},
    "springs": {"s": {"nodes": ["a", "b"], "material": {"type": "linear_elastic", "stiffness": 2.0e5}}},
    "end_time": 0.02,
    "initial_velocity": {"b": [-10.0]},
    "output": {"histories": "none"},
}


@pytest.mark.parametrize(
    ("loaded", "ready", "expected"),
    [
        (set(), True, "reference"),  # compiled on disk but not loaded: loading it costs more than the run
        ({"generic"}, True, "generic"),  # loaded: it starts at once and runs ~1000x quicker
        ({"generated"}, False, "reference"),  # another shape's generated kernel loaded, no generic kernel
    ],
)
def test_a_short_run_takes_a_kernel_already_loaded(
    monkeypatch: pytest.MonkeyPatch, loaded: set[str], ready: bool, expected: str
) -> None:
    plan = model_plan(MODEL)
    batch, _ = build_batch(plan.topology, plan.base[:, None].copy(), plan.interval)
    S, steps = 1, float(batch.n_steps.max())
    t_ref = choice.reference_seconds(steps, S, steps * S)
    assert t_ref < choice.LOAD  # the case: the reference beats loading any compiled kernel
    assert steps * S / choice.GENERIC_RATE < t_ref  # ... but not a generic kernel that is already loaded
    monkeypatch.setattr(choice, "_LOADED", loaded)
    monkeypatch.setattr(choice, "generic_ready", lambda: ready)
    monkeypatch.setattr(choice, "generated_ready", lambda *a, **k: False)
    monkeypatch.setattr(choice, "own_compile_running", lambda: False)
    assert choice.pick(batch, plan.topology.histories, None) == expected
    assert np.all(batch.n_steps == steps)
