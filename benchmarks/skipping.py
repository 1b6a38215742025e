"""What skipping costs and saves: one feature toggled at a time, same physics (issue 4, item 3).

Every comparison runs its cases side by side in the same process and interleaved (repeat 1 of every
case, then repeat 2, ...; the order rotates each repeat), so load from other users hits all cases
alike. Each case is warmed up (compiled, caches filled) before it is timed; the medians of
``--repeats`` runs (default 5) of CPU time (``time.process_time``, kernel on one thread via
``crashstudy.kernel.compiled.set_threads(1)``) and wall time are reported, with the time per
element-step (one spring advanced one step for one variant: springs x steps actually computed) and
the load average before and after each comparison.

1. histories ``none`` vs ``[spring_force]`` vs ``all`` (frontal model, 2000 variants), with the
   bytes of the history arrays (the kernel's energy buffer included).
2. the frontal model in 1-D vs the same model drawn in 2-D along x (positions [x, 0], velocities
   [v, 0]), once with every node fixed in y and once free in y; peaks must agree to 1e-9. Both are
   drawn twice as long as in the file (see ``cmp_geometry``: as drawn, the crash box passes zero
   length, which 2-D treats differently).
3. a rigid wall that is never reached / a load with zero force vs neither (both cost the fused
   1-D node update); peaks must agree to 1e-12.
4. material state: every curve-driven spring as ``nonlinear_elastic`` vs ``crush`` vs
   ``general_nonlinear`` on the same curves (different physics: cost only).
5. early termination (``kinetic_energy_fraction: 0.01``, and 0.05) with end_time 0.3 s vs the same
   run without; steps computed (from ``t_end``) and peaks (must agree to 1e-12).
6. ``run_chunk`` over 10^4 variants of which 100 are unique vs 10^4 unique (a study file in a
   temporary folder); the duplicated variants must equal a run of the 100 unique ones exactly.
7. the numba cache: process wall and CPU time of a first ``crashstudy simulate`` of a small model
   (``NUMBA_CACHE_DIR`` an empty folder) and of a second one reusing it.

Usage::

    python benchmarks/skipping.py                  # default run (~3 CPU-minutes), writes the report
    python benchmarks/skipping.py --quick          # small sizes, 2 repeats: checks the script only
    python benchmarks/skipping.py --only 1,5       # some of the comparisons

Options: ``--variants N`` (comparisons 2-5, default 2000), ``--history-variants N`` (comparison 1,
default 2000), ``--dedup-axis N`` (comparison 6: 10 x 10 x N variants, default 100), ``--repeats N``
(default 5), ``--cold-repeats N`` (first-call processes of comparison 7, default 3 to stay within
~8 minutes: each compiles the kernel, ~25 s of CPU), ``--report FILE`` (default
benchmarks/results/skipping.md, with a PNG beside it; ``-`` prints only), ``--no-plot``,
``--source-note TEXT`` (recorded with the crashstudy source measured). To measure a fixed commit
while the checkout changes: ``git archive COMMIT src | tar -x -C /tmp/cs`` and run with
``PYTHONPATH=/tmp/cs/src``.
"""

from __future__ import annotations

import argparse
import copy
import datetime as _dt
import os
import platform
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

ROOT = Path(__file__).resolve().parents[1]
MODEL = ROOT / "studies" / "models" / "frontal-9mass.yaml"
SMALL_MODEL = ROOT / "studies" / "models" / "linear-spring.yaml"
REPORT = ROOT / "benchmarks" / "results" / "skipping.md"
sys.path.insert(0, str(ROOT / "tests"))

from crashstudy.arrays.batch import build_batch  # noqa: E402
from crashstudy.arrays.compiler import apply_axis  # noqa: E402
from crashstudy.kernel.compiled import set_threads  # noqa: E402
from crashstudy.kernel.output import KernelOutput  # noqa: E402
from crashstudy.run.runner import run_chunk, run_kernel  # noqa: E402
from crashstudy.schema.yamlio import load_yaml  # noqa: E402
from crashstudy.study.plan import load_study  # noqa: E402
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


