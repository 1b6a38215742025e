"""Where ``crashstudy run STUDY`` spends what matrix.py's in-process cell does not (issue 25: the CLI vs
in-process gap of the 10^6 x 86-step curve-scale study, 7 s against 3.7 s on a quiet machine).

Each repeat runs the command line in a fresh process, as the console script does (``main()`` without
arguments, so the process ends as a user's does), with process-CPU marks around the phases matrix.py
leaves out: the interpreter start and the imports (the runner's modules and numba, which matrix.py imports
before its clock starts), the pre-run checks (``check_plan``), ``run_plan`` (what matrix.py times as its
end to end), the after-run checks (``_after_run``), and the process's end after ``main`` returned (the
parent's ``RUSAGE_CHILDREN`` less the CPU at the last mark). CPU seconds (all threads), because the
machine is shared; wall seconds beside them. ``PYTHONPATH`` picks the code measured (run once per tree).

Run: ``python benchmarks/cli_gap.py STUDY [--repeats 2] [--label NAME]``; prints a Markdown table.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import time

CHILD = r"""
import json, resource, sys, time
def cpu():
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime
marks = {"start": (cpu(), time.time())}
import numba  # noqa: F401  (matrix.py imports it, through kernel.compiled, before its clock starts)
import crashstudy.run.runner, crashstudy.study.sanity  # noqa: F401
from crashstudy.cli import main as M
marks["imports"] = (cpu(), time.time())
spans = {}
def timed(owner, name, label):
    real = getattr(owner, name)
    def f(*a, **k):
        c, w = cpu(), time.time()
        try:
            return real(*a, **k)
        finally:
            s = spans.setdefault(label, [0.0, 0.0])
            s[0] += cpu() - c
            s[1] += time.time() - w
    setattr(owner, name, f)
timed(M, "_checked", "pre-run checks (check_plan)")
timed(crashstudy.run.runner, "run_plan", "run_plan (matrix.py's end to end)")
timed(M, "_after_run", "after-run checks")
import atexit
def last():
    c, w = cpu(), time.time()
    print("@@" + json.dumps({"marks": marks, "spans": spans, "main_end": (c, w)}), file=sys.stderr, flush=True)
atexit.register(last)
sys.argv = ["crashstudy", "run", sys.argv[1], "-o", sys.argv[2], "--force"]
rc = M.main()
last()
sys.exit(rc)
"""


def one(study: str, out: str) -> dict[str, float]:
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.time()
    p = subprocess.run([sys.executable, "-c", CHILD, study, out], capture_output=True, text=True)
    t1 = time.time()
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    assert p.returncode == 0, p.stderr[-2000:]
    d = json.loads([x for x in p.stderr.splitlines() if x.startswith("@@")][0][2:])
    total = after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime
    c_imp, w_imp = d["marks"]["imports"]
    c_end, w_end = d["main_end"]
    row = {"start + imports": (c_imp, w_imp - t0)}
    inside = 0.0
    for k, (c, w) in d["spans"].items():
        row[k] = (c, w)
        inside += c
    row["rest of main (parse, load_study, print)"] = (c_end - c_imp - inside, float("nan"))
    row["after main returned (process end)"] = (total - c_end, t1 - w_end)
    row["total (process)"] = (total, t1 - t0)
    return {k: v for k, v in row.items()}  # type: ignore[misc]


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("study")
    ap.add_argument("--repeats", type=int, default=2)
    ap.add_argument("--label", default=os.environ.get("PYTHONPATH", "installed"))
    ap.add_argument("--out", default="cli_gap_out")
    args = ap.parse_args()
    rows = [one(args.study, args.out) for _ in range(args.repeats)]
    print(f"\n{args.label}: load average {os.getloadavg()[0]:.2f} at the end; cpu_s / wall_s per repeat\n")
    print("| phase | " + " | ".join(f"run {i + 1} cpu_s / wall_s" for i in range(len(rows))) + " |")
    print("|---|" + "---|" * len(rows))
    for k in rows[0]:
        print(f"| {k} | " + " | ".join(f"{r[k][0]:.2f} / {r[k][1]:.2f}" for r in rows) + " |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
