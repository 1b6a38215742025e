"""Why ``frontal_specialised``'s peak forces agree with crashstudy's only to ~1e-4 (the matrix's frontal
``check``, issue 25 item 4): per spring, the hand loop against crashstudy (NumPy reference kernel, bitwise the
compiled ones), and crashstudy against itself with every mass x (1 + 1e-15) (how far rounding alone moves a
peak in this model).

32 variants (engine mass 120-210 kg x bumper mass 10-30 kg), 0.12 s, crashstudy's steps. Run:
``python benchmarks/frontal_check.py``; prints the table (results: ``benchmarks/results/frontal_check.md``).
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from common import FRONTAL  # noqa: E402


def main() -> int:
    import frontal_specialised as fs
    from crashstudy.arrays.batch import build_batch
    from crashstudy.kernel.entry import run_batch
    from crashstudy.study.plan import load_study

    with tempfile.TemporaryDirectory() as tmp:
        st = Path(tmp) / "study.yaml"
        st.write_text(
            f"name: fc\nmodel: {FRONTAL}\nmatrix:\n  nodes.engine.mass: {np.linspace(120.0, 210.0, 8).round(6).tolist()}\n"
            f"  nodes.bumper.mass: {np.linspace(10.0, 30.0, 4).round(6).tolist()}\n"
        )
        plan = load_study(st)
    b, _ = build_batch(plan.topology, plan.params(0, plan.n_variants), plan.interval)
    ours = run_batch(b, (), 1, "reference").peak_force
    fs.set_threads(1)
    loop = fs.run_specialised(b, (), 1).peak_force
    b2, _ = build_batch(plan.topology, plan.params(0, plan.n_variants), plan.interval)
    b2.mass[:] = b2.mass * (1 + 1e-15)
    b2.inv_mass[:] = np.where(
        b2.inv_mass > 0, 1.0 / np.where(b2.mass[:, None, :] > 0, b2.mass[:, None, :], 1.0), 0.0
    )
    pert = run_batch(b2, (), 1, "reference").peak_force
    knots = {
        int(b.curve_a[s])
        for s in range(len(b.spring_i))
        if b.curve_a[s] >= 0
        and np.any(b.knot_check[b.curve_off[b.curve_a[s]] : b.curve_off[b.curve_a[s] + 1]])
    }
    print(
        "| spring | loop vs crashstudy | crashstudy vs itself, masses x (1 + 1e-15) | its loading curve has a knot peak "
        "(peak_force counts knots passed between steps) |\n|---|---|---|---|"
    )
    for s, sid in enumerate(plan.topology.spring_ids):
        rel = np.max(np.abs(loop[s] - ours[s]) / np.abs(ours[s]))
        relp = np.max(np.abs(pert[s] - ours[s]) / np.abs(ours[s]))
        print(f"| {sid} | {rel:.2e} | {relp:.2e} | {'yes' if int(b.curve_a[s]) in knots else 'no'} |")
    s = plan.topology.spring_ids.index("rear-rail")
    print(
        f"\nrear-rail: crashstudy's peak is {np.unique(ours[s])} in every variant (the knot at x = -0.01 m); the loop's "
        f"{loop[s].min():.9e} .. {loop[s].max():.9e} (the largest force at a step)"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