# ---------------------------------------------------------------------------------------------- comparisons


def cmp_histories(V: int, repeats: int, log: list[str]) -> list[Row]:
    cases = [
        kernel_case("histories: all", frontal("all"), V),
        kernel_case("histories: [spring_force]", frontal(["spring_force"]), V),
        kernel_case("histories: none", frontal("none"), V),
    ]
    before, after = measure(cases, repeats)
    for c in cases:
        finish_kernel_case(c)
    mem = {c.name: hist_bytes(c.result, c.plan.topology.histories, c.plan.n_out, V) for c in cases}  # type: ignore[attr-defined]
    PLOTTED.append(("1. histories", cases))
    log.append(f"1. histories, {V} variants, load {before} -> {after}")
    for c in cases:
        log.append(f"   {fmt_case(c)}; history arrays {mem[c.name] / 2**20:.1f} MiB {c.note}")
    base = cases[0]
    rows = []
    for c in cases[1:]:
        d = rel_diff(c.result, base.result, base.plan, 0.0)  # type: ignore[attr-defined]
        rows.append(
            Row(
                f"histories ({V} variants): {c.name.split(': ')[1]} instead of all",
                f"{fmt_case(base)}; arrays {mem[base.name] / 2**20:.0f} MiB",
                f"{fmt_case(c)}; arrays {mem[c.name] / 2**20:.1f} MiB",
                gain(base, c),
                f"peaks vs `all`: {d.text(V)}",
            )
        )
    return rows


def stretched(d: dict[str, Any], factor: float) -> dict[str, Any]:
    """The model drawn ``factor`` times longer (in 1-D the drawing only gives each spring's direction)."""
    d = copy.deepcopy(d)
    for node in d["nodes"].values():
        node["position"] = [p * factor for p in node["position"]]
    return d


def to_2d(d: dict[str, Any], y_fixed: bool) -> dict[str, Any]:
    """The same 1-D model drawn along the x axis of a 2-D model: positions [x, 0], velocities [v, 0]."""
    d = copy.deepcopy(d)
    for node in d["nodes"].values():
        node["position"] = [node["position"][0], 0.0]
        if node.get("fixed") is not True:
            node["fixed"] = ["y"] if y_fixed else False
    d["initial_velocity"] = {k: [v[0], 0.0] for k, v in d["initial_velocity"].items()}
    return d


def cmp_geometry(V: int, repeats: int, log: list[str], factor: float = 2.0) -> list[Row]:
    """1-D vs 2-D on the frontal model drawn ``factor`` x longer.

    As drawn in the file, the crash box (0.15 m) is crushed past zero length (the bumper passes the
    barrier; 1-D elongation down to about -0.150 m): in 1-D that is still the curve's bottoming, in
    2-D the spring turns inside out. Drawn twice as long every spring keeps over a quarter of its
    length in every sampled variant (the share left is reported), so the two models are the same physics; the 1-D results of the
    stretched drawing are checked against the file's drawing.
    """
    orig = frontal("none")
    base = stretched(orig, factor)
    cases = [
        kernel_case("2-D, y fixed", to_2d(base, True), V),
        kernel_case("2-D, y free", to_2d(base, False), V),
        kernel_case("1-D", base, V),
    ]
    same_dt = all(np.array_equal(c.batch.dt, cases[2].batch.dt) for c in cases)  # type: ignore[attr-defined]
    before, after = measure(cases, repeats)
    for c in cases:
        finish_kernel_case(c)
    one = cases[2]
    drawn = kernel_case("1-D as drawn in the file", orig, V)
    d_drawn = rel_diff(drawn.run(), one.result, one.plan, 1e-9)  # type: ignore[attr-defined]
    left = float(np.min(1.0 - cases[0].result.max_crush / cases[0].batch.length0))  # type: ignore[attr-defined]
    PLOTTED.append(("2. geometry", cases))
    log.append(
        f"2. 1-D vs 2-D along x, model drawn {factor:g}x longer, {V} variants (same dt in every case: "
        f"{same_dt}), load {before} -> {after}"
    )
    log.append(
        f"   1-D drawn {factor:g}x vs as in the file: peaks {d_drawn.text(V)}; shortest spring "
        f"in 2-D keeps {left:.0%} of its length"
    )
    rows = []
    for c in cases[:2]:
        d = rel_diff(c.result, one.result, one.plan, 1e-9)  # type: ignore[attr-defined]
        log.append(f"   {fmt_case(c)} {c.note}; peaks vs 1-D {d.text(V)}")
        rows.append(
            Row(
                f"geometry: 1-D instead of {c.name} ({V} variants)",
                fmt_case(c),
                fmt_case(one),
                gain(c, one),
                f"peaks (force, accel., crush) vs 1-D: {d.text(V)}",
            )
        )
    log.append(f"   {fmt_case(one)} {one.note}")
    return rows


