"""Size of the HTML file and time of ``crashstudy report`` for 10^3, 10^4 and 10^5 variants.

The study is the 2-spring chain of ``small_models.py`` (histories none), run once per size; then
``crashstudy report DIR -o ...`` runs in a subprocess, timed (wall and the child's CPU time). The load average
is recorded beside the figures (the machine is shared).

Run: ``python benchmarks/report_size.py [--variants 1000 10000 100000] [--work DIR]``.
Writes ``benchmarks/results/report_size.{csv,md}``.
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from common import RESULTS, load, machine, machine_md, md_table, write_csv  # noqa: E402
from small_models import model_yaml, study_yaml  # noqa: E402


def child_cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--variants", type=int, nargs="+", default=[1000, 10_000, 100_000])
    ap.add_argument("--work", type=Path, default=Path("/tmp/crashstudy-report-size"))
    args = ap.parse_args()
    start = load()
    args.work.mkdir(parents=True, exist_ok=True)
    model = args.work / "chain-2.yaml"
    model.write_text(model_yaml(2, 0.075))
    rows = []
    for n in args.variants:
        study = args.work / f"study-{n}.yaml"
        study.write_text(study_yaml(2, n, model))
        out = args.work / f"res-{n}"
        subprocess.run(
            [
                sys.executable,
                "-m",
                "crashstudy.cli",
                "run",
                str(study),
                "-o",
                str(out),
                "--force",
                "--progress",
                "off",
            ],
            check=True,
            capture_output=True,
        )
        html = args.work / f"report-{n}.html"
        html.unlink(missing_ok=True)
        cpu0, t0 = child_cpu(), time.perf_counter()
        subprocess.run(
            [sys.executable, "-m", "crashstudy.cli", "report", str(out), "-o", str(html)],
            check=True,
            capture_output=True,
        )
        wall, cpu = time.perf_counter() - t0, child_cpu() - cpu0
        rows.append(
            {
                "variants": n,
                "html_MiB": round(html.stat().st_size / 2**20, 2),
                "report_wall_s": round(wall, 1),
                "report_cpu_s": round(cpu, 1),
                "load_avg_1min": os.getloadavg()[0],
            }
        )
        print(rows[-1], flush=True)
    info = machine(start)
    write_csv(RESULTS / "report_size.csv", rows, info)
    (RESULTS / "report_size.md").write_text(
        "# crashstudy report: file size and time\n\n2-spring chain (benchmarks/small_models.py), histories none; "
        "the report samples the scatter figures above 2000 ok variants and the table above 10^4 variants.\n\n"
        + md_table(rows)
        + "\n\n"
        + machine_md(info)
        + "\n"
    )


if __name__ == "__main__":
    main()
