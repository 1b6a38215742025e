"""Several one-variant models of ONE topology run as the variants ("lanes") of one kernel call.

The NumPy reference kernel costs about the same per step for one variant as for a few (it is vectorised
over the variants; its cost is the Python work of each step), so physics tests that run the same model with
other numbers (a speed, a direction, a failure option, a time step) run them side by side here, each test's
assertions then read its own lane. Every lane's parameter vector is exactly the one its model alone builds
(``plan.base``), and the kernels keep variants independent (tests/test_stress.py asserts every variant of a
batch bitwise equal to its run alone), so each lane is that model's own run.
"""

from __future__ import annotations

from dataclasses import fields
from typing import Any

import numpy as np

from crashstudy.arrays.batch import build_batch
from crashstudy.arrays.compiler import Topology
from crashstudy.kernel.output import KernelOutput
from crashstudy.study.plan import Plan
from helpers import model_plan

_NOT_STRUCTURE = {"name", "paths", "blocks", "metrics"}  # the rest of Topology is what every variant shares


def same_topology(a: Topology, b: Topology) -> bool:
    """Whether two models compile to the same structure (nodes, springs, materials, curves' knot counts,
    walls, loads, histories ...): then their parameter vectors line up and can be variants of one batch."""
    if a.n_params != b.n_params or a.blocks != b.blocks or set(a.paths) != set(b.paths):
        return False
    for f in fields(Topology):
        if f.name in _NOT_STRUCTURE:
            continue
        x, y = getattr(a, f.name), getattr(b, f.name)
        if isinstance(x, np.ndarray) or isinstance(y, np.ndarray):
            if x is None or y is None or not np.array_equal(x, y):
                return False
        elif x != y:
            return False
    return True


def run_lanes(
    models: list[dict[str, Any]], kernel: str = "reference"
) -> tuple[list[KernelOutput], Any, Plan]:
    """Run ``models`` (one variant each, one topology, the same output sampling) in one kernel call.

    Returns (each model's output as a one-variant KernelOutput, the batch, the first model's plan)."""
    from crashstudy.run.runner import run_kernel

    plans = [model_plan(m) for m in models]
    first = plans[0]
    for p in plans[1:]:
        assert same_topology(first.topology, p.topology), "lanes must be one topology"
        assert (p.n_out, p.interval) == (first.n_out, first.interval), "lanes must share the sampling"
    P = np.stack([p.base for p in plans], axis=1)
    batch, _ = build_batch(first.topology, P, first.interval)
    out = run_kernel(batch, first.topology.histories, first.n_out, kernel)  # type: ignore[arg-type]
    return [lane(out, k) for k in range(len(models))], batch, first


def lane(out: KernelOutput, k: int) -> KernelOutput:
    """Variant ``k`` of ``out`` as a one-variant output (every array keeps its variant axis, of length 1)."""
    picked: dict[str, Any] = {}
    for f in fields(KernelOutput):
        x = getattr(out, f.name)
        if f.name == "histories":
            picked[f.name] = {h: a[..., k : k + 1] for h, a in x.items()}
        elif f.name == "criteria":
            picked[f.name] = None if x is None else x.take(np.array([k]))
        elif isinstance(x, np.ndarray):
            picked[f.name] = x[..., k : k + 1]
        else:
            picked[f.name] = x
    return KernelOutput(**picked)