def cmp_wall_load(V: int, repeats: int, log: list[str]) -> list[Row]:
    base = frontal("none")
    wall = copy.deepcopy(base)
    wall["rigid_walls"] = [{"id": "far", "point": [-100.0], "normal": [1.0]}]  # 100 m behind the barrier
    load = copy.deepcopy(base)
    load["loads"] = [{"node": "survival_room", "force": [0.0]}]
    cases = [
        kernel_case("wall never reached", wall, V),
        kernel_case("zero load", load, V),
        kernel_case("neither (fused 1-D update)", base, V),
    ]
    before, after = measure(cases, repeats)
    for c in cases:
        finish_kernel_case(c)
    ref = cases[2]
    PLOTTED.append(("3. wall / load", cases))
    log.append(f"3. wall / load vs neither, {V} variants, load {before} -> {after}")
    rows = []
    for c in cases[:2]:
        d = rel_diff(c.result, ref.result, ref.plan, 1e-12)  # type: ignore[attr-defined]
        extra = ""
        if c.name.startswith("wall"):
            extra = f"; peak wall force {float(np.max(c.result.peak_wall_force)):.1g}"
        log.append(f"   {fmt_case(c)} {c.note}; peaks vs neither {d.text(V)}{extra}")
        rows.append(
            Row(
                f"no {c.name.split(' ')[0]} loop, fused 1-D update ({V} variants)",
                fmt_case(c),
                fmt_case(ref),
                gain(c, ref),
                f"peaks vs neither: {d.text(V)}{extra}",
            )
        )
    log.append(f"   {fmt_case(ref)} {ref.note}")
    return rows


def with_material(d: dict[str, Any], kind: str) -> dict[str, Any]:
    """Every curve-driven spring of the frontal model as ``kind`` on its own loading curve.

    crush: unloading_stiffness = the model's (crush springs) or the unloading curve's slope;
    general_nonlinear: unloading = the model's curve or a straight line of the crush unloading
    stiffness, yields as in the model (none for the former crush springs). gearbox-flange stays linear.
    """
    d = copy.deepcopy(d)
    for sid, s in d["springs"].items():
        m = s["material"]
        if m["type"] not in ("crush", "general_nonlinear"):
            continue
        loading = m["loading"]
        if m["type"] == "crush":
            k = m["unloading_stiffness"]
            unl = f"{sid}-unloading"
            d["curves"][unl] = {"x": [-1.0, 0.0, 1.0], "y": [-k, 0.0, k]}
            yields = {}
        else:
            unl = m["unloading"]
            c = d["curves"][unl]
            k = (c["y"][-1] - c["y"][0]) / (c["x"][-1] - c["x"][0])
            yields = {key: m[key] for key in ("tension_yield", "compression_yield") if key in m}
        if kind == "nonlinear_elastic":
            s["material"] = {"type": kind, "curve": loading}
        elif kind == "crush":
            s["material"] = {"type": kind, "loading": loading, "unloading_stiffness": float(k)}
        else:
            s["material"] = {"type": kind, "loading": loading, "unloading": unl, **yields}
    return d


