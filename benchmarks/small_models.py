"""Small models over many variants: where the time of ``crashstudy run`` goes when physics is cheap.

Models (1-D, SI): 1, 2 or 3 ``nonlinear_elastic`` springs in a chain from a fixed wall, the last
mass hitting at 2-8 m/s; about 100 steps per variant (``end_time`` 75 ms, ``safety_factor`` 0.9, one history sample: the step is not capped by the sampling interval). Studies: a matrix over
the masses and the impact velocity of 10^5 and 10^6 variants, histories none. Plus the long case
of issue 9: the 2-spring model, 10^5 variants x ~9000 steps (``end_time`` 6.8 s), beside the hand-specialised SIMD loop
of :mod:`two_spring_specialised` doing the same steps in the same process.

Each case runs in its own process (``--one``) on WARM caches ("second run": a first run of the same
study went before, and its background compile was waited for): ``load_study`` + ``run_plan`` end to
end, with the time inside the kernel calls (``kernel.entry.run_batch``) summed separately, so
"other" = everything outside the time-step loop (expansion, hashing, kernel set-up, writing). Peak
RSS from ``resource.getrusage``. Medians over ``--repeats``.

Run: ``python benchmarks/small_models.py [--repeats 3] [--cases ...]``.
Writes ``benchmarks/results/small_models.{csv,md}``.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from common import RESULTS, load, machine, machine_md, md_table, median, write_csv  # noqa: E402

CURVES = {
    "c1": ([-0.2, -0.05, 0.0, 0.05], [-4.0e5, -6.0e4, 0.0, 6.0e4]),
    "c2": ([-0.2, -0.05, 0.0, 0.05], [-2.0e5, -3.0e4, 0.0, 3.0e4]),
    "c3": ([-0.2, -0.05, 0.0, 0.05], [-1.0e5, -1.5e4, 0.0, 1.5e4]),
}


def model_yaml(n_springs: int, end_time: float) -> str:
    lines = [f"name: chain-{n_springs}", "units: SI", "curves:"]
    for c in list(CURVES)[:n_springs]:
        x, y = CURVES[c]
        lines.append(f"  {c}: {{x: {x}, y: {y}}}")
    lines.append("nodes:")
    lines.append("  wall: {position: [0.0], fixed: true}")
    for k in range(1, n_springs + 1):
        lines.append(f"  m{k}: {{position: [{0.5 * k}], mass: 1.0}}")
    lines.append("springs:")
    for k in range(1, n_springs + 1):
        a = "wall" if k == 1 else f"m{k - 1}"
        lines.append(f"  s{k}: {{nodes: [{a}, m{k}], material: {{type: nonlinear_elastic, curve: c{k}}}}}")
    lines.append(f"initial_velocity: {{m{n_springs}: [-5.0]}}")
    lines.append(f"end_time: {end_time}")
    lines.append("time_step: {safety_factor: 0.9}")
    lines.append(f"output: {{histories: none, interval: {end_time}}}")  # the step is not capped by sampling
    return "\n".join(lines) + "\n"


def study_yaml(n_springs: int, n_variants: int, model: Path) -> str:
    """Masses of the first two nodes (one node for one spring) x impact velocity, ``n_variants`` in all."""
    nv = 10 if n_variants <= 10**5 else 100
    rest = n_variants // nv
    axes = {}
    if n_springs == 1:
        axes["nodes.m1.mass"] = np.linspace(1.0, 3.0, rest)
    else:
        side = int(round(np.sqrt(rest)))
        axes["nodes.m1.mass"] = np.linspace(1.0, 2.0, side)
        axes["nodes.m2.mass"] = np.linspace(1.0, 3.0, rest // side)
    axes["impact_velocity"] = np.linspace(2.0, 8.0, nv)
    body = "\n".join(f"  {k}: {[round(float(v), 9) for v in vals]}" for k, vals in axes.items())
    return f"name: small-{n_springs}-{n_variants}\nmodel: {model}\nmatrix:\n{body}\n"


CASES = {  # name: (springs, variants, end_time [s])
    "1spring-1e5": (1, 10**5, 0.075),
    "2spring-1e5": (2, 10**5, 0.075),
    "3spring-1e5": (3, 10**5, 0.075),
    "1spring-1e6": (1, 10**6, 0.075),
    "2spring-1e6": (2, 10**6, 0.075),
    "3spring-1e6": (3, 10**6, 0.075),
    "2spring-1e5-long": (2, 10**5, 6.8),
}


def one(case: str, folder: Path) -> dict[str, Any]:
    """Run ``case`` once in this process; times in seconds."""
    from crashstudy.kernel import entry
    from crashstudy.run import runner
    from crashstudy.study.plan import load_study

    springs, n, end_time = CASES[case]
    model = folder / f"chain-{springs}-{end_time}.yaml"
    model.write_text(model_yaml(springs, end_time))
    study = folder / f"{case}.yaml"
    study.write_text(study_yaml(springs, n, model))
    spent = {"kernel": 0.0, "steps": 0.0}
    real = entry.run_batch  # every kernel call goes through the entry point

    def timed(batch, *a, **k):  # type: ignore[no-untyped-def]
        t0 = time.perf_counter()
        out = real(batch, *a, **k)
        spent["kernel"] += time.perf_counter() - t0
        spent["steps"] += float(np.sum(batch.n_steps)) * springs
        return out

    entry.run_batch = timed
    t0 = time.perf_counter()
    plan = load_study(study)
    rep = runner.run_plan(plan, folder / f"out-{case}", force=True, progress=False)
    total = time.perf_counter() - t0
    row = {
        "case": case,
        "variants": plan.n_variants,
        "element_steps": spent["steps"],
        "total_s": total,
        "kernel_s": spent["kernel"],
        "other_s": total - spent["kernel"],
        "other_us_per_variant": 1e6 * (total - spent["kernel"]) / plan.n_variants,
        "total_us_per_variant": 1e6 * total / plan.n_variants,
        "failed": rep.n_failed,
        "peak_rss_MiB": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
    }
    if case.endswith("long"):
        row.update(specialised(plan, rep.results.summary))
    return row


def specialised(plan: Any, summary: Any) -> dict[str, Any]:
    """The hand-specialised loop on the same variants and steps (batch built outside the timing)."""
    from crashstudy.arrays.batch import build_batch
    from two_spring_specialised import run_specialised

    batch, _ = build_batch(plan.topology, plan.params(0, plan.n_variants), plan.interval)
    m = batch.mass
    args = (
        np.ascontiguousarray(m[1]),
        np.ascontiguousarray(m[2]),
        np.ascontiguousarray(batch.v0[1, 0]),
        np.ascontiguousarray(batch.v0[2, 0]),
        batch.dt,
        batch.n_steps,
    )
    run_specialised(*(a[:256] for a in args))  # compile / load
    t0 = time.perf_counter()
    out = run_specialised(*args)
    t = time.perf_counter() - t0
    ours = summary[["peak_force.s1", "peak_force.s2"]].to_numpy().T
    rel = float(np.max(np.abs(out["peak_force"] - ours) / np.abs(ours)))
    return {"specialised_s": t, "peak_force_max_rel_diff_vs_specialised": rel}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--cases", nargs="+", default=list(CASES))
    ap.add_argument("--one", help=argparse.SUPPRESS)
    ap.add_argument("--folder", type=Path, help=argparse.SUPPRESS)
    ap.add_argument("--out", type=Path, default=RESULTS)
    args = ap.parse_args(argv)
    if args.one:
        print(json.dumps(one(args.one, args.folder)))
        return 0
    start_load = load()
    t_start = time.perf_counter()
    rows: list[dict[str, Any]] = []
    with tempfile.TemporaryDirectory(prefix="small-models-") as tmp:
        env = dict(os.environ)
        env.pop("CRASHSTUDY_KERNEL", None)
        for case in args.cases:
            cmd = [sys.executable, __file__, "--one", case, "--folder", tmp]
            first = json.loads(
                subprocess.run(cmd, env=env, capture_output=True, text=True, check=True).stdout
            )
            from crashstudy.kernel.choice import compiling

            while compiling():
                time.sleep(1.0)  # the first run's background compile
            runs = [
                json.loads(subprocess.run(cmd, env=env, capture_output=True, text=True, check=True).stdout)
                for _ in range(args.repeats)
            ]
            row = {
                k: (median([r[k] for r in runs]) if isinstance(v, float) else v) for k, v in runs[0].items()
            }
            row["first_run_total_s"] = first["total_s"]
            row["load"] = load()
            rows.append(row)
            print(json.dumps(row), flush=True)
    info = machine(start_load)
    write_csv(args.out / "small_models.csv", rows, info)
    cols = [
        "case",
        "variants",
        "element_steps",
        "total_s",
        "kernel_s",
        "other_s",
        "other_us_per_variant",
        "total_us_per_variant",
        "peak_rss_MiB",
        "first_run_total_s",
        "specialised_s",
        "peak_force_max_rel_diff_vs_specialised",
        "failed",
        "load",
    ]
    text = (
        "# Small models, many variants (second run, warm caches)\n\n"
        + machine_md(info)
        + f"- total script time: {time.perf_counter() - t_start:.0f} s\n\n"
        + __doc__.split("\n\n", 1)[1]
        + "\n"
        + md_table(rows, cols)
    )
    (args.out / "small_models.md").write_text(text)
    print(f"wrote {args.out / 'small_models.md'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
