"""Issue 19, the reading side: peak RSS and time of the commands that read a large result folder.

Each reader runs as its own process under ``/usr/bin/time -v`` (peak RSS = its maximum resident set size;
CPU = user + system seconds, the figure to compare on a shared machine; wall as measured):

- ``crashstudy summary DIR --exceed peak_force.s2 4000`` (counts per block)
- ``crashstudy sensitivity DIR --metric peak_force.s2`` (``--method correlation``; writes DIR/sensitivity.csv)
- ``crashstudy compare DIR DIR`` (the result against itself: the same order, read block by block)
- ``open_results(DIR).summary`` (refused beyond ``summary_limit`` rows: the message is recorded)
- ``open_results(DIR).summary_batches(["peak_force.s2"])``: the largest value, block by block
- ``crashstudy plot DIR --kind matrix -o PLOTS``: beyond ``--max-points`` (10^6) a density matrix counted
  block by block (the PNG goes to ``--plots``, default a folder in TMPDIR: never into DIR)

Usage::

    python benchmarks/readers.py DIR [DIR ...] [--src SRC] [--label TEXT] [--only NAMES] [--append TITLE]

``--src`` runs the readers of another source tree (e.g. an extracted ``git archive`` of the commit before,
for a before/after pair); ``--append TITLE`` adds the table to benchmarks/results/scale.md as a section.
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import pyarrow.parquet as pq

sys.path.insert(0, str(Path(__file__).resolve().parent))

from common import RESULTS, load, md_table  # noqa: E402

REPORT = RESULTS / "scale.md"
WHOLE = (
    "import sys\nfrom crashstudy.errors import InputError\nfrom crashstudy.results.reader import open_results\n"
    "res = open_results(sys.argv[1])\ntry:\n    print(len(res.summary), 'rows read whole')\n"
    "except InputError as exc:\n    print('refused:', exc.problems[0].message)\n"
)
BOUNDED = (
    "import sys\nfrom crashstudy.results.reader import open_results\nres = open_results(sys.argv[1])\n"
    "best, n = float('-inf'), 0\nfor b in res.summary_batches(['peak_force.s2']):\n"
    "    best, n = max(best, float(b['peak_force.s2'].max())), n + len(b)\nprint(n, 'rows, largest', best)\n"
)


def readers(folder: Path, plots: Path) -> dict[str, list[str]]:
    cli = [sys.executable, "-m", "crashstudy.cli"]
    return {
        "summary --exceed": [*cli, "summary", str(folder), "--exceed", "peak_force.s2", "4000"],
        "sensitivity (correlation)": [*cli, "sensitivity", str(folder), "--metric", "peak_force.s2"],
        "compare DIR DIR": [*cli, "compare", str(folder), str(folder)],
        "open_results().summary": [sys.executable, "-c", WHOLE, str(folder)],
        "summary_batches (bounded)": [sys.executable, "-c", BOUNDED, str(folder)],
        "plot --kind matrix": [*cli, "plot", str(folder), "--kind", "matrix", "-o", str(plots)],
    }


def timed(cmd: list[str], env: dict[str, str]) -> dict[str, Any]:
    """Run ``cmd`` under /usr/bin/time -v: exit code, wall, CPU, peak RSS, the last line of its output."""
    t0 = time.perf_counter()
    p = subprocess.run(["/usr/bin/time", "-v", *cmd], capture_output=True, text=True, env=env)
    wall = time.perf_counter() - t0

    def field(name: str) -> float:
        m = re.search(rf"{re.escape(name)}: ([0-9.]+)", p.stderr)
        return float(m.group(1)) if m else float("nan")

    said = [ln for ln in (p.stdout.strip().splitlines() or [""]) if ln.strip()]
    return {
        "exit": p.returncode,
        "wall": wall,
        "cpu": field("User time (seconds)") + field("System time (seconds)"),
        "rss": field("Maximum resident set size (kbytes)") * 1024,
        "said": (said[-1] if said else "")[:160],
        "stderr": p.stderr[:400] if p.returncode not in (0, 1) else "",
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("dirs", nargs="+", type=Path)
    ap.add_argument(
        "--src", type=Path, help="source tree whose crashstudy runs the readers (default: installed)"
    )
    ap.add_argument("--plots", type=Path, help="folder for plot's PNG (default: a new folder in TMPDIR)")
    ap.add_argument("--label", default="", help="a name of the code measured (e.g. a commit)")
    ap.add_argument("--only", default="", help="comma list of readers to run (default all)")
    ap.add_argument(
        "--append", default="", metavar="TITLE", help="add the table to the report as a section TITLE"
    )
    args = ap.parse_args(argv)
    env = dict(os.environ)
    if args.src:
        env["PYTHONPATH"] = str(args.src)
    rows = []
    for folder in args.dirs:
        size = pq.ParquetFile(folder / "summary.parquet").metadata.num_rows
        plots = args.plots or Path(tempfile.mkdtemp(prefix="crashstudy-readers-plots-"))
        for name, cmd in readers(folder, plots).items():
            if args.only and name not in args.only.split(","):
                continue
            r = timed(cmd, env)
            rows.append(
                {
                    "variants": size,
                    "reader": name,
                    "code": args.label or "-",
                    "peak RSS [MiB]": round(r["rss"] / 2**20),
                    "CPU [s]": round(r["cpu"], 1),
                    "wall [s]": round(r["wall"], 1),
                    "exit": r["exit"],
                    "prints (last line)": r["said"].replace("|", "/"),
                    "load": load(),
                }
            )
            print(rows[-1], r["stderr"], flush=True)
    table = md_table(rows)
    print(table)
    if args.append:
        with open(REPORT, "a") as fh:
            fh.write(f"\n## {args.append}\n\n{table}\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
