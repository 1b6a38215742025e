"""Time and memory of :func:`crashstudy.analysis.iso18571.rate` for V = 10^4 variants x n = 2000 samples
(0.2 s at 10 kHz): crash pulses with random shift, scale and noise against one test pulse.

Prints and writes ``benchmarks/results/iso18571_rate.json``: wall and process CPU time of a warm call
(compiled code loaded by a first small call), the peak resident memory of the process, and the load
average before and after. Run: ``python benchmarks/iso18571_rate.py [--variants 10000 --samples 2000]``.
"""

from __future__ import annotations

import argparse
import json
import resource
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from common import RESULTS, load, machine  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--variants", type=int, default=10_000)
    ap.add_argument("--samples", type=int, default=2000)
    a = ap.parse_args()
    start = load()
    from crashstudy.analysis.iso18571 import rate

    rng = np.random.default_rng(0)
    t = np.arange(a.samples) * 1e-4
    span = t[-1]

    def pulse(shift: np.ndarray, scale: np.ndarray) -> np.ndarray:
        u = (t[None, :] - shift[:, None]) / (0.6 * span)
        return scale[:, None] * np.where((u > 0) & (u < 1), np.sin(np.pi * np.clip(u, 0, 1)) ** 2, 0.0)

    test = pulse(np.array([0.05 * span]), np.array([300.0]))[0]
    models = pulse(rng.uniform(0, 0.1 * span, a.variants), rng.uniform(250, 350, a.variants))
    models += rng.normal(0, 3.0, models.shape)
    rate(test, models[:4])  # compiled code loaded (or compiled)
    w0, c0 = time.perf_counter(), time.process_time()
    out = rate(test, models)
    wall, cpu = time.perf_counter() - w0, time.process_time() - c0
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024  # MiB (Linux: KiB)
    row = {
        "variants": a.variants,
        "samples": a.samples,
        "wall_s": round(wall, 2),
        "cpu_s": round(cpu, 2),
        "peak_rss_mib": round(peak, 1),
        "input_mib": round(models.nbytes / 2**20, 1),
        "median_R": float(np.median(out["R"])),
        "load_after": load(),
        **machine(start),
    }
    print(json.dumps(row, indent=1))
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "iso18571_rate.json").write_text(json.dumps(row, indent=1) + "\n")


if __name__ == "__main__":
    main()
