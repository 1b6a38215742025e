"""Accuracy of the crash criteria from the block-mean record (docs/criteria.md, "Record rate").

For the example models with a ``metrics:`` block (frontal-occupant: 7 crash-box scales x 3 speeds;
helicopter-seat: drop speeds 6, 7 and 8.2 m/s) the criteria are computed three ways:

- ``default``: the default step and the record rate crashstudy chooses (``metrics.record_blocks``);
- ``every step``: the default step, every step recorded (k = 1);
- ``converged``: the step halved (``time_step.tolerance`` / 4), every step recorded.

and the largest relative difference over the variants of ``default`` and ``every step`` from
``converged`` is reported per criterion (relative to the largest |value| of the criterion over the
study for the HIC window ends, which are times). ``--rate``/``--per-cfc`` try another record-rate rule.

Run: ``python benchmarks/criteria_accuracy.py``; prints a Markdown table.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
MODELS = ROOT / "studies" / "models"
STUDIES = {
    "frontal-occupant": (
        "matrix:\n  curves.crash-box-loading.scale: [0.6, 0.8, 1.0, 1.2, 1.4, 1.6, 1.8]\n"
        "  impact_velocity: [13.889, 15.556, 17.778]\n"
    ),
    "helicopter-seat": "matrix:\n  impact_velocity: [6.0, 7.0, 8.2]\n",  # 9 m/s and up: the seat bottoms
}


def criteria(model: str, tol: float | None, every_step: bool, tmp: Path) -> dict[str, np.ndarray]:
    """Criteria (name.node -> (V,)) of the example study of ``model``."""
    from crashstudy.metrics import record as metrics
    from crashstudy.run.runner import run_chunk
    from crashstudy.study.plan import load_study

    d = tmp / f"{model}-{tol}-{every_step}"
    d.mkdir()
    (d / "m.yaml").write_text((MODELS / f"{model}.yaml").read_text())
    extra = f"set:\n  time_step: {{tolerance: {tol}}}\n" if tol else ""
    (d / "s.yaml").write_text(f"name: acc\nmodel: m.yaml\n{STUDIES[model]}{extra}")
    plan = load_study(d / "s.yaml")
    saved = metrics.RECORD_RATE, metrics.RECORD_PER_CFC
    if every_step:
        metrics.RECORD_RATE, metrics.RECORD_PER_CFC = np.inf, np.inf
    try:
        res = run_chunk(plan, 0, plan.n_variants)
    finally:
        metrics.RECORD_RATE, metrics.RECORD_PER_CFC = saved
    topo = plan.topology
    out = {}
    for name, arr in res.criteria.values.items():
        for n in range(topo.n_nodes):
            if np.all(np.isfinite(arr[:, n])):
                out[f"{name}.{topo.node_ids[n]}"] = arr[:, n]
    return out


def compare(model: str, tmp: Path) -> list[tuple[str, float, float, float]]:
    """(criterion, max rel. difference of default, of every step from the converged values, of default
    from every step)."""
    tol = 1.0e-3  # the default tolerance (the example models do not set time_step)
    conv = criteria(model, tol / 4.0, True, tmp)
    dflt = criteria(model, None, False, tmp)
    every = criteria(model, None, True, tmp)
    rows = []
    for name, truth in conv.items():
        scale = np.max(np.abs(truth)) if name.split(".")[0].endswith(("_t1", "_t2")) else np.abs(truth)
        scale = np.where(scale > 0, scale, 1.0)
        rows.append(
            (
                name,
                float(np.max(np.abs(dflt[name] - truth) / scale)),
                float(np.max(np.abs(every[name] - truth) / scale)),
                float(np.max(np.abs(dflt[name] - every[name]) / scale)),
            )
        )
    return rows


def main(argv: list[str] | None = None) -> int:
    from crashstudy.metrics import record as metrics

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rate", type=float, default=metrics.RECORD_RATE)
    ap.add_argument("--per-cfc", type=float, default=metrics.RECORD_PER_CFC)
    args = ap.parse_args(argv)
    metrics.RECORD_RATE, metrics.RECORD_PER_CFC = args.rate, args.per_cfc
    print(f"record rate >= max({args.rate:g} Hz, {args.per_cfc:g} x CFC)\n")
    print(
        "| model | criterion | default vs converged | every step vs converged | default vs every step |\n"
        "|---|---|---|---|---|"
    )
    with tempfile.TemporaryDirectory() as t:
        for model in STUDIES:
            for name, e_d, e_e, e_k in compare(model, Path(t)):
                print(f"| {model} | `{name}` | {100 * e_d:.3f} % | {100 * e_e:.3f} % | {100 * e_k:.4f} % |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
