"""Stability stress table (issue 4, item 2): every case of ``tests/test_stress.py`` and the long ones the
tests leave out, each run through ``crashstudy.run.runner.run_chunk`` (the path a study takes), with its
outcome, energy error, steps, wall time and a check against an independent truth where one exists.

Outcomes: ``stable`` (status ok and the check holds), ``refused: <reason>`` / ``failed: <reason>`` (the
runner's reason, verbatim), and ``WRONG`` where the run says ok but the check shows the answer is not
(a solver bug or gap; the tests hold those as strict xfails).

Long cases beyond the tests: 10^7 steps on the conservative 2-mass chain (and on a free chain drifting
with net momentum), the 1e8 / 1e6 ratio model over a full quarter of its slow period (1.1e7 steps), the
1000-mass chains for 10x the steps.

Usage::

    python benchmarks/stress.py                 # writes benchmarks/results/stress.md (about 2 minutes)
    python benchmarks/stress.py --quick         # no long cases, prints only (checks the script)
    python benchmarks/stress.py --report -      # print the table only

Wall times are of ``run_chunk`` (batch build + kernel; the model is validated before the clock starts),
the kernel compiled and warm, on a shared machine: read them as orders of magnitude.
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import datetime as _dt
import math
import os
import platform
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any
from unittest import mock

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

import crashstudy.run.runner as runner  # noqa: E402
import stress_models as builders  # noqa: E402  (the tests' model builders: the table runs the same models)
import test_stress as cases  # noqa: E402  (and the tests' cases: sizes, ratios, speeds)
from crashstudy.kernel.output import INVALID  # noqa: E402
from crashstudy.results.chunk_result import ChunkResult  # noqa: E402
from crashstudy.study.plan import Axis, Plan  # noqa: E402
from helpers import output_differences  # noqa: E402  (tests/helpers.py: the tests' comparer of kernel outputs)

ROWS: list[dict[str, str]] = []


def variant_plan(model: dict[str, Any], path: str, values: list[float]) -> Plan:
    """The model's plan with one study axis ``path`` (as a study file's matrix would give)."""
    plan = builders.model_plan(model)
    ref = plan.topology.paths[path]
    n_out = plan.n_out
    if path == "end_time":
        n_out = int(math.floor(max(values) / plan.interval + 1e-9)) + 1
    axis = Axis(path, np.asarray(values, dtype=float), 0, ref)
    return dataclasses.replace(plan, axes=(axis,), shape=(len(values),), n_out=n_out)


def run(model: dict[str, Any], path: str, values: list[float]) -> tuple[ChunkResult, Plan, float]:
    plan = variant_plan(model, path, values)
    t0 = time.perf_counter()
    res = runner.run_chunk(plan, 0, plan.n_variants)
    return res, plan, time.perf_counter() - t0


def steps_of(res: ChunkResult) -> np.ndarray:
    """Steps actually computed per variant (from t_end and dt)."""
    return np.rint(res.out.t_end / res.dt).astype(np.int64)


def outcome(res: ChunkResult, k: int, wrong: str | None = None) -> str:
    code = int(res.out.status[k])
    if code == 0:
        if wrong:
            return f"**WRONG** (status ok): {wrong}"
        return (
            "stable"
            if res.out.energy_error[k] < 1e-3
            else "stable, energy error > 1e-3 (coarse step: see check)"
        )
    kind = "refused" if code == INVALID else "failed"
    return f"{kind}: {res.reasons[k]}"


def add(case: str, out: str, err: float | None, steps: int | str, wall: float, check: str) -> None:
    ROWS.append(
        {
            "case": case,
            "outcome": out,
            "energy_error": "-" if err is None else f"{err:.1e}",
            "steps": f"{steps:,}" if isinstance(steps, (int, np.integer)) else str(steps),
            "wall": f"{wall:.2f}",
            "check": check,
        }
    )
    print(
        f"  {case}: {out} | {ROWS[-1]['energy_error']} | {ROWS[-1]['steps']} | {wall:.2f} s | {check}",
        flush=True,
    )


# --------------------------------------------------------------------------------------------------


def chains(quick: bool) -> None:
    print("chains at safety_factor 1.0")
    for n in cases.CHAIN_SIZES:
        for unequal in (False, True):
            for fixed in (True, False):
                N = max(2000, 8 * n) * (1 if quick or n < 1000 else 10)
                model = builders.at_step(builders.chain(n, unequal, fixed), N)
                T = model["end_time"]
                res, _, wall = run(model, "end_time", [T, 2 * T])
                w_dt = builders.chain_omega_max(model) * res.dt[0]
                p1, p2 = res.out.peak_force.max(axis=0)
                ok = p2 <= 1.5 * p1 and w_dt < 2.0
                name = f"chain {n} {'unequal' if unequal else 'equal'} {'fixed-end' if fixed else 'free'}, sf 1.0"
                add(
                    name,
                    outcome(res, 1, None if ok else f"peak 2N/N {p2 / p1:.3g}"),
                    float(res.out.energy_error.max()),
                    int(steps_of(res).sum()),
                    wall,
                    f"omega_max dt {w_dt:.3f}; peak force 2N/N steps {p2 / p1:.3f}",
                )


def ratios(quick: bool) -> None:
    print("stiffness / mass ratios at safety_factor 1.0")
    for kr, mr in cases.RATIOS:
        steps = builders.ratio_steps(kr, mr)
        if quick:
            steps = min(steps, 100_000)
        steps = 100 * (steps // 100)
        model = builders.at_step(builders.ratio_model(kr, mr), steps, samples=100)
        _, node, spring = builders.critical(model)
        res, plan, wall = run(model, "end_time", [model["end_time"]])
        t = np.arange(plan.n_out) * plan.interval
        exact = builders.ratio_closed_form(kr, mr, t)[:, 0]
        got = res.out.histories["displacement"][:, 1, 0, 0]
        rel = float(np.max(np.abs(got - exact)) / np.max(np.abs(exact)))
        add(
            f"k ratio {kr:.0e}, m ratio {mr:.0e}, sf 1.0 (quarter slow period)",
            outcome(res, 0, None if rel < 1e-6 else f"heavy-mass error {rel:.2g}"),
            float(res.out.energy_error[0]),
            int(steps_of(res)[0]),
            wall,
            f"dt_crit from node {node} / spring {spring}; heavy mass vs closed form: {rel:.1e} of amplitude",
        )


def frontal() -> None:
    print("frontal-9mass 10 .. 100 m/s")
    speeds = cases.FRONTAL_SPEEDS
    ref = None
    for ts in (None, {"safety_factor": 1.0}):
        res, _, wall = run(builders.frontal(ts), "impact_velocity", speeds)
        crush = res.out.max_crush.max(axis=0)
        if ref is None:
            ref = crush
        kind = "default tolerance 1e-3" if ts is None else "sf 1.0"
        for k, v in enumerate(speeds):
            add(
                f"frontal-9mass (1-D) {v:g} m/s, {kind}",
                outcome(res, k),
                float(res.out.energy_error[k]),
                int(steps_of(res)[k]),
                wall / len(speeds),
                f"max crush {crush[k]:.3f} m"
                + (f"; vs default step {crush[k] / ref[k] - 1:+.1e}" if ts else ""),
            )


def helicopter() -> None:
    print("helicopter-subfloor (2-D) 6 .. 100 m/s")
    model = builders.load_yaml(str(builders.HELICOPTER)).data
    for ts in (None, {"safety_factor": 1.0}):
        m = dict(model, output=dict(model["output"], histories=["position"]))
        if ts:
            m["time_step"] = ts
        res, plan, wall = run(m, "impact_velocity", cases.SPEEDS)
        k_tr = plan.topology.node_ids.index("transmission")
        low = np.nanmin(res.out.histories["position"][:, k_tr, 1, :], axis=0)
        kind = "default tolerance 1e-3" if ts is None else "sf 1.0"
        for k, v in enumerate(cases.SPEEDS):
            wrong = None
            if low[k] <= 0:
                wrong = (
                    f"transmission passes the ground node (y down to {low[k]:.2f} m); underfloor crushed through "
                    "zero length between two steps, not detected [bug]"
                )
            add(
                f"helicopter-subfloor (2-D) {v:g} m/s, {kind}",
                outcome(res, k, wrong),
                float(res.out.energy_error[k]),
                int(steps_of(res)[k]),
                wall / len(cases.SPEEDS),
                f"underfloor max crush {res.out.max_crush[0, k]:.3f} of 0.3 m; transmission lowest y {low[k]:.3f} m",
            )


def softening() -> None:
    print("softening curve (snap-through)")
    for ts in (None, {"safety_factor": 1.0}):
        kind = "default tolerance 1e-3" if ts is None else "sf 1.0"
        res, _, wall = run(builders.snap_through(1.0, ts), "impact_velocity", cases.SNAP_SPEEDS)
        for k, v in enumerate(cases.SNAP_SPEEDS):
            crush, _, peak = builders.snap_through_closed_form(v)
            c, p = res.out.max_crush[0, k], res.out.peak_force[0, k]
            snapped_exact, snapped = crush > 0.75, c > 0.75
            note = (
                f"crush {c:.4f} m vs exact {crush:.4f} ({c / crush - 1:+.1e}); peak force {p / peak - 1:+.1e}"
            )
            if snapped != snapped_exact:
                note += "; snaps through where the exact shell does not (accuracy of the critical step)"
            add(
                f"snap-through curve (slope -4 N/m) {v:g} m/s, {kind}",
                outcome(res, k),
                float(res.out.energy_error[k]),
                int(steps_of(res)[k]),
                wall / len(cases.SNAP_SPEEDS),
                note,
            )


def long_runs(quick: bool) -> None:
    print("long runs")
    for n_steps in [10**5] if quick else [10**6, 10**7]:
        model = builders.conservative(n_steps)
        res, _, wall = run(model, "end_time", [model["end_time"]])
        e = res.out.final_energy[:, 0]
        add(
            f"conservative 2-mass chain, sf 1.0, {n_steps:.0e} steps",
            outcome(res, 0, None if res.out.energy_error[0] < 1e-6 else "drift"),
            float(res.out.energy_error[0]),
            int(steps_of(res)[0]),
            wall,
            f"(KE + IE) / KE0 - 1 at the end {(e[0] + e[1]) / 4.5 - 1:+.1e}",
        )
    # the same springs and masses, nothing fixed, net momentum: positions drift far from x0 (1e5 m over 10^7
    # steps), so the elongation (x_j - x0_j) - (x_i - x0_i) loses digits to cancellation
    n_steps = 10**5 if quick else 10**7
    model = builders.conservative(n_steps)
    model["nodes"]["ground"] = {"position": [0.0], "mass": 1.0}
    model["initial_velocity"]["ground"] = [5.0]  # momentum 5 + 1 - 4 = 2 kg m/s: drifts at 0.5 m/s
    model = builders.at_step(model, n_steps)
    res, _, wall = run(model, "end_time", [model["end_time"]])
    drift = 0.5 * res.out.t_end[0]
    add(
        f"free 3-mass chain drifting (net momentum 2 kg m/s), sf 1.0, {n_steps:.0e} steps",
        outcome(res, 0),
        float(res.out.energy_error[0]),
        int(steps_of(res)[0]),
        wall,
        f"drifts {drift:.2g} m: elongations (x_j - x0_j) - (x_i - x0_i) lose digits to cancellation",
    )


def fixed_dt(tmp: Path) -> None:
    print("fixed dt above dt_crit (study over the end mass)")
    from crashstudy.study.plan import load_study

    masses = [1e-4, 1e-3, 1e-2, 0.1, 1.0]
    plan = load_study(builders.mass_axis_study(tmp, 1.0e-3, masses))
    t0 = time.perf_counter()
    res = runner.run_chunk(plan, 0, plan.n_variants)
    wall = time.perf_counter() - t0
    for k, mb in enumerate(masses):
        add(
            f"fixed dt 1 ms, end mass {mb:g} kg",
            outcome(res, k),
            None if res.out.status[k] else float(res.out.energy_error[k]),
            int(steps_of(res)[k]),
            wall / len(masses),
            f"dt_crit {res.dt_crit[k]:.3g} s",
        )


@contextlib.contextmanager
def forced_dt(
    node: str, v: float, factor: float | None = None, absolute: float | None = None
) -> Iterator[None]:
    """Overwrite, where the runner builds its batch, the step of the variants whose node ``node`` starts at
    velocity ``v``: ``factor`` x dt_crit, or ``absolute``."""
    real = runner.build_batch

    def patched(topo, P, interval):  # type: ignore[no-untyped-def]
        batch, steps = real(topo, P, interval)
        hit = batch.v0[topo.node_ids.index(node), 0] == v
        batch.dt[hit] = absolute if absolute is not None else factor * steps.dt_crit[hit]
        return batch, steps

    with mock.patch.object(runner, "build_batch", patched):
        yield


def forced() -> None:
    print("instabilities forced by hand")
    model = builders.conservative(2000)
    speeds = [1.0, 2.0, 3.0, 4.0]
    clean, _, _ = run(model, "impact_velocity", speeds)
    with forced_dt("b", -3.0, factor=3.0):
        res, _, wall = run(model, "impact_velocity", speeds)
    same = all(output_differences(res.out, clean.out, k, k) == [] for k in (0, 1, 3))
    add(
        "conservative chain, 3 m/s variant at dt = 3 x dt_crit by hand (batch of 4)",
        outcome(res, 2),
        None,
        int(steps_of(res)[2]),
        wall,
        f"other 3 variants bitwise equal to an unforced run: {same}",
    )
    K = np.array([[4.0e4, -3.0e4], [-3.0e4, 3.0e4]])
    Ms = 1.0 / np.sqrt(np.array([1.0, 2.0]))
    w_max = float(np.sqrt(np.linalg.eigvalsh(Ms[:, None] * K * Ms[None, :]).max()))
    with forced_dt("b", -3.0, absolute=1.0001 * 2.0 / w_max):
        res, _, wall = run(model, "impact_velocity", speeds)
    p = res.out.peak_force.max(axis=0)
    add(
        "conservative chain, 3 m/s variant at dt = 1.0001 x 2/omega_max by hand (2000 steps)",
        outcome(res, 2, f"blown up but finite: peak force {p[2]:.1e} N vs {p[0]:.1e} N, not flagged [gap]"),
        float(res.out.energy_error[2]),
        int(steps_of(res)[2]),
        wall,
        "only a non-finite energy balance is UNSTABLE",
    )


def dampers() -> None:
    print("dampers at safety_factor 1.0")
    for label, fixed, k, sf in (
        ("free pair, damper", False, None, 1.0),
        ("free pair, damper + 1e4 N/m spring", False, 1.0e4, 1.0),
        ("free pair, damper", False, None, 0.5),
        ("free pair, damper", False, None, None),
        ("fixed anchor, damper", True, None, 1.0),
        ("fixed anchor, damper", True, None, None),
    ):
        model = builders.damper_pair(sf or 1.0, k)
        if fixed:
            model["nodes"]["a"] = {"position": [0.0], "fixed": True}
        if sf is None:  # the default time_step, tolerance 1e-3; one sample so the step is not cut by it
            del model["time_step"]
            model["end_time"] = 0.2
            model["output"] = {"interval": 0.2, "histories": "none"}
        else:
            model = builders.at_step(model, 200)
        res, _, wall = run(model, "end_time", [model["end_time"]])
        ke = res.out.final_energy[0, 0]
        wrong = (
            None
            if abs(ke) <= 0.5
            else f"final KE {ke:.1e} J from 0.5 J: dt_crit 2x too large for dampers [bug]"
        )
        kind = f"sf {sf:g}" if sf else "default tolerance 1e-3"
        add(
            f"damper 1000 N s/m, {label}, {kind}",
            outcome(res, 0, wrong),
            float(res.out.energy_error[0]),
            int(steps_of(res)[0]),
            wall,
            f"dt {res.dt[0]:.3g} s; final KE {ke:.2g} J",
        )


# --------------------------------------------------------------------------------------------------


def machine() -> list[str]:
    import numba

    cpu = platform.processor() or "?"
    with contextlib.suppress(OSError):
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    commit = subprocess.run(
        ["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True, text=True
    ).stdout.strip()
    dirty = subprocess.run(
        ["git", "status", "--porcelain", "src"], cwd=ROOT, capture_output=True, text=True
    ).stdout
    if dirty.strip():
        commit += " + uncommitted changes under src/"
    load = os.getloadavg()
    return [
        f"- {cpu}, {os.cpu_count()} logical cores (shared: load average {load[0]:.2f} at the end)",
        f"- Python {platform.python_version()}, numpy {np.__version__}, numba {numba.__version__}, "
        f"{platform.system()} {platform.release()}",
        f"- crashstudy at commit {commit}, {_dt.datetime.now().strftime('%Y-%m-%d %H:%M')}",
    ]


def report(total: float) -> str:
    lines = [
        "# Stability stress table",
        "",
        "Written by `python benchmarks/stress.py` (issue 4, item 2); the same models as `tests/test_stress.py`,",
        "run through `run_chunk`. Outcome: `stable` (status ok and the check holds), `refused` / `failed` with the",
        "runner's reason verbatim, **WRONG** where the run says ok but the check shows otherwise (bugs, held as",
        "strict xfails in the tests). Energy error: the run's `energy_error` (max over time of the balance",
        "|KE + IE + E_wall - KE0 - W_ext| / (KE0 + |W_ext|)); without dampers, walls or loads it is an algebraic",
        "identity of central difference whatever the step, so it shows round-off, and accuracy is judged by the",
        "check column (closed forms). Steps: computed (chains: N + 2N, both runs). Wall: `run_chunk` seconds.",
        "",
        "| case | outcome | energy error | steps | wall [s] | check |",
        "|---|---|---|---|---|---|",
    ]
    for r in ROWS:
        lines.append(
            f"| {r['case']} | {r['outcome']} | {r['energy_error']} | {r['steps']} | {r['wall']} | {r['check']} |"
        )
    lines += ["", f"Total {total:.0f} s.", "", "Machine:", "", *machine(), ""]
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument(
        "--quick", action="store_true", help="short runs only; prints, writes nothing unless --report"
    )
    ap.add_argument(
        "--report", default=None, help="output file (default benchmarks/results/stress.md; - prints)"
    )
    args = ap.parse_args()
    import tempfile

    t0 = time.perf_counter()
    run(builders.conservative(10), "end_time", [1e-3])  # warm-up: load the compiled kernel
    chains(args.quick)
    ratios(args.quick)
    frontal()
    helicopter()
    softening()
    long_runs(args.quick)
    with tempfile.TemporaryDirectory() as tmp:
        fixed_dt(Path(tmp))
    forced()
    dampers()
    text = report(time.perf_counter() - t0)
    dest = args.report or ("-" if args.quick else str(ROOT / "benchmarks" / "results" / "stress.md"))
    if dest == "-":
        print(text)
    else:
        Path(dest).write_text(text)
        print(f"wrote {dest}")


if __name__ == "__main__":
    main()
