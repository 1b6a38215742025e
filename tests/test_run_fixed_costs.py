"""The fixed cost of a run (issue 25 item 2): what a run does not need is never loaded. A run whose
kernel is this shape's compiled generated one never imports the generic kernel's module nor looks at
its cache, and the choice it makes is the one the full comparison makes."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from crashstudy.arrays.batch import build_batch
from crashstudy.arrays.compiler import apply_axis
from crashstudy.kernel import choice
from helpers import model_plan


def _batch(n: int, end_time: float) -> Any:
    model = {"name": "fixedcost", "nodes": {"w": {"position": [0.0], "fixed": True}, "m": {"position": [0.5], "mass": 1.0}},
             "springs": {"s": {"nodes": ["w", "m"], "material": {"type": "linear_elastic", "stiffness": 1.0e5}}},
             "initial_velocity": {"m": [-5.0]}, "end_time": end_time, "output": {"histories": "none"}}  # fmt: skip
    plan = model_plan(model)
    P = np.repeat(plan.base[:, None], n, axis=1)
    apply_axis(P, plan.topology.paths["nodes.m.mass"], np.linspace(1.0, 2.0, n))
    return build_batch(plan.topology, P, plan.interval)[0], plan


def _full_choice(b: Any, repeat: float, generic: bool) -> str:
    """Independent truth: the expected-time comparison of every kernel, as choice.pick documents it."""
    S = len(b.spring_i)
    work = float(np.sum(b.n_steps)) * S * repeat
    t_ref = choice.reference_seconds(float(np.max(b.n_steps)), S, float(np.sum(b.n_steps)) * S) * repeat
    if t_ref <= choice.LOAD:
        return "reference"
    times = {"reference": t_ref, "generated": work / choice.GENERATED_RATE + choice.LOAD}
    if generic:
        times["generic"] = work / choice.GENERIC_RATE + choice.LOAD
    return min(times, key=lambda k: times[k])


@pytest.mark.parametrize("end_time, n, repeat", [(0.05, 64, 1.0), (0.05, 64, 1e4), (0.5, 1000, 100.0), (0.002, 8, 1.0)])
def test_a_ready_generated_kernel_never_loads_the_generic_one(monkeypatch: pytest.MonkeyPatch, end_time: float,
                                                              n: int, repeat: float) -> None:  # fmt: skip
    """With this shape's generated kernel compiled, pick and plan_start never ask whether the generic
    kernel is compiled (that imports its module: ~0.1-0.5 s of a short run) whenever the generated one
    wins anyway; the kernel picked equals the full comparison with the generic kernel compiled."""
    from crashstudy.kernel import generated

    b, plan = _batch(n, end_time)
    asked = []
    monkeypatch.setattr(choice, "_LOADED", set())
    monkeypatch.setattr(choice, "kernel_override", lambda: "compiled")
    monkeypatch.setattr(generated, "is_compiled", lambda *a, **k: True)
    monkeypatch.setattr(choice, "generic_ready", lambda: asked.append(1) or True)
    picked = choice.pick(b, (), None, "compiled", repeat)
    truth = _full_choice(b, repeat, generic=True)
    assert picked == truth
    assert not asked or truth == "generic"
    assert choice.plan_start(b, (), None, int(n * repeat)) is None
    assert not asked or truth == "generic"
