"""Where the CPU and wall time of one ``crashstudy run`` go, phase by phase (issue 25: the time outside the kernel).

Runs the command line in this process (``crashstudy.cli.main.main``) with a timer around each phase:
the imports, ``load_study`` (load, validate, expand, work estimate), ``check_plan``, creating the result
store, the kernel start, per chunk (``params_at``, ``build_batch``, the kernel ``run_ordered``, hashes,
curve ends, the rest of ``run_chunk``), writing each chunk (``ResultWriter.write``: netCDF/Zarr and, since
the summary is streamed, the Parquet row groups), the finish (text tables, run id, ``write_summary`` when
the store is read back, manifest, renames) and the checks after the run. Times are exclusive (a phase
inside another is not counted twice). CPU = the CPU seconds of the thread that ran the phase (the main
thread, or the writer thread of run/write_behind.py, whose writes overlap the next chunk); the kernel's own
worker threads are the line "kernel worker threads, and the rest" (process total minus the phases).
Wall seconds of the writer thread's phase overlap the main thread's.

Run: ``python benchmarks/run_phases.py run STUDY -o OUT --force`` (any ``crashstudy`` arguments); the
table goes to stderr. ``PHASES_WRITE_BEHIND=0``: no writer thread. ``PYTHONPATH`` chooses the code measured (e.g. an archive of an older commit).
"""

from __future__ import annotations

import os
import resource
import sys
import threading
import time
from typing import Any


def _cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


T0W, T0C = time.perf_counter(), _cpu()

import crashstudy.kernel.entry as E  # noqa: E402
import crashstudy.results.integrity as I  # noqa: E402, E741
import crashstudy.results.store as S  # noqa: E402
import crashstudy.run.chunk as C  # noqa: E402
import crashstudy.run.runner as R  # noqa: E402
import crashstudy.study.plan as P  # noqa: E402
import crashstudy.study.sanity as SA  # noqa: E402
from crashstudy.cli import main as M  # noqa: E402

ACC: dict[str, list[float]] = {}  # label: [thread CPU, wall, calls] (exclusive of the phases inside it)
FIRST: list[float] = []  # process CPU and wall from the end of the imports to the first kernel call
KERNEL = "chunk: kernel (run_ordered)"
IMPORT_C = IMPORT_W = 0.0
LOCAL = threading.local()  # each thread's stack of open phases (the writer thread has its own)


def wrap(owner: Any, name: str, label: str) -> None:
    real = getattr(owner, name)

    def timed(*a: Any, **k: Any) -> Any:
        if label == KERNEL and not FIRST:  # the time before the first kernel call (after the imports)
            FIRST.extend([_cpu() - T0C - IMPORT_C, time.perf_counter() - T0W - IMPORT_W])
        stack = LOCAL.__dict__.setdefault("stack", [])
        c0, w0 = time.thread_time(), time.perf_counter()
        stack.append([0.0, 0.0])  # CPU and wall of the phases opened inside this one
        try:
            return real(*a, **k)
        finally:
            inner = stack.pop()
            c, w = time.thread_time() - c0, time.perf_counter() - w0
            e = ACC.setdefault(label, [0.0, 0.0, 0])
            e[0], e[1], e[2] = e[0] + c - inner[0], e[1] + w - inner[1], e[2] + 1
            if stack:
                stack[-1][0] += c
                stack[-1][1] += w

    setattr(owner, name, timed)


PHASES = [
    (P, "load_study", "load / validate / expand / work estimate"),
    (SA, "check_plan", "pre-run checks (check_plan)"),
    (S.ResultWriter, "__init__", "create the result store"),
    (R, "start_kernels", "kernel start (choice, loading)"),
    (C, "run_chunk", "chunk: rest of run_chunk"),
    (C, "_step_order", "chunk: params_at (step order)"),
    (C, "build_batch", "chunk: build_batch"),
    (E, "run_ordered", "chunk: kernel (run_ordered)"),
    (C, "variant_hashes", "chunk: variant_hashes"),
    (C, "past_curve_ends", "chunk: past_curve_ends"),
    (S.ResultWriter, "write", "write a chunk (store + summary rows)"),
    (S.ResultWriter, "finish", "finish: renames"),
    (S.ResultWriter, "_sort_tables", "finish: sort text tables"),
    (I, "run_id", "finish: run id"),
    (S, "write_summary", "finish: summary read back from the store"),
    (I, "write_manifest", "finish: manifest"),
    (R, "Results", "open the results"),
    (M, "_after_run", "checks after the run (warnings)"),
    (R, "run_plan", "run_plan (rest)"),
]
for owner, name, label in PHASES:
    if hasattr(owner, name):
        wrap(owner, name, label)
IMPORT_C, IMPORT_W = _cpu() - T0C, time.perf_counter() - T0W
if os.environ.get("PHASES_WRITE_BEHIND") == "0":  # every write in the main thread (compare the two)
    import crashstudy.run.write_behind as WB

    WB.THREADED = False


def main() -> int:
    rc = M.main(sys.argv[1:])
    total_c, total_w = _cpu() - T0C, time.perf_counter() - T0W
    rows = [("imports (crashstudy.cli, runner, store)", IMPORT_C, IMPORT_W, 1)]
    rows += [(label, *ACC[label]) for _, _, label in PHASES if label in ACC]  # type: ignore[misc]
    named = sum(r[1] for r in rows)
    rows.append(("kernel worker threads, and the rest", total_c - named, float("nan"), 1))
    out = ["| phase | cpu_s (its thread) | wall_s | calls |", "|---|---|---|---|"]
    out += [f"| {a} | {c:.3f} | {w:.3f} | {int(n)} |" for a, c, w, n in rows]
    out.append(f"| **total in process** | **{total_c:.3f}** | **{total_w:.3f}** | |")
    if FIRST:
        out.append(
            f"| before the first kernel call (after the imports) | {FIRST[0]:.3f} (process) | {FIRST[1]:.3f} | |"
        )
    print("\n".join(out) + f"\n\nload average at end: {os.getloadavg()[0]:.2f}", file=sys.stderr)
    return rc


if __name__ == "__main__":
    sys.exit(main())
