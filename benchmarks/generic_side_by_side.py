"""The generic kernel of two source trees side by side: CPU seconds per call and cold compile.

Two worker processes, one per tree (``PYTHONPATH=<tree>/src``, each with its own numba and kernel cache
folders), are started from this one script; the parent asks them in turn (base, branch, base, branch, ...)
to time one ``run_compiled`` call on the same batch, so both see the same load. Figures:

- run: CPU seconds (``process_time`` of the worker) per ``run_compiled`` call on each of ``--models``
  (frontal: frontal-9mass.yaml over engine mass x impact velocity; tension: general-nonlinear-tension.yaml,
  prescribed motion and general_nonlinear reversals; helicopter: helicopter-seat.yaml, 2-D, gravity,
  general_nonlinear and crush; the last two over a loading-curve scale 0.9-1.1), 256 variants (one block),
  the model's end time, no histories, 1 thread, after a warm-up call; the median of ``--repeats`` calls
  each and the median of the paired (branch / base) ratios;
- compile (``--compile``): one fresh process per tree with EMPTY cache folders, the ``process_time`` of its
  first ``run_compiled`` call on 4 frontal variants minus that of its second (the run itself), trees
  alternated ``--compile-repeats`` times.

Run: ``python benchmarks/generic_side_by_side.py BASE_TREE BRANCH_TREE [--repeats 5] [--models frontal tension
helicopter] [--compile]
[--cache-root DIR]``. Prints one JSON line per figure and the load average at both ends.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile

WORKER = r"""
import sys, time, json
import numpy as np
root = sys.argv[1]
sys.path.insert(0, root + "/benchmarks")
from crashstudy.kernel.compiled import run_compiled
from crashstudy.kernel.driver import set_threads
set_threads(1)
mode, model = sys.argv[2], sys.argv[4]
MODELS = {  # model: (file, axis over 256 variants (one block), end time)
    "frontal": ("frontal-9mass", None, None),
    "tension": ("general-nonlinear-tension", "curves.table3-loading.scale", None),
    "helicopter": ("helicopter-seat", "curves.underfloor-loading.scale", None),
}


def plan_of(n, end_time):
    import throughput as tp
    from crashstudy.study.plan import load_study

    name, axis, _ = MODELS[model]
    if axis is None:
        return tp.frontal_plan(n, end_time, "none")
    set_ = {"output": {"histories": "none"}}
    if end_time is not None:
        set_["end_time"] = end_time
    values = [float(v) for v in np.linspace(0.9, 1.1, n)]
    study = {"name": "gsbs", "model": root + "/studies/models/" + name + ".yaml", "matrix": {axis: values}, "set": set_}
    return load_study(study)


def batch_of(plan):
    import throughput as tp

    return tp.chunks(plan)[0]


if mode == "compile":
    plan = plan_of(4, 0.0012 if model == "frontal" else None)
    b = batch_of(plan)
    c0 = time.process_time(); run_compiled(b, (), plan.n_out); c1 = time.process_time()
    run_compiled(b, (), plan.n_out); c2 = time.process_time()
    print(json.dumps({"compile_cpu_s": (c1 - c0) - (c2 - c1)}), flush=True)
    sys.exit(0)
plan = plan_of(256, None if sys.argv[3] == "model" else float(sys.argv[3]))
b = batch_of(plan)
run_compiled(b, (), plan.n_out)  # warm (loads or compiles the kernel)
print("ready", flush=True)
for line in sys.stdin:
    c0 = time.process_time(); run_compiled(b, (), plan.n_out); c1 = time.process_time()
    print(c1 - c0, flush=True)
