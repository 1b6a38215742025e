"""Timing the cases of a comparison side by side (interleaved repeats, medians of CPU and wall time,
time per element-step), comparing their outputs, and the rows of the report.

Part of benchmarks/skipping.py (what skipping costs and saves, issue 4, item 3), which describes the
comparisons and how they are timed."""

from __future__ import annotations

import os
import statistics
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from crashstudy.arrays.batch import build_batch
from crashstudy.arrays.compiler import apply_axis
from crashstudy.kernel.output import KernelOutput
from crashstudy.run.runner import run_kernel
from crashstudy.schema.yamlio import load_yaml

ROOT = Path(__file__).resolve().parents[1]
MODEL = ROOT / "studies" / "models" / "frontal-9mass.yaml"
SMALL_MODEL = ROOT / "studies" / "models" / "linear-spring.yaml"
sys.path.insert(0, str(ROOT / "tests"))

from helpers import model_plan  # noqa: E402  (tests/helpers.py: a one-variant plan from a dict)

PEAKS = ("peak_force", "peak_acceleration", "max_crush")
PLOTTED: list[tuple[str, list[Case]]] = []  # kernel comparisons, for the figure


# ---------------------------------------------------------------------------------------------- helpers


def loadavg() -> str:
    return " / ".join(f"{x:.2f}" for x in os.getloadavg())


def frontal(histories: Any = "none") -> dict[str, Any]:
    d = load_yaml(MODEL).data
    d["output"]["histories"] = histories
    return d


def sample(plan: Any, V: int, seed: int = 1) -> np.ndarray:
    """Parameter matrix of V variants over the frontal-matrix ranges (engine mass, rail scale, speed)."""
    topo = plan.topology
    P = np.repeat(plan.base[:, None], V, axis=1)
    rng = np.random.default_rng(seed)
    for path, lo, hi in (
        ("nodes.engine.mass", 120.0, 210.0),
        ("curves.rail-loading.scale", 0.7, 1.6),
        ("impact_velocity", 10.0, 20.0),
    ):
        if path in topo.paths:
            apply_axis(P, topo.paths[path], rng.uniform(lo, hi, V))
    return P


@dataclass
class Case:
    """One configuration of a comparison: a kernel call, its element-step count and its output."""

    name: str
    run: Callable[[], Any]
    warm: Callable[[], Any] | None = None
    wall: list[float] = field(default_factory=list)
    cpu: list[float] = field(default_factory=list)
    result: Any = None
    elem_steps: float = float("nan")
    note: str = ""

    @property
    def wall_med(self) -> float:
        return statistics.median(self.wall)

    @property
    def cpu_med(self) -> float:
        return statistics.median(self.cpu)

    @property
    def ns_per(self) -> float:
        return 1e9 * self.cpu_med / self.elem_steps


def measure(cases: list[Case], repeats: int) -> tuple[str, str]:
    """Warm every case up, then time them interleaved; returns the load average before and after."""
    before = loadavg()
    for c in cases:
        (c.warm or c.run)()
    for r in range(repeats):
        for k in range(len(cases)):
            c = cases[(k + r) % len(cases)]
            w0, c0 = time.perf_counter(), time.process_time()
            res = c.run()
            c.cpu.append(time.process_time() - c0)
            c.wall.append(time.perf_counter() - w0)
            if c.result is None:
                c.result = res
    return before, loadavg()


def kernel_case(name: str, model: dict[str, Any], V: int, histories: tuple[str, ...] | None = None) -> Case:
    """A case that runs the compiled kernel on V sampled variants of ``model`` (batch built once)."""
    plan = model_plan(model)
    P = sample(plan, V)
    batch, _ = build_batch(plan.topology, P, plan.interval)
    small, _ = build_batch(plan.topology, np.ascontiguousarray(P[:, :8]), plan.interval)
    hist = plan.topology.histories if histories is None else histories
    case = Case(
        name, lambda: run_kernel(batch, hist, plan.n_out), lambda: run_kernel(small, hist, plan.n_out)
    )
    case.batch = batch  # type: ignore[attr-defined]
    case.plan = plan  # type: ignore[attr-defined]
    return case


def finish_kernel_case(case: Case) -> None:
    """Element-steps actually computed: springs x (t_end / dt) summed over the variants."""
    out: KernelOutput = case.result
    b = case.batch  # type: ignore[attr-defined]
    steps = np.rint(out.t_end / b.dt)
    case.elem_steps = float(len(b.spring_i) * steps.sum())
    bad = int(np.count_nonzero(out.status))
    if bad:
        case.note = f"{bad} variants failed"


@dataclass
class Diff:
    """Item-wise relative difference of the per-variant peaks of two runs."""

    worst: float  # max |a - b| / max(|b|, 1e-9 x the largest item of its array)
    where: str  # the worst item
    n_variants: int  # variants with any item above ``tol``
    tol: float

    def text(self, total: int) -> str:
        ok = self.n_variants == 0
        if self.tol == 0.0 and ok:
            return "bit-identical"
        out = f"max rel diff {self.worst:.1e} ({'ok' if ok else 'FAILS'} {self.tol:g}"
        if not ok:
            out += f": {self.n_variants} of {total} variants, worst {self.where}"
        return out + ")"


def rel_diff(a: KernelOutput, b: KernelOutput, plan: Any, tol: float, names: tuple[str, ...] = PEAKS) -> Diff:
    """Compare peak force, peak acceleration and max crush of ``a`` against ``b`` item by item."""
    topo = plan.topology
    worst, where = 0.0, ""
    bad = np.zeros(a.peak_force.shape[-1], dtype=bool)
    for n in names:
        x, y = getattr(a, n), getattr(b, n)
        scale = np.max(np.abs(y), initial=0.0)
        r = np.abs(x - y) / np.maximum(np.abs(y), max(1e-9 * scale, 1e-300))
        bad |= np.any(r > tol, axis=0)
        if r.size and float(r.max()) > worst:
            i, w = np.unravel_index(int(np.argmax(r)), r.shape)
            ids = topo.node_ids if n == "peak_acceleration" else topo.spring_ids
            worst, where = float(r.max()), f"{n} of {ids[i]} in variant {w}: {x[i, w]:.10g} vs {y[i, w]:.10g}"
    return Diff(worst, where, int(bad.sum()), tol)


def hist_bytes(out: KernelOutput, histories: tuple[str, ...], n_out: int, V: int) -> int:
    n = sum(a.nbytes for a in out.histories.values())
    energies = ("kinetic_energy", "internal_energy", "external_work", "wall_energy")
    if any(h in histories for h in energies):
        n += n_out * 4 * V * 8  # the kernel's energy buffer (run_compiled: h_energy)
    return n


@dataclass
class Row:
    feature: str
    baseline: str
    skip: str
    gain: str
    check: str


def fmt_case(c: Case) -> str:
    return f"{c.name}: {c.ns_per:.2f} ns/elem-step (CPU {c.cpu_med:.3g} s, wall {c.wall_med:.3g} s)"


def gain(base: Case, skip: Case, per_elem: bool = True) -> str:
    if per_elem:
        g = base.ns_per / skip.ns_per
        return f"{g:.2f}x per elem-step (CPU {base.cpu_med / skip.cpu_med:.2f}x, wall {base.wall_med / skip.wall_med:.2f}x)"
    return f"CPU {base.cpu_med / skip.cpu_med:.2f}x, wall {base.wall_med / skip.wall_med:.2f}x"