def cmp_material(V: int, repeats: int, log: list[str]) -> list[Row]:
    base = frontal("none")
    cases = [
        kernel_case(f"all {k}", with_material(base, k), V)
        for k in ("general_nonlinear", "crush", "nonlinear_elastic")
    ]
    before, after = measure(cases, repeats)
    for c in cases:
        finish_kernel_case(c)
    PLOTTED.append(("4. material state", cases))
    log.append(f"4. material state, {V} variants, load {before} -> {after}")
    for c in cases:
        dts = np.unique(c.batch.dt)  # type: ignore[attr-defined]
        log.append(f"   {fmt_case(c)} {c.note}; dt {dts.min():.3g}..{dts.max():.3g} s")
    ne = cases[2]
    return [
        Row(
            f"no material state: 7 curve springs nonlinear_elastic instead of {c.name.split(' ')[1]} "
            f"({V} variants)",
            fmt_case(c),
            fmt_case(ne),
            gain(c, ne),
            "different physics: cost only",
        )
        for c in cases[:2]
    ]


def cmp_termination(V: int, repeats: int, log: list[str]) -> list[Row]:
    """end_time 0.3 s with and without ``termination``: 1% (the asked-for setting) and 5% of the KE."""
    long_run = frontal("none")
    long_run["end_time"] = 0.3
    long_run["output"]["interval"] = 3.0e-4
    cases = [kernel_case("end_time 0.3 s, no termination", long_run, V)]
    for frac in (0.01, 0.05):
        term = copy.deepcopy(long_run)
        term["termination"] = {"kinetic_energy_fraction": frac}
        cases.append(kernel_case(f"termination KE {frac:.0%}", term, V))
    before, after = measure(cases, repeats)
    for c in cases:
        finish_kernel_case(c)
    full = cases[0]
    PLOTTED.append(("5. termination", cases))
    log.append(f"5. early termination, end_time 0.3 s, {V} variants, load {before} -> {after}")
    log.append(f"   {fmt_case(full)} {full.note}")
    rows = []
    for cut in cases[1:]:
        d = rel_diff(cut.result, full.result, full.plan, 1e-12)  # type: ignore[attr-defined]
        te = cut.result.t_end
        stopped = float(np.mean(te < 0.3 - 1e-9))
        log.append(
            f"   {fmt_case(cut)} {cut.note}; {stopped:.0%} of the variants stopped early, t_end "
            f"min/median/max {te.min():.4f}/{np.median(te):.4f}/{te.max():.4f} s; peaks {d.text(V)}"
        )
        steps = (
            f"variant-steps {full.elem_steps / 8:.3g} -> {cut.elem_steps / 8:.3g} ({full.elem_steps / cut.elem_steps:.2f}x; "
            f"{stopped:.0%} stopped early, t_end median {np.median(te):.3f} s)"
        )
        rows.append(
            Row(
                f"early termination, {cut.name} ({V} variants, end_time 0.3 s)",
                fmt_case(full),
                fmt_case(cut),
                f"wall {full.wall_med / cut.wall_med:.2f}x, CPU {full.cpu_med / cut.cpu_med:.2f}x; {steps}",
                f"peaks vs no termination: {d.text(V)}",
            )
        )
    return rows


def study_plan(folder: Path, name: str, scales: list[float]) -> Any:
    text = {
        "name": name,
        "model": MODEL.name,
        "set": {"output": {"histories": "none"}},
        "matrix": {
            "nodes.engine.mass": [120.0 + 10 * k for k in range(10)],
            "impact_velocity": [10.0 + 10.0 * k / 9 for k in range(10)],
            "curves.rail-loading.scale": scales,
        },
    }
    path = folder / f"{name}.yaml"
    path.write_text(yaml.safe_dump(text, sort_keys=False))
    return load_study(path)


