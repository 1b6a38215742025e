"""Time of :func:`crashstudy.metrics.criteria.compute` for a frontal-study-sized batch.

V = 10^4 variants of T = 5000 steps (each its own dt, 16-24 us: records of 80-120 ms), D = 1 and
D = 2, all criteria, CFC 180. The pulses are a sin^2 deceleration of 25-40 g over 60-100 ms with a
15 % ripple at 50-300 Hz and 3 % white noise (what a spring-mass model's node gives), along a
per-variant direction in 2-D.

- ``warm``: median (and min/max) of 5 calls in one process after a first call (compiled code
  loaded), wall time and process CPU time (compute() is single-threaded, so on a shared machine
  the CPU time is the steadier figure).
- ``with compile``: a fresh process with an empty numba cache: import + first call (compile +
  run), and the same process's second call, so the compile time is the difference.
- one row per criterion alone and two typical sets (an occupant's peak_g, hic15 and clips; a
  cabin's peak_g, olc, delta_v), warm median of 3, D = 1, to see where the time goes.

Run: ``python benchmarks/criteria.py [--variants 10000 --steps 5000]``.
Writes ``benchmarks/results/criteria.json`` (machine, commit, all numbers).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from common import RESULTS, load, machine, median  # noqa: E402

G = 9.80665


def batch(nv: int, nt: int, nd: int, seed: int = 0) -> tuple[np.ndarray, ...]:
    rng = np.random.default_rng(seed)
    dt = rng.uniform(1.6e-5, 2.4e-5, nv)
    count = np.full(nv, nt, dtype=np.int64)
    acc = np.empty((nv, nt, nd))
    ang = rng.uniform(-0.3, 0.3, nv)
    dirs = np.stack([np.cos(ang), np.sin(ang)], axis=1)[:, :nd]
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    chunk = 1000
    for a in range(0, nv, chunk):
        b = min(nv, a + chunk)
        t = np.arange(nt)[None, :] * dt[a:b, None]
        tau = rng.uniform(0.06, 0.1, (b - a, 1))
        peak = rng.uniform(25, 40, (b - a, 1)) * G
        f = rng.uniform(50, 300, (b - a, 1))
        s = np.clip(t / tau, 0.0, 1.0)
        d = peak * np.sin(np.pi * s) ** 2 * (1 + 0.15 * np.sin(2 * np.pi * f * t))
        d += 0.03 * peak * rng.standard_normal(d.shape)
        acc[a:b] = -d[:, :, None] * dirs[a:b, None, :]
    v0 = rng.uniform(12, 18, nv)[:, None] * dirs
    return acc, count, dt, v0, dirs


CPU: list[float] = []  # process CPU seconds of each timed call (the machine is shared: wall time
# includes waiting for a core; compute() is single-threaded, so CPU time is its own work)


def timed(fn: Any) -> float:
    c0 = time.process_time()
    t0 = time.perf_counter()
    fn()
    CPU.append(time.process_time() - c0)
    return time.perf_counter() - t0


def cpu_median(k: int) -> float:
    return median(CPU[-k:])


def child(nv: int, nt: int, nd: int) -> None:
    """In a fresh process: import + first call (compile) and second call, printed as JSON."""
    t0 = time.perf_counter()
    from crashstudy.metrics import criteria

    t_import = time.perf_counter() - t0
    args = batch(nv, nt, nd)
    first = timed(lambda: criteria.compute(*args, 180, criteria.CRITERIA, G))
    second = timed(lambda: criteria.compute(*args, 180, criteria.CRITERIA, G))
    print(json.dumps({"import_s": t_import, "first_call_s": first, "second_call_s": second}))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--variants", type=int, default=10_000)
    ap.add_argument("--steps", type=int, default=5000)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--out", type=Path, default=RESULTS)
    ap.add_argument("--child", nargs=3, type=int, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.child:
        child(*args.child)
        return 0
    start_load = load()
    from crashstudy.metrics import criteria

    rows: list[dict[str, Any]] = []
    for nd in (1, 2):
        with tempfile.TemporaryDirectory() as cache:
            env = {**os.environ, "NUMBA_CACHE_DIR": cache}
            cmd = [sys.executable, __file__, "--child", str(args.variants), str(args.steps), str(nd)]
            out = subprocess.run(cmd, env=env, capture_output=True, text=True, check=True)
            cold = json.loads(out.stdout.strip().splitlines()[-1])
        data = batch(args.variants, args.steps, nd)
        criteria.compute(*data, 180, criteria.CRITERIA, G)  # warm up (cache load)
        ts = [
            timed(lambda d=data: criteria.compute(*d, 180, criteria.CRITERIA, G)) for _ in range(args.repeats)
        ]
        row = {
            "variants": args.variants,
            "steps": args.steps,
            "D": nd,
            "criteria": "all",
            "cfc": 180,
            "warm_median_s": median(ts),
            "warm_min_s": min(ts),
            "warm_max_s": max(ts),
            "warm_cpu_median_s": cpu_median(len(ts)),
            "warm_cpu_us_per_variant": 1e6 * cpu_median(len(ts)) / args.variants,
            "fresh_process_import_s": cold["import_s"],
            "fresh_process_first_call_s (compile + run)": cold["first_call_s"],
            "fresh_process_second_call_s": cold["second_call_s"],
            "compile_s (first - second)": cold["first_call_s"] - cold["second_call_s"],
        }
        rows.append(row)
        print(json.dumps(row), flush=True)
        if nd == 1:
            # a frontal study with an occupant: the occupant's head/chest criteria and the cabin's
            sets = {
                "occupant: peak_g hic15 clip3ms clip3ms_cumulative": [
                    "peak_g",
                    "hic15",
                    "clip3ms",
                    "clip3ms_cumulative",
                ],
                "cabin: peak_g olc delta_v": ["peak_g", "olc", "delta_v"],
            }
            for label, names in sets.items():
                ts1 = [timed(lambda d=data, n=names: criteria.compute(*d, 180, n, G)) for _ in range(3)]
                r = {
                    "variants": args.variants,
                    "steps": args.steps,
                    "D": 1,
                    "criteria": label,
                    "warm_median_s": median(ts1),
                    "warm_cpu_median_s": cpu_median(3),
                }
                rows.append(r)
                print(json.dumps(r), flush=True)
            for name in criteria.CRITERIA:
                ts1 = [timed(lambda d=data, n=name: criteria.compute(*d, 180, [n], G)) for _ in range(3)]
                r = {
                    "variants": args.variants,
                    "steps": args.steps,
                    "D": 1,
                    "criteria": name,
                    "warm_median_s": median(ts1),
                    "warm_cpu_median_s": cpu_median(3),
                }
                rows.append(r)
                print(json.dumps(r), flush=True)
        del data
    info = machine(start_load)
    args.out.mkdir(parents=True, exist_ok=True)
    path = args.out / "criteria.json"
    path.write_text(json.dumps({"machine": info, "rows": rows}, indent=2) + "\n")
    print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
