"""Run speed of a generated kernel in the process that compiled it and loaded from numba's cache.

The frontal model, 2048 variants (engine mass x impact velocity, full length, histories none), 1 thread,
generated kernel only (``run_generated`` chunk by chunk as ``crashstudy run`` cuts them): process CPU s of
each of ``--repeats`` runs, after one untimed run (which compiles, or loads from the cache). Run twice with
the same ``NUMBA_CACHE_DIR`` / ``CRASHSTUDY_KERNEL_CACHE``: with empty caches (``fresh``: this process
compiles the kernel) and again (``cache``: the kernel is loaded from the disk cache).

Run: ``python benchmarks/split_speed.py [--repeats 5] [--variants 2048]``; prints one line
``mode | median CPU s | min CPU s | compile CPU s | load``.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from common import load, median  # noqa: E402
from crashstudy.kernel.compiled import set_threads  # noqa: E402
from crashstudy.kernel.generated import is_compiled, run_generated  # noqa: E402
from throughput import chunks, frontal_plan  # noqa: E402


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--variants", type=int, default=2048)
    args = ap.parse_args(argv)
    set_threads(1)
    plan = frontal_plan(args.variants, None, "none")
    batches = chunks(plan)
    h = plan.topology.histories
    mode = "cache" if is_compiled(batches[0], h) else "fresh"
    c0 = time.process_time()
    run_generated(batches[0], h, plan.n_out)
    first = time.process_time() - c0
    cpu = []
    for _ in range(args.repeats):
        c0 = time.process_time()
        for b in batches:
            run_generated(b, h, plan.n_out)
        cpu.append(time.process_time() - c0)
    print(
        f"{mode} | {median(cpu):.3f} | {min(cpu):.3f} | {first:.1f} | {load()} | "
        f"{os.environ.get('NUMBA_CACHE_DIR', '')}"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