def cmp_dedup(n_unique_axis: int, repeats: int, log: list[str]) -> list[Row]:
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        (folder / MODEL.name).write_text(MODEL.read_text())
        uniq = study_plan(
            folder, "all-unique", [round(float(v), 6) for v in np.linspace(0.7, 1.6, n_unique_axis)]
        )
        dup = study_plan(folder, "hundred-unique", [1.0] * n_unique_axis)
        ref = study_plan(folder, "the-hundred", [1.0])
    n = uniq.n_variants
    cases = [
        Case(f"{n} unique", lambda: run_chunk(uniq, 0, n), lambda: run_chunk(uniq, 0, 16)),
        Case(f"{n} variants, 100 unique", lambda: run_chunk(dup, 0, n), lambda: run_chunk(dup, 0, 16)),
    ]
    before, after = measure(cases, repeats)
    full, once = cases
    ref_out = run_chunk(ref, 0, ref.n_variants).out
    # variant k of the duplicated study is variant k // n_unique_axis of the 100-variant one
    idx = np.arange(n) // n_unique_axis
    exact = all(
        np.array_equal(getattr(once.result.out, a), getattr(ref_out, a)[..., idx])
        for a in (*PEAKS, "absorbed_energy", "t_end", "energy_error")
    )
    log.append(f"6. run_chunk dedup, {n} variants, load {before} -> {after}")
    for c in cases:
        log.append(f"   {c.name}: CPU {c.cpu_med:.3g} s, wall {c.wall_med:.3g} s")
    return [
        Row(
            f"identical variants computed once (run_chunk, {n} variants, 100 unique)",
            f"{full.name}: CPU {full.cpu_med:.3g} s, wall {full.wall_med:.3g} s",
            f"{once.name}: CPU {once.cpu_med:.3g} s, wall {once.wall_med:.3g} s",
            gain(full, once, False),
            f"each variant equals its unique twin run alone: {'exact' if exact else 'DIFFERS'}",
        )
    ]


