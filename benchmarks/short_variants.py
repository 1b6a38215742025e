"""Short variants against long ones (issue 25 item 2): where a 10^6 x 86-step study's CPU goes, per variant.

The 2-spring 1-D model of ``matrix.py`` (``nonlinear_elastic`` curves of 5 and 6 points), a matrix over a mass
x ``curves.outer.scale`` (x ``impact_velocity``), histories none, warm caches, in this process:

- ``kernel``: the generated kernel alone (``kernel.generated.run_generated`` on a built batch, best of 3,
  process CPU seconds, ``--threads`` threads): 65,536 variants x 86 steps (fixed dt, the matrix's 10^6 cell)
  against 1,000 variants x 8,695 steps (its 10^3 / 10^5 cells). ``short / long`` = the short variants'
  element-steps per CPU second over the long ones': the per-variant set-up, summaries and block bookkeeping
  inside the kernel are what makes it fall below 1.
- ``chunk``: ``run.runner.run_chunk`` of 65,536-variant chunks (the runner's chunk at 86 steps), CPU per
  variant split into the kernel entry (``entry.run_batch``) and the rest (batch, step choice, dedupe, texts,
  hashes), for the fixed-dt model and for ``time_step: {safety_factor: 0.085}`` (~86 steps; the chunk is built
  in step order).

Run: ``python benchmarks/short_variants.py [--threads 1]``. Writes ``benchmarks/results/short_variants.md``.
CPU seconds, not wall: the machine is shared.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from common import RESULTS, load, machine, machine_md, md_table  # noqa: E402
from matrix import MODEL_SPECS, study_text  # noqa: E402

CHUNK = 65536


def _plan(folder: Path, size: int, safety: bool) -> Any:
    from crashstudy.study.plan import load_study

    text = MODEL_SPECS["2spring"]["text"].replace(
        "END", str(MODEL_SPECS["2spring"]["end"][int(size >= 10**6)])
    )
    if safety:
        text = text.replace("time_step: {dt: 1.0e-4}", "time_step: {safety_factor: 0.085}")
    model = folder / f"m-{size}-{safety}.yaml"
    model.write_text(text)
    study = folder / f"s-{size}-{safety}.yaml"
    study.write_text(study_text("2spring", "scale", size, model))
    return load_study(study)


def kernel_rate(plan: Any, n: int, repeats: int = 3) -> dict[str, Any]:
    from crashstudy.arrays.batch import build_batch
    from crashstudy.kernel.generated import run_generated

    b, _ = build_batch(plan.topology, plan.params(0, n), plan.interval)
    vary = plan.varying_curves
    run_generated(b, (), 1, vary)  # load
    best = np.inf
    for _ in range(repeats):
        c0 = time.process_time()
        run_generated(b, (), 1, vary)
        best = min(best, time.process_time() - c0)
    es = float(np.sum(b.n_steps)) * len(b.spring_i)
    return {
        "variants": n,
        "steps": int(b.n_steps.max()),
        "kernel_cpu_s": best,
        "element_steps_per_cpu_s": es / best,
        "us_per_variant": 1e6 * best / n,
    }


def chunk_split(plan: Any, chunks: int = 3) -> dict[str, Any]:
    from crashstudy.kernel import entry
    from crashstudy.run import runner

    runner.run_chunk(plan, 0, 1000)  # load
    spent = [0.0]
    real = entry.run_batch

    def timed(*a: Any, **k: Any) -> Any:
        c0 = time.process_time()
        try:
            return real(*a, **k)
        finally:
            spent[0] += time.process_time() - c0

    entry.run_batch = timed  # type: ignore[assignment]
    try:
        c0 = time.process_time()
        for k in range(1, chunks + 1):
            runner.run_chunk(plan, k * CHUNK, (k + 1) * CHUNK)
        total = time.process_time() - c0
    finally:
        entry.run_batch = real  # type: ignore[assignment]
    n = chunks * CHUNK
    return {
        "chunk_us_per_variant": 1e6 * total / n,
        "kernel_entry_us": 1e6 * spent[0] / n,
        "rest_us": 1e6 * (total - spent[0]) / n,
    }


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--out", type=Path, default=RESULTS / "short_variants.md")
    args = ap.parse_args()
    from crashstudy.kernel.driver import set_threads

    set_threads(args.threads)
    start = load()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        short, long_ = _plan(folder, 10**6, False), _plan(folder, 1000, False)
        ks, kl = kernel_rate(short, CHUNK), kernel_rate(long_, 1000)
        rows = [{"case": "kernel, 86 steps (short)", **ks}, {"case": "kernel, 8695 steps (long)", **kl}]
        ratio = ks["element_steps_per_cpu_s"] / kl["element_steps_per_cpu_s"]
        split = [
            {"model": "fixed dt (matrix.py 2spring)", **chunk_split(short)},
            {"model": "safety_factor 0.085", **chunk_split(_plan(folder, 10**6, True))},
        ]
    text = (
        f"# Short variants against long ones (benchmarks/short_variants.py)\n\n{machine_md(machine(start))}\n\n"
        f"## Inside the generated kernel ({args.threads} thread(s), CPU s, best of 3)\n\n{md_table(rows)}\n\n"
        f"**short / long element-steps per CPU second: {ratio:.2f}** (issue 25 goal: >= 0.30).\n\n"
        f"## A 65,536-variant chunk (run.runner.run_chunk), CPU us per variant\n\n{md_table(split)}\n"
    )
    args.out.write_text(text)
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
