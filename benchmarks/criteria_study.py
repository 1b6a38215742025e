"""Cost of the crash criteria in a study (issue 11 item 4: at most 20 % of the study's time).

The frontal model with its occupant (``studies/models/frontal-occupant.yaml``), 10^4 variants: crash-box
scale 0.6 ... 1.8 (100 values) x impact velocity 13.9 ... 17.8 m/s (100 values), ``histories: none``,
run with ``crashstudy run`` in this process (results.nc and summary.csv written) in three forms,
interleaved, after one warm-up run of each (compiled kernels loaded), all on the generated kernel
(``CRASHSTUDY_KERNEL=generated``, ``--kernel``: without it the first runs of a shape may use the NumPy
reference while the generated kernel compiles in the background, which would time the compiler):

- ``no metrics``: the model with its ``metrics:`` block removed;
- ``metrics``: the model as it is (the record at the rate ``crashstudy.metrics.record.record_blocks`` chooses);
- ``metrics, every step``: the same with every step recorded (k = 1, the record before block means).

For each: wall time and process CPU time (all threads), median of ``--repeats`` (3), and the time spent
in :func:`crashstudy.metrics.record.criteria_of` (the filter and the criteria; timed by a wrapper). The criteria's
share of the study is ``(metrics - no metrics) / metrics``.

Run: ``python benchmarks/criteria_study.py [--repeats 3]``. Writes ``benchmarks/results/criteria_study.md``.
"""

from __future__ import annotations

import argparse
import os
import re
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from common import MODELS, RESULTS, load, machine, machine_md, md_table, median  # noqa: E402

MODEL = MODELS / "frontal-occupant.yaml"


def study_text(model: str, n_box: int, n_speed: int) -> str:
    boxes = ", ".join(f"{x:.6g}" for x in np.linspace(0.6, 1.8, n_box))
    speeds = ", ".join(f"{x:.6g}" for x in np.linspace(13.889, 17.778, n_speed))
    return (
        f"name: criteria-study\nmodel: {model}\nmatrix:\n  curves.crash-box-loading.scale: [{boxes}]\n"
        f"  impact_velocity: [{speeds}]\nset:\n  output: {{histories: none}}\n"
    )


def without_metrics(text: str) -> str:
    """The model text with its top-level ``metrics:`` block removed."""
    out = re.sub(r"(?ms)^metrics:.*?(?=^\S|\Z)", "", text)
    assert "metrics:" not in out
    return out


def main(argv: list[str] | None = None) -> int:
    from crashstudy.cli.main import main as cli
    from crashstudy.metrics import record as metrics

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--size", type=int, nargs=2, default=(100, 100), help="crash-box scales x speeds")
    ap.add_argument(
        "--kernel", default="generated", help="CRASHSTUDY_KERNEL for the runs (default generated)"
    )
    ap.add_argument(
        "--rate", type=float, default=metrics.RECORD_RATE, help="try another record rate rule [Hz]"
    )
    ap.add_argument("--per-cfc", type=float, default=metrics.RECORD_PER_CFC)
    args = ap.parse_args(argv)
    os.environ["CRASHSTUDY_KERNEL"] = args.kernel
    start = load()
    spent = [0.0]
    real = metrics.criteria_of

    def timed(*a):  # type: ignore[no-untyped-def]
        t0 = time.perf_counter()
        try:
            return real(*a)
        finally:
            spent[0] += time.perf_counter() - t0

    metrics.criteria_of = timed  # type: ignore[assignment]
    rate = args.rate, args.per_cfc
    with tempfile.TemporaryDirectory() as t:
        tmp = Path(t)
        text = MODEL.read_text()
        (tmp / "with.yaml").write_text(text)
        (tmp / "without.yaml").write_text(without_metrics(text))
        forms = {
            "no metrics": ("without.yaml", rate),
            "metrics": ("with.yaml", rate),
            "metrics, every step": ("with.yaml", (np.inf, np.inf)),
        }
        for name, (model, _) in forms.items():
            (tmp / f"{name}.yaml").write_text(study_text(model, *args.size))
        times: dict[str, list[tuple[float, float, float]]] = {n: [] for n in forms}
        for rep in range(args.repeats + 1):  # the first round warms up
            for name, (_, r) in forms.items():
                metrics.RECORD_RATE, metrics.RECORD_PER_CFC = r
                spent[0] = 0.0
                w0, c0 = time.perf_counter(), time.process_time()
                code = cli(["run", str(tmp / f"{name}.yaml"), "-o", str(tmp / f"out-{rep}-{name}")])
                wall, cpu = time.perf_counter() - w0, time.process_time() - c0
                assert code == 0, name
                if rep:
                    times[name].append((wall, cpu, spent[0]))
                print(
                    f"{name}: wall {wall:.2f} s, cpu {cpu:.2f} s, criteria {spent[0]:.2f} s", file=sys.stderr
                )
        metrics.RECORD_RATE, metrics.RECORD_PER_CFC = rate
    rows = []
    base_wall = median([x[0] for x in times["no metrics"]])
    base_cpu = median([x[1] for x in times["no metrics"]])
    for name, xs in times.items():
        wall, cpu, crit = (median([x[i] for x in xs]) for i in range(3))
        rows.append(
            {
                "study": name,
                "wall [s]": wall,
                "CPU [s]": cpu,
                "in criteria_of [s]": crit,
                "criteria share of wall, (t - t_none) / t": (wall - base_wall) / wall if wall else 0.0,
                "criteria share of CPU": (cpu - base_cpu) / cpu if cpu else 0.0,
                "criteria_of / wall": crit / wall,
            }
        )
    V = args.size[0] * args.size[1]
    md = (
        f"# Crash criteria in a study: frontal-occupant, {V} variants\n\n"
        f"`python benchmarks/criteria_study.py` (median of {args.repeats}, warm, the three studies interleaved;"
        f" histories none; kernel {args.kernel}; record rate >= max({rate[0]:g} Hz, {rate[1]:g} x CFC)).\n\n"
        + md_table(rows)
        + "\n"
        + machine_md(machine(start))
    )
    RESULTS.mkdir(parents=True, exist_ok=True)
    (RESULTS / "criteria_study.md").write_text(md)
    print(md)
    return 0


if __name__ == "__main__":
    sys.exit(main())