"""


def _env(root: str, cache: str) -> dict[str, str]:
    env = dict(os.environ)
    env.update(
        PYTHONPATH=root + "/src",
        NUMBA_CACHE_DIR=cache + "/numba",
        CRASHSTUDY_KERNEL_CACHE=cache + "/kernels",
        NUMBA_NUM_THREADS="1",
        OMP_NUM_THREADS="1",
    )
    for sub in ("numba", "kernels"):
        os.makedirs(f"{cache}/{sub}", mode=0o700, exist_ok=True)
    return env


def runs(
    trees: list[str],
    caches: list[str],
    repeats: int,
    end_time: str,
    model: str,
    worker: str = WORKER,
    figure: str = "256 variants, 1 thread",
) -> dict[str, object]:
    """CPU seconds of ``repeats`` calls in each tree's ``worker`` (it prints "ready", then one figure per
    line it reads), trees alternated (also :mod:`generic_narrow`)."""
    procs = [
        subprocess.Popen(
            [sys.executable, "-c", worker, t, "run", str(end_time), model],
            env=_env(t, c),
            text=True,
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
        )
        for t, c in zip(trees, caches, strict=True)
    ]
    for p in procs:
        assert p.stdout is not None and p.stdout.readline().strip() == "ready"
    times: list[list[float]] = [[], []]
    for _ in range(repeats):
        for k, p in enumerate(procs):
            assert p.stdin is not None and p.stdout is not None
            p.stdin.write("go\n")
            p.stdin.flush()
            times[k].append(float(p.stdout.readline()))
    for p in procs:
        assert p.stdin is not None
        p.stdin.close()
        p.wait()
    med = [sorted(t)[len(t) // 2] for t in times]
    return {
        "figure": f"run_cpu_s_per_call ({model}, {figure})",
        "base": med[0],
        "branch": med[1],
        "ratio": med[1] / med[0],
        "paired_ratio_median": sorted(b / a for a, b in zip(times[0], times[1], strict=True))[repeats // 2],
        "base_all": times[0],
        "branch_all": times[1],
    }


def compiles(trees: list[str], repeats: int, cache_root: str) -> dict[str, object]:
    cpu: list[list[float]] = [[], []]
    for _ in range(repeats):
        for k, t in enumerate(trees):
            cache = tempfile.mkdtemp(prefix=f"cold{k}_", dir=cache_root)
            out = subprocess.run(
                [sys.executable, "-c", WORKER, t, "compile", "model", "frontal"],
                env=_env(t, cache),
                text=True,
                capture_output=True,
                check=True,
            ).stdout
            cpu[k].append(json.loads(out.strip().splitlines()[-1])["compile_cpu_s"])
            shutil.rmtree(cache, ignore_errors=True)
    med = [sorted(c)[len(c) // 2] for c in cpu]
    return {
        "figure": "generic cold compile CPU s",
        "base": med[0],
        "branch": med[1],
        "ratio": med[1] / med[0],
        "base_all": cpu[0],
        "branch_all": cpu[1],
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("base")
    ap.add_argument("branch")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--end-time", default="model", help="seconds, or 'model': the model's own end time")
    ap.add_argument("--models", nargs="+", default=["frontal"], choices=["frontal", "tension", "helicopter"])
    ap.add_argument("--compile", action="store_true")
    ap.add_argument("--compile-repeats", type=int, default=1)
    ap.add_argument("--no-run", action="store_true")
    ap.add_argument("--cache-root", default=tempfile.gettempdir())
    ap.add_argument("--caches", nargs=2, default=None, help="warm cache folders of base and branch (runs)")
    a = ap.parse_args()
    trees = [os.path.abspath(a.base), os.path.abspath(a.branch)]
    caches = a.caches or [tempfile.mkdtemp(prefix=f"warm{k}_", dir=a.cache_root) for k in range(2)]
    print(json.dumps({"load_start": os.getloadavg(), "trees": trees}), flush=True)
    if not a.no_run:
        for model in a.models:
            print(json.dumps(runs(trees, caches, a.repeats, a.end_time, model)), flush=True)
    if a.compile:
        print(json.dumps(compiles(trees, a.compile_repeats, a.cache_root)), flush=True)
    print(json.dumps({"load_end": os.getloadavg()}), flush=True)


if __name__ == "__main__":
    main()
