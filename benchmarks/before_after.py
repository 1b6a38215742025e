"""Two checkouts of crashstudy side by side in one run: cold compile time and throughput of the
generic and generated kernels (the laws refactor, issue 10: speed must not drop).

For each checkout (``--before`` and ``--after``, each a folder holding ``src/crashstudy``):

- cold compile: a fresh process with an empty ``NUMBA_CACHE_DIR`` and an empty private kernel
  folder (``CRASHSTUDY_KERNEL_CACHE``) runs the frontal model (4 variants, 1.2 ms) once with the
  generic kernel, then once with the generated one; the wall time of each first call is the compile
  (plus a negligible run);
- throughput: that checkout's ``benchmarks/throughput.py`` (``--sizes``, ``--threads``, ``--repeats``)
  in a fresh process, with the caches of the cold-compile step (so compile is excluded).

The checkouts run alternately (before, after, before, after for ``--rounds 2``) so that a change of
machine load hits both. Writes ``benchmarks/results/before_after.{csv,md}``.

Run: ``python benchmarks/before_after.py --before /tmp/main-before --after . [--sizes 100 10000]``.
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))

from common import RESULTS, load, machine, machine_md, md_table, median, write_csv  # noqa: E402

COLD = r"""
import json, sys, time
sys.path.insert(0, sys.argv[1] + "/benchmarks")
from throughput import chunks, frontal_plan
from crashstudy.kernel.compiled import run_compiled
from crashstudy.kernel.generated import run_generated
plan = frontal_plan(4, 0.0012, "none")
b = chunks(plan)[0]
out = {}
for name, fn in (("generic", run_compiled), ("generated", run_generated)):
    t0 = time.perf_counter()
    fn(b, plan.topology.histories, plan.n_out)
    out[name] = time.perf_counter() - t0
print(json.dumps(out))
"""


def _env(tree: Path, cache: Path) -> dict[str, str]:
    env = dict(os.environ)
    env["PYTHONPATH"] = str(tree / "src")
    env["NUMBA_CACHE_DIR"] = str(cache / "numba")
    env["CRASHSTUDY_KERNEL_CACHE"] = str(cache / "kernels")
    return env


def cold_compile(tree: Path, cache: Path) -> dict[str, float]:
    """Seconds of the first generic and generated calls in a fresh process with empty caches."""
    out = subprocess.run(
        [sys.executable, "-c", COLD, str(tree)],
        env=_env(tree, cache),
        check=True,
        capture_output=True,
        text=True,
    ).stdout
    return {k: float(v) for k, v in json.loads(out.strip().splitlines()[-1]).items()}


def throughput(tree: Path, cache: Path, args: argparse.Namespace) -> list[dict[str, Any]]:
    with tempfile.TemporaryDirectory() as out:
        cmd = [
            sys.executable,
            str(tree / "benchmarks" / "throughput.py"),
            "--out",
            out,
            "--repeats",
            str(args.repeats),
            "--sizes",
            *map(str, args.sizes),
            "--threads",
            *map(str, args.threads),
        ]
        subprocess.run(cmd, env=_env(tree, cache), check=True, capture_output=True, text=True)
        with open(Path(out) / "throughput.csv") as f:
            return [r for r in csv.DictReader(line for line in f if not line.startswith("#"))]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--before", type=Path, required=True)
    ap.add_argument("--after", type=Path, required=True)
    ap.add_argument("--sizes", type=int, nargs="+", default=[100, 10_000])
    ap.add_argument("--threads", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--rounds", type=int, default=1)
    ap.add_argument("--out", type=Path, default=RESULTS)
    args = ap.parse_args(argv)
    start_load = load()
    t_start = time.perf_counter()
    trees = {"before": args.before.resolve(), "after": args.after.resolve()}
    cold: dict[str, dict[str, list[float]]] = {k: {"generic": [], "generated": []} for k in trees}
    tput: dict[tuple[str, str], dict[str, list[float]]] = {}
    for rnd in range(args.rounds):
        for name, tree in trees.items():
            with tempfile.TemporaryDirectory() as cache:
                c = cold_compile(tree, Path(cache))
                for k, v in c.items():
                    cold[name][k].append(v)
                print(f"round {rnd} {name}: cold compile {c}", flush=True)
                for r in throughput(tree, Path(cache), args):
                    key = (f"{r['variants']} {r['histories']} curve={r['curve_axis']}", r["threads"])
                    d = tput.setdefault(key, {})
                    for k in ("generic_es_per_s", "generated_es_per_s", "specialised_es_per_s"):
                        d.setdefault(f"{name}_{k}", []).append(float(r[k]))
                print(
                    f"round {rnd} {name}: throughput done ({time.perf_counter() - t_start:.0f} s)", flush=True
                )
    rows: list[dict[str, Any]] = []
    for kern in ("generic", "generated"):
        b, a = median(cold["before"][kern]), median(cold["after"][kern])
        rows.append(
            {
                "what": f"cold compile {kern} [s]",
                "threads": "",
                "before": b,
                "after": a,
                "after/before": a / b,
            }
        )
    for (case, th), d in tput.items():
        for kern in ("generic", "generated", "specialised"):
            b = median(d[f"before_{kern}_es_per_s"])
            a = median(d[f"after_{kern}_es_per_s"])
            rows.append(
                {
                    "what": f"{case} {kern} [element-steps/s]",
                    "threads": th,
                    "before": b,
                    "after": a,
                    "after/before": a / b,
                }
            )
    args.out.mkdir(parents=True, exist_ok=True)
    info = machine(start_load)
    write_csv(args.out / "before_after.csv", rows, info)
    text = (
        "# Before / after: cold compile and throughput (frontal-9mass)\n\n"
        + machine_md(info)
        + f"- before: {trees['before']}\n- after: {trees['after']}\n"
        + f"- total script time: {time.perf_counter() - t_start:.0f} s\n\n"
        + "Cold compile: first call in a fresh process with empty numba and kernel caches (4 variants). "
        "Throughput: each checkout's benchmarks/throughput.py (median of its repeats; `specialised` is the "
        "hand-written loop, unchanged, a gauge of machine load). `after/before` > 1: after is slower to "
        "compile / faster to run.\n\n" + md_table(rows)
    )
    (args.out / "before_after.md").write_text(text)
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
