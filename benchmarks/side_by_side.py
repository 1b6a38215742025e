"""Compile CPU time (cold caches) and kernel throughput (CPU time, 1 thread) of the generic and generated
kernels on the frontal model, beside the hand-specialised loop, for one source tree: run it once per tree
(e.g. a ``git archive`` of the base commit and the working tree), back to back, each with empty
``NUMBA_CACHE_DIR`` / ``CRASHSTUDY_KERNEL_CACHE`` folders, and compare the two JSON lines.

Run: ``PYTHONPATH=<tree>/src python benchmarks/side_by_side.py <tree>``. Throughput: frontal model,
10^4 variants (engine mass x impact velocity), end_time 6 ms, no histories, median of 3, element-steps
per CPU second (``benchmarks/throughput.py``'s plan and chunks). Prints the load average at both ends.
"""

from __future__ import annotations

import json
import os
import sys
import time

import numpy as np


def main(root: str) -> dict[str, object]:
    sys.path.insert(0, root + "/src")
    sys.path.insert(0, root + "/benchmarks")
    import throughput as tp
    from crashstudy.kernel.compiled import run_compiled
    from crashstudy.kernel.driver import set_threads
    from crashstudy.kernel.generated import run_generated

    set_threads(1)
    out: dict[str, object] = {"root": root, "load_start": os.getloadavg()}
    plan = tp.frontal_plan(4, 0.0012, "none")
    b = tp.chunks(plan)[0]
    for name, fn in (("generic", run_compiled), ("generated", run_generated)):
        c0, t0 = time.process_time(), time.perf_counter()
        fn(b, (), plan.n_out)
        out[f"compile_{name}_cpu_s"] = round(time.process_time() - c0, 1)
        out[f"compile_{name}_wall_s"] = round(time.perf_counter() - t0, 1)
    plan = tp.frontal_plan(10000, 0.006, "none")
    batches = tp.chunks(plan)
    steps = sum(int(np.sum(bb.n_steps)) for bb in batches) * len(plan.topology.spring_ids)
    for name in ("generic", "generated", "specialised"):
        tp.run_all(name, batches[:1], (), plan.n_out)  # warm (the specialised loop compiles here)
        rates = [steps / tp.run_all(name, batches, (), plan.n_out)[1] for _ in range(3)]
        out[f"{name}_elem_steps_per_cpu_s"] = float(np.median(rates))
    out["load_end"] = os.getloadavg()
    return out


if __name__ == "__main__":
    print(json.dumps(main(sys.argv[1])), flush=True)
