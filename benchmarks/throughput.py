"""Throughput of the compiled kernels on the frontal model, beside a hand-specialised loop.

Two crashstudy kernels are measured: the generic one (topology read from arrays at run time,
:mod:`crashstudy.kernel.compiled`) and the generated one (numba source written from the model's
topology, :mod:`crashstudy.kernel.generated`, what ``crashstudy run`` uses for big studies).

Element-steps per second = (springs x steps, summed over variants) / seconds, for 1, 10^2, 10^4 and
10^6 variants of ``studies/models/frontal-9mass.yaml`` (engine mass x impact velocity, so the
variants differ), histories all and none, 1 and 2 threads. Beside every generic run, in the same
process and interleaved with it, :mod:`frontal_specialised` integrates the same variants with the
same steps and threads; the ratio generic / specialised is the median of the paired ratios.

What is timed: the kernel calls only (``run_compiled`` / ``run_specialised``), called chunk by chunk
exactly as ``crashstudy run`` does (``runner.chunk_size``: chunks of at most 8192 variants, fewer when
histories are kept so that a chunk's history arrays stay under 256 MiB); the allocation of the
output and history arrays is inside the call and so inside the time. Compile time and cache
loading are excluded: both kernels are warmed up on a small batch first. Batches are built before
timing. Wall time (``perf_counter``) and process CPU time (``process_time``, all threads) are both
recorded: on a shared machine CPU time is the steadier measure of the code, wall time is what a
user waits.

The default run keeps 10^6 variants short (``--end-time-big``, default 6 ms = 300 steps, the
first 5% of the crash) so that the script finishes in about 10 minutes; the element-step count
is the one actually computed.

Run: ``python benchmarks/throughput.py [--repeats 3] [--sizes 1 100 10000 1000000] [--threads 1 2]``.
Writes ``benchmarks/results/throughput.{csv,md,png}``.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from common import FRONTAL, RESULTS, load, machine, machine_md, md_table, median, write_csv  # noqa: E402
from crashstudy.arrays.batch import Batch, build_batch  # noqa: E402
from crashstudy.kernel.compiled import run_compiled  # noqa: E402
from crashstudy.kernel.compiled import set_threads as gen_threads  # noqa: E402
from crashstudy.kernel.generated import run_generated  # noqa: E402
from crashstudy.run.runner import MAX_CHUNK, chunk_size  # noqa: E402
from crashstudy.study.plan import Plan, load_study  # noqa: E402
from frontal_specialised import run_specialised  # noqa: E402
from frontal_specialised import set_threads as spec_threads  # noqa: E402

GOAL = 1.0e9  # element-steps/s, 2 threads, 10^4+ variants, histories off (issue 4)


def frontal_plan(n_variants: int, end_time: float | None, histories: str, curve_axis: bool = False) -> Plan:
    """The frontal model over an engine-mass x impact-velocity grid of ``n_variants`` variants
    (``curve_axis``: front-rail curve scale 0.8-1.6 instead of the engine mass, so the generated
    kernel keeps that curve's coefficients per variant instead of as constants)."""
    a = int(round(math.sqrt(n_variants)))
    while n_variants % a:
        a -= 1
    b = n_variants // a
    masses = [float(x) for x in np.linspace(120.0, 210.0, a)] if a > 1 else [170.0]
    speeds = [float(x) for x in np.linspace(10.0, 20.0, b)] if b > 1 else [15.556]
    set_: dict[str, Any] = {"output": {"histories": histories}}
    if end_time is not None:
        set_["end_time"] = end_time
    first = (
        ("curves.rail-loading.scale", [0.8 + 0.8 * (m - 120.0) / 90.0 for m in masses])
        if curve_axis
        else ("nodes.engine.mass", masses)
    )
    study = {
        "name": "throughput",
        "model": str(FRONTAL),
        "matrix": {first[0]: first[1], "impact_velocity": speeds},
        "set": set_,
    }
    plan = load_study(study)
    assert plan.n_variants == n_variants
    return plan


def chunks(plan: Plan) -> list[Batch]:
    """The plan's variants as the runner cuts them (built before timing)."""
    size = chunk_size(plan)
    out = []
    for lo in range(0, plan.n_variants, size):
        hi = min(lo + size, plan.n_variants)
        out.append(build_batch(plan.topology, plan.params(lo, hi), plan.interval)[0])
    return out


def run_all(
    kernel: str, batches: list[Batch], histories: tuple[str, ...], n_out: int
) -> tuple[float, float, Any]:
    """(wall s, CPU s, last output) of one kernel over all chunks."""
    fn = {"generic": run_compiled, "generated": run_generated, "specialised": run_specialised}[kernel]
    c0, t0 = time.process_time(), time.perf_counter()
    out = None
    for b in batches:
        out = fn(b, histories, n_out)
    return time.perf_counter() - t0, time.process_time() - c0, out


def peak_check(batches: list[Batch], histories: tuple[str, ...], n_out: int) -> tuple[float, bool]:
    """(largest relative difference of peak forces specialised vs generic, generated == generic
    bitwise on every summary) over the first chunk."""
    b = batches[0]
    g = run_compiled(b, histories, n_out)
    s = run_specialised(b, histories, n_out)
    x = run_generated(b, histories, n_out)
    same = all(
        np.array_equal(getattr(g, k), getattr(x, k), equal_nan=True)
        for k in ("status", "peak_force", "peak_acceleration", "max_crush", "absorbed_energy", "energy_error")
    )
    return float(np.max(np.abs(s.peak_force - g.peak_force) / np.maximum(np.abs(g.peak_force), 1e-300))), same


def warm_up() -> None:
    plan = frontal_plan(4, 0.0012, "all")
    b = chunks(plan)
    for hist in (plan.topology.histories, ()):
        run_compiled(b[0], hist, plan.n_out)
        run_generated(b[0], hist, plan.n_out)
        run_specialised(b[0], hist, plan.n_out)
    run_generated(chunks(frontal_plan(4, 0.0012, "none", curve_axis=True))[0], (), 1)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[1, 100, 10_000, 1_000_000])
    ap.add_argument("--threads", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument(
        "--end-time-big",
        type=float,
        default=0.006,
        help="end_time [s] for sizes >= 10^6 (the model has 0.12 s)",
    )
    ap.add_argument("--out", type=Path, default=RESULTS)
    args = ap.parse_args(argv)
    start_load = load()
    t_start = time.perf_counter()
    t0 = time.perf_counter()
    warm_up()
    print(
        f"warm-up (compile / cache load, excluded from the timings): {time.perf_counter() - t0:.1f} s",
        flush=True,
    )

    rows: list[dict[str, Any]] = []
    cases = [(V, h, False) for V in args.sizes for h in ("none", "all")]
    cases += [(V, "none", True) for V in args.sizes if V == 10_000]  # a study that scales a curve
    for V, hist_mode, curve_axis in cases:
        end_time = args.end_time_big if V >= 1_000_000 else None
        plan = frontal_plan(V, end_time, hist_mode, curve_axis)
        histories = plan.topology.histories
        batches = chunks(plan)
        S = plan.topology.n_springs
        n_steps = np.concatenate([b.n_steps for b in batches])
        elem_steps = float(S * n_steps.sum())
        check, same = peak_check(batches, histories, plan.n_out)
        for th in args.threads:
            gen_threads(th)
            spec_threads(th)
            load0 = load()
            kernels = ("generic", "generated", "specialised")
            res: dict[str, list[float]] = {k + sfx: [] for k in kernels for sfx in ("", "_cpu")}
            for r in range(args.repeats):
                for k in kernels[r % 3 :] + kernels[: r % 3]:  # rotate the order between repeats
                    wall, cpu, _ = run_all(k, batches, histories, plan.n_out)
                    res[k].append(wall)
                    res[k + "_cpu"].append(cpu)
            ratios = [g / s for g, s in zip(res["generic"], res["specialised"], strict=True)]
            gratios = [g / s for g, s in zip(res["generated"], res["specialised"], strict=True)]
            row = {
                "variants": V,
                "histories": hist_mode,
                "curve_axis": curve_axis,
                "threads": th,
                "steps_per_variant": int(n_steps.max()),
                "end_time_s": float(plan.base[plan.topology.blocks["end_time"].start]),
                "chunk": min(chunk_size(plan), MAX_CHUNK),
                "element_steps": elem_steps,
                "generic_s": median(res["generic"]),
                "specialised_s": median(res["specialised"]),
                "generic_es_per_s": elem_steps / median(res["generic"]),
                "specialised_es_per_s": elem_steps / median(res["specialised"]),
                "generated_s": median(res["generated"]),
                "generated_es_per_s": elem_steps / median(res["generated"]),
                "generic_es_per_cpu_s": elem_steps / median(res["generic_cpu"]),
                "generated_es_per_cpu_s": elem_steps / median(res["generated_cpu"]),
                "specialised_es_per_cpu_s": elem_steps / median(res["specialised_cpu"]),
                "ratio_generic_over_specialised": median(ratios),
                "ratio_min": min(ratios),
                "ratio_max": max(ratios),
                "ratio_generated_over_specialised": median(gratios),
                "gratio_min": min(gratios),
                "gratio_max": max(gratios),
                "repeats": args.repeats,
                "peak_force_max_rel_diff": check,
                "generated_equals_generic": same,
                "load_before": load0,
                "load_after": load(),
            }
            rows.append(row)
            print(
                f"V={V:>8} hist={hist_mode:4} curve_axis={curve_axis} threads={th}: generic "
                f"{row['generic_es_per_s']:.3g}, generated {row['generated_es_per_s']:.3g}, specialised "
                f"{row['specialised_es_per_s']:.3g} es/s; generated/specialised time "
                f"{row['ratio_generated_over_specialised']:.2f} (peak-force check {check:.1e}, generated == "
                f"generic: {same}; load {row['load_after']})",
                flush=True,
            )

    args.out.mkdir(parents=True, exist_ok=True)
    info = machine(start_load)
    write_csv(args.out / "throughput.csv", rows, info)
    plot(rows, args.out / "throughput.png")
    cols = [
        "variants",
        "histories",
        "curve_axis",
        "threads",
        "steps_per_variant",
        "element_steps",
        "generic_es_per_s",
        "generated_es_per_s",
        "specialised_es_per_s",
        "ratio_generated_over_specialised",
        "gratio_min",
        "gratio_max",
        "ratio_generic_over_specialised",
        "generated_es_per_cpu_s",
        "specialised_es_per_cpu_s",
        "generated_equals_generic",
        "load_after",
    ]
    text = (
        "# Throughput: generic and generated kernels vs hand-specialised loop (frontal-9mass)\n\n"
        + machine_md(info)
        + f"- total script time: {time.perf_counter() - t_start:.0f} s\n\n"
        + "Element-steps/s = springs x steps summed over variants / median wall seconds of "
        f"{args.repeats} repeats (compile and cache load excluded: both kernels warmed up first). "
        "`*_per_cpu_s` divides by process CPU seconds instead (all threads). Ratios = medians of the "
        "paired wall-time ratios (kernel time / specialised time, the three kernels run in rotating order in "
        "each repeat; > 1 means slower than the hand-specialised loop). `curve_axis`: the study scales the "
        "front-rail curve (its coefficients are per-variant rows in the generated kernel) instead of the "
        "engine mass. `generated_equals_generic`: every summary bitwise equal over the first chunk.\n\n"
        + md_table(rows, cols)
        + "\n![throughput](throughput.png)\n"
    )
    (args.out / "throughput.md").write_text(text)
    print(f"wrote {args.out / 'throughput.md'} ({time.perf_counter() - t_start:.0f} s)")
    return 0


def plot(rows: list[dict[str, Any]], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(11, 4.4), sharey=True)
    for ax, hist in zip(axes, ("none", "all"), strict=True):
        for th, ls in ((1, "--"), (2, "-")):
            sel = [r for r in rows if r["histories"] == hist and r["threads"] == th and not r["curve_axis"]]
            if not sel:
                continue
            x = [r["variants"] for r in sel]
            ax.plot(
                x,
                [r["generic_es_per_s"] for r in sel],
                "o" + ls,
                color="C0",
                label=f"generic, {th} thread(s)",
            )
            ax.plot(
                x,
                [r["generated_es_per_s"] for r in sel],
                "^" + ls,
                color="C2",
                label=f"generated, {th} thread(s)",
            )
            ax.plot(
                x,
                [r["specialised_es_per_s"] for r in sel],
                "s" + ls,
                color="C3",
                label=f"hand-specialised, {th} thread(s)",
            )
        ax.axhline(GOAL, color="gray", lw=0.8, ls=":")
        ax.text(1.2, GOAL * 1.15, "goal 1e9 (2 threads, histories off)", color="gray", fontsize=8)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("variants")
        ax.set_title(f"frontal-9mass, histories {hist}")
        ax.grid(True, which="both", alpha=0.3)
    axes[0].set_ylabel("element-steps per second (wall)")
    axes[0].legend(fontsize=8, loc="lower right")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


if __name__ == "__main__":
    raise SystemExit(main())
