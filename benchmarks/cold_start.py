"""Cold start: what a user waits for on a fresh machine, and on the repeat.

Every case starts from EMPTY caches: a fresh ``HOME``, ``NUMBA_CACHE_DIR`` and
``CRASHSTUDY_KERNEL_CACHE`` in a temporary folder, so nothing compiled before is found. Each case
is run three ways, one after another, each on its own empty caches:

- ``choice``: the default (kernel choice by expected time: the NumPy reference while a kernel compiles
  in the background, or a kernel compiled first when that is quicker);
- ``generic``: ``CRASHSTUDY_KERNEL=generic``, what every run did before kernel choice (compile the
  generic kernel first, then run it);
- ``repeat``: the ``choice`` run again on the caches its first run left, after its background
  compile finished (what the next run of the same study waits).

Cases: ``crashstudy simulate`` of the one-spring example; the README's first command's run
(``studies/subfloor-small.yaml``, 12 variants); a 10^4-variant frontal study (engine mass x impact
velocity, 100 x 100, histories none); the same study of the frontal model with its occupant and
``metrics:`` (``occupant``: the crash criteria compile too). Wall time of the whole process (start to exit, results
written) with ``perf_counter`` around ``subprocess.run``; the background compile is not waited for
by the ``choice`` run (it is detached), but it shares the 2 cores with it.

Run: ``python benchmarks/cold_start.py [--cases simulate readme frontal occupant]``.
Writes ``benchmarks/results/cold_start.{csv,md}``.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))

from common import FRONTAL, MODELS, RESULTS, ROOT, load, machine, machine_md, md_table, write_csv  # noqa: E402

FRONTAL_STUDY = f"""name: frontal-1e4
model: {FRONTAL}
matrix:
  nodes.engine.mass: {[round(150.0 + 2.0 * k, 3) for k in range(100)]}
  impact_velocity: {[round(10.0 + 0.1 * k, 3) for k in range(100)]}
set: {{output: {{histories: none}}}}
"""


def cases(tmp: Path) -> dict[str, list[str]]:
    study = tmp / "frontal-1e4.yaml"
    study.write_text(FRONTAL_STUDY)
    occupant = tmp / "frontal-occupant-1e4.yaml"
    occupant.write_text(FRONTAL_STUDY.replace(str(FRONTAL), str(MODELS / "frontal-occupant.yaml")))
    cli = [sys.executable, "-m", "crashstudy.cli"]
    return {
        "simulate": [*cli, "simulate", str(MODELS / "linear-spring.yaml"), "-o", "{out}"],
        "readme": [*cli, "run", str(ROOT / "studies/subfloor-small.yaml"), "-o", "{out}", "--force"],
        "frontal": [*cli, "run", str(study), "-o", "{out}", "--force"],
        "occupant": [*cli, "run", str(occupant), "-o", "{out}", "--force"],
    }


def wait_compiles(kernels: Path, limit: float = 900.0) -> float:
    """Wait until no background compile holds the cache's lock; seconds waited."""
    from crashstudy.kernel.choice import compiling

    t0 = time.perf_counter()
    time.sleep(1.0)  # a detached compile may take a moment to take the lock
    while compiling(kernels) and time.perf_counter() - t0 < limit:
        time.sleep(1.0)
    return time.perf_counter() - t0


def run_case(name: str, cmd: list[str], tmp: Path) -> list[dict[str, Any]]:
    rows = []
    for mode in ("choice", "generic"):
        home = tmp / f"{name}-{mode}"
        env = dict(
            os.environ,
            HOME=str(home / "home"),
            NUMBA_CACHE_DIR=str(home / "numba"),
            CRASHSTUDY_KERNEL_CACHE=str(home / "kernels"),
        )
        env.pop("CRASHSTUDY_BACKGROUND_COMPILE", None)
        env.pop("CRASHSTUDY_KERNEL", None)
        if mode == "generic":
            env["CRASHSTUDY_KERNEL"] = "generic"
        runs = [mode] + (["repeat"] if mode == "choice" else [])
        for k, label in enumerate(runs):
            waited = wait_compiles(home / "kernels") if label == "repeat" else 0.0
            argv = [a.replace("{out}", str(home / f"out{k}")) for a in cmd]
            t0 = time.perf_counter()
            p = subprocess.run(argv, env=env, capture_output=True, text=True)
            wall = time.perf_counter() - t0
            note = next((ln for ln in p.stderr.splitlines() if ln.startswith("note:")), "")
            rows.append(
                {
                    "case": name,
                    "run": label,
                    "wall_s": wall,
                    "exit": p.returncode,
                    "waited_for_background_s": waited,
                    "load": load(),
                    "note": note[:160],
                }
            )
            print(f"{name} {label}: {wall:.2f} s exit {p.returncode} {note[:100]}", flush=True)
            if p.returncode not in (0, 1):
                print(p.stderr[-2000:], file=sys.stderr)
        wait_compiles(home / "kernels")  # a detached compile must not run into the next case
    return rows


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cases", nargs="+", default=["simulate", "readme", "frontal", "occupant"])
    ap.add_argument("--out", type=Path, default=RESULTS)
    args = ap.parse_args(argv)
    start_load = load()
    t_start = time.perf_counter()
    rows: list[dict[str, Any]] = []
    with tempfile.TemporaryDirectory(prefix="cold-start-") as tmp:
        all_cases = cases(Path(tmp))
        for name in args.cases:
            rows += run_case(name, all_cases[name], Path(tmp))
    info = machine(start_load)
    write_csv(args.out / "cold_start.csv", rows, info)
    text = (
        "# Cold start (empty caches) and repeat\n\n"
        + machine_md(info)
        + f"- total script time: {time.perf_counter() - t_start:.0f} s\n\n"
        + __doc__.split("\n\n", 1)[1]
        + "\n"
        + md_table(rows, ["case", "run", "wall_s", "exit", "waited_for_background_s", "load", "note"])
    )
    (args.out / "cold_start.md").write_text(text)
    print(f"wrote {args.out / 'cold_start.md'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