def run_process(args: list[str], env: dict[str, str]) -> tuple[float, float]:
    """Wall time and CPU time (user + sys of the child) of one process."""
    w0 = time.perf_counter()
    proc = subprocess.Popen(args, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - w0
    err = proc.stderr.read().decode() if proc.stderr else ""
    if os.waitstatus_to_exitcode(status) != 0:
        raise RuntimeError(f"{' '.join(args)} failed: {err}")
    return wall, usage.ru_utime + usage.ru_stime


def cmp_cache(cold_repeats: int, repeats: int, log: list[str]) -> list[Row]:
    exe = [sys.executable, "-m", "crashstudy.cli", "simulate", str(SMALL_MODEL), "-o"]
    cold: list[tuple[float, float]] = []
    warm: list[tuple[float, float]] = []
    imp: list[tuple[float, float]] = []
    before = loadavg()
    with tempfile.TemporaryDirectory() as tmp:
        for r in range(max(cold_repeats, repeats)):
            env = dict(os.environ, NUMBA_CACHE_DIR=str(Path(tmp) / f"cache{r}"))
            if r < cold_repeats:  # first call: empty cache, the kernel is compiled and cached
                cold.append(run_process([*exe, str(Path(tmp) / f"out{r}a")], env))
            else:
                env["NUMBA_CACHE_DIR"] = str(Path(tmp) / "cache0")
            warm.append(run_process([*exe, str(Path(tmp) / f"out{r}b")], env))  # second call: cache reused
            imp.append(
                run_process([sys.executable, "-c", "import crashstudy.run.runner, crashstudy.cli.main"], env)
            )
    after = loadavg()

    def med(xs: list[tuple[float, float]], k: int) -> float:
        return statistics.median(x[k] for x in xs)

    log.append(f"7. numba cache ({SMALL_MODEL.name}), load {before} -> {after}")
    log.append(
        f"   first call ({len(cold)} runs): wall {[round(x[0], 2) for x in cold]}, CPU {[round(x[1], 2) for x in cold]}"
    )
    log.append(
        f"   second call ({len(warm)} runs): wall {[round(x[0], 2) for x in warm]}, CPU {[round(x[1], 2) for x in warm]}"
    )
    log.append(
        f"   python -c 'import crashstudy.run.runner, crashstudy.cli.main' ({len(imp)} runs): wall median "
        f"{med(imp, 0):.2f} s, CPU {med(imp, 1):.2f} s"
    )
    return [
        Row(
            f"numba cache: second `crashstudy simulate` of {SMALL_MODEL.name} (separate processes)",
            f"first call, empty NUMBA_CACHE_DIR: process wall {med(cold, 0):.1f} s, CPU {med(cold, 1):.1f} s",
            f"second call, cache reused: process wall {med(warm, 0):.2f} s, CPU {med(warm, 1):.2f} s "
            f"(imports alone: wall {med(imp, 0):.2f} s)",
            f"wall {med(cold, 0) / med(warm, 0):.1f}x, CPU {med(cold, 1) / med(warm, 1):.1f}x",
            "both runs exit 0",
        )
    ]


# ---------------------------------------------------------------------------------------------- report


def machine(note: str = "") -> list[str]:
    try:
        lscpu = subprocess.run(["lscpu"], capture_output=True, text=True).stdout
        model = next(
            (ln.split(":", 1)[1].strip() for ln in lscpu.splitlines() if ln.startswith("Model name")), "?"
        )
    except OSError:
        model = platform.processor() or "?"
    import numba

    import crashstudy

    pkg = Path(crashstudy.__file__).resolve().parent
    if pkg.is_relative_to(ROOT):
        git = ["git", "-C", str(ROOT)]
        head = subprocess.run(
            [*git, "rev-parse", "--short", "HEAD"], capture_output=True, text=True
        ).stdout.strip()
        dirty = subprocess.run(
            [*git, "status", "--porcelain", "src"], capture_output=True, text=True
        ).stdout.split()
        changed = [f for f in dirty if f.startswith("src/")]
        source = f"this checkout at {head}" + (
            f", with uncommitted changes in {', '.join(changed)}" if changed else ""
        )
    else:
        source = str(pkg)
    if note:
        source += f" ({note})"
    return [
        f"- crashstudy source: {source}",
        f"- CPU: {model}, {os.cpu_count()} cores (lscpu); shared with other users' runs",
        f"- Python {platform.python_version()}, numpy {np.__version__}, numba {numba.__version__}, "
        f"{platform.system()} {platform.release()}",
        f"- date {_dt.datetime.now().isoformat(timespec='seconds')}",
    ]


NOTES = [
    "Notes (what each skip is: [docs/benchmarks-skipping.md](../../docs/benchmarks-skipping.md)):",
    "",
    "- Geometry: both drawings are the frontal model drawn twice as long. As drawn in the file, the crash box is "
    "compressed past zero length (1-D: the curve's bottoming); in 2-D it turns inside out without being flagged.",
    "- Termination: the kernel runs a block of 256 variants until its last variant stops; stopped variants are "
    "still computed under the masks, so only whole blocks that stop save time.",
    "- Identical variants: the gain is total CPU time for the same 10^4 results; most of what remains is "
    "`np.unique` over the parameter columns.",
]


def write_report(
    rows: list[Row],
    log: list[str],
    args: argparse.Namespace,
    seconds: float,
    load0: str,
    load1: str,
    png: str | None,
) -> str:
    lines = [
        "# Skipping what a scene does not need: measured gains",
        "",
        "Written by `python benchmarks/skipping.py` "
        f"(`--variants {args.variants} --repeats {args.repeats} --cold-repeats {args.cold_repeats}`). "
        "Each comparison toggles one feature on the same physics; its cases run side by side in one process, "
        f"interleaved, after a warm-up; medians of {args.repeats} repeats (first-call processes: "
        f"{args.cold_repeats}). CPU time is `time.process_time()` with the kernel on one thread "
        "(`set_threads(1)`); one element-step = one spring advanced one step for one variant, counted "
        "from the steps actually computed (`t_end / dt`). Gain = baseline / with-skip (per element-step "
        "where the element-steps are the same; total time where the skip removes steps or variants).",
        "",
        "## Machine",
        "",
        *machine(args.source_note),
        f"- load average (1/5/15 min) at start {load0}, at end {load1}",
        f"- total run time {seconds:.0f} s",
        "",
        "## Table",
        "",
        "| feature | baseline | with skip | gain | error check |",
        "|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(f"| {r.feature} | {r.baseline} | {r.skip} | {r.gain} | {r.check} |")
    lines += ["", *NOTES]
    lines += [
        "",
        "## Details (medians; load average before -> after each comparison)",
        "",
        "```",
        *log,
        "```",
    ]
    if png:
        lines += ["", f"![time per element-step]({png})"]
    return "\n".join(lines) + "\n"


def plot(all_cases: list[tuple[str, list[Case]]], path: Path) -> bool:
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return False
    groups = [(g, cs) for g, cs in all_cases if cs]
    fig, axes = plt.subplots(1, len(groups), figsize=(3.2 * len(groups), 3.6), squeeze=False)
    for ax, (g, cs) in zip(axes[0], groups, strict=True):
        total = g.startswith("5.")  # termination removes steps: compare the whole run's CPU time
        vals = [c.cpu_med if total else c.ns_per for c in cs]
        ax.bar(range(len(cs)), vals, color="tab:blue")
        ax.set_xticks(range(len(cs)), [c.name for c in cs], rotation=30, ha="right", fontsize=7)
        ax.set_title(g, fontsize=9)
        ax.set_ylabel("CPU s (median)" if total else "CPU ns per element-step (median)", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return True


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--variants", type=int, default=2000, help="variants of comparisons 2-5 (default 2000)")
    ap.add_argument("--history-variants", type=int, default=2000)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--cold-repeats", type=int, default=3)
    ap.add_argument(
        "--dedup-axis", type=int, default=100, help="values of the repeated axis (10 x 10 x N variants)"
    )
    ap.add_argument("--only", default="1,2,3,4,5,6,7")
    ap.add_argument("--quick", action="store_true", help="small sizes, 2 repeats (a check of the script)")
    ap.add_argument("--report", default=str(REPORT))
    ap.add_argument("--no-plot", action="store_true")
    ap.add_argument(
        "--source-note", default="", help="a note on the crashstudy source measured, for the report"
    )
    args = ap.parse_args(argv)
    if args.quick:
        args.variants, args.history_variants, args.repeats, args.cold_repeats, args.dedup_axis = (
            256,
            256,
            2,
            1,
            10,
        )
    set_threads(1)
    only = {int(x) for x in args.only.split(",")}
    t0, load0 = time.perf_counter(), loadavg()
    rows: list[Row] = []
    log: list[str] = []
    steps: list[tuple[int, Callable[[], list[Row]]]] = [
        (1, lambda: cmp_histories(args.history_variants, args.repeats, log)),
        (2, lambda: cmp_geometry(args.variants, args.repeats, log)),
        (3, lambda: cmp_wall_load(args.variants, args.repeats, log)),
        (4, lambda: cmp_material(args.variants, args.repeats, log)),
        (5, lambda: cmp_termination(args.variants, args.repeats, log)),
        (6, lambda: cmp_dedup(args.dedup_axis, args.repeats, log)),
        (7, lambda: cmp_cache(args.cold_repeats, args.repeats, log)),
    ]
    for k, fn in steps:
        if k in only:
            print(f"comparison {k} ... (load {loadavg()})", flush=True)
            new = fn()
            rows += new
            for r in new:
                print(f"  {r.feature}: {r.gain}; {r.check}", flush=True)
    seconds = time.perf_counter() - t0
    png = None
    if not args.no_plot and args.report != "-" and PLOTTED:
        png_path = Path(args.report).with_suffix(".png")
        png_path.parent.mkdir(parents=True, exist_ok=True)
        if plot(PLOTTED, png_path):
            png = png_path.name
    text = write_report(rows, log, args, seconds, load0, loadavg(), png)
    if args.report != "-":
        Path(args.report).parent.mkdir(parents=True, exist_ok=True)
        Path(args.report).write_text(text)
        print(f"wrote {args.report}")
    print(text)
    print(f"peak RSS {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**10:.0f} MiB")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
