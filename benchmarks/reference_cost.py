"""The NumPy reference kernel's cost per time step, against the kernel choice's model of it.

``crashstudy.kernel.choice.reference_seconds`` decides whether a chunk runs on the reference or waits for a
compiled kernel (``REF_STEP`` per step, ``REF_SPRING_STEP`` per step and spring, ``REF_ELEMENT_STEP`` per
element-step). Its calibration points, measured here in one process (CPU seconds of the reference alone, the
median of 5 runs, the batch built before timing): one linear spring, one variant (4000 steps); the
frontal model (8 springs), one variant; the frontal model, 1000 variants (engine mass x impact speed).

Run: ``python benchmarks/reference_cost.py``. Writes ``benchmarks/results/reference_cost.md``.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from common import RESULTS, load, machine, machine_md, md_table, median  # noqa: E402
from crashstudy.arrays.batch import build_batch  # noqa: E402
from crashstudy.kernel import choice  # noqa: E402
from crashstudy.kernel.reference import run_reference  # noqa: E402
from crashstudy.study.plan import load_study  # noqa: E402
from throughput import frontal_plan  # noqa: E402

SPRING = """name: one-spring
nodes:
  a: {position: [0.0], fixed: true}
  b: {position: [0.1], mass: 1.0}
springs:
  s: {nodes: [a, b], material: {type: linear_elastic, stiffness: 100.0}}
initial_velocity: {b: [-1.0]}
end_time: 4.0
time_step: {dt: 1.0e-3}
output: {histories: none}
"""


def _case(name: str, plan: Any, steps_cap: int | None = None) -> dict[str, Any]:
    b, _ = build_batch(plan.topology, plan.params(0, plan.n_variants), plan.interval)
    S = len(b.spring_i)
    cpu = []
    for _ in range(5):
        t = time.process_time()
        run_reference(b, plan.topology.histories, plan.n_out)
        cpu.append(time.process_time() - t)
    steps = float(np.max(b.n_steps))
    per_step = median(cpu) / steps
    model = choice.reference_seconds(1.0, S, float(np.sum(b.n_steps)) * S / steps)
    return {
        "case": name,
        "variants": int(b.x0.shape[2]),
        "springs": S,
        "steps": int(steps),
        "cpu_s_median": round(median(cpu), 3),
        "us_per_step": round(per_step * 1e6, 1),
        "model_us_per_step": round(model * 1e6, 1),
        "measured_over_model": round(per_step / model, 2),
    }


def main() -> int:
    start = load()
    rows = []
    with __import__("tempfile").TemporaryDirectory() as tmp:
        spring = Path(tmp) / "spring.yaml"
        spring.write_text(SPRING)
        study = Path(tmp) / "study.yaml"
        study.write_text(f"name: one\nmodel: {spring}\nmatrix:\n  impact_velocity: [1.0]\n")
        rows.append(_case("one linear spring, 1 variant", load_study(study)))
    rows.append(_case("frontal (8 springs), 1 variant", frontal_plan(1, 0.02, "none")))
    rows.append(_case("frontal (8 springs), 1000 variants", frontal_plan(1000, 0.005, "none")))
    for r in rows:
        print(r, flush=True)
    text = (
        "# The NumPy reference's cost per step against the kernel choice's model\n\n"
        + machine_md(machine(start))
        + "\n"
        + (__doc__ or "").split("\n\n", 1)[1]
        + "\n"
        + md_table(rows)
        + f"\nModel constants: REF_STEP {choice.REF_STEP:g} s, REF_SPRING_STEP {choice.REF_SPRING_STEP:g} s, "
        f"REF_ELEMENT_STEP {choice.REF_ELEMENT_STEP:g} s.\n"
    )
    (RESULTS / "reference_cost.md").write_text(text)
    print(f"wrote {RESULTS / 'reference_cost.md'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
