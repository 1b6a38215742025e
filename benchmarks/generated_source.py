"""Emitted source and cold compile of the generated kernel for each model shape of the twin tests.

For each case of ``tests/twins.py`` (CASES, with its per-step record as the twin test runs it), the
generated module's size: characters and lines of code (the module without its ``_SHAPE`` line and its
constant tables ``_T<i>``, which are data) and in total; and the CPU seconds (``time.process_time``) of
its first ``run_generated`` call minus a second call, i.e. its compile: numba's cache holds the laws
(compiled once, before the first case is timed), and the generated module's own cache entries are
deleted before each case, so each case compiles as on a fresh machine that has the laws.

Run with the code to measure on ``PYTHONPATH`` (a base commit's ``src`` and this branch's ``src`` side by
side, under the same load): ``python benchmarks/generated_source.py [--cases NAME ...] [--tests DIR]``.
Prints one line per case (``case | code chars | code lines | total chars | compile CPU s | load``).
"""

from __future__ import annotations

import argparse
import glob
import os
import re
import sys
import tempfile
import time
from pathlib import Path


def code_size(src: str) -> tuple[int, int]:
    """(characters, lines) of a generated module without its data lines (``_SHAPE``, tables ``_T<i>``)."""
    code = [ln for ln in src.splitlines() if not re.match(r"(_SHAPE|_T\d+) = ", ln)]
    return sum(len(ln) + 1 for ln in code), len(code)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cases", nargs="*", default=None, help="twin cases (default: all, one per shape)")
    ap.add_argument("--tests", type=Path, default=Path(__file__).resolve().parent.parent / "tests")
    ap.add_argument("--compile", action=argparse.BooleanOptionalAction, default=True)
    args = ap.parse_args(argv)
    if args.compile and "NUMBA_CACHE_DIR" not in os.environ:  # a private cache (the laws compile once)
        os.environ["NUMBA_CACHE_DIR"] = tempfile.mkdtemp(prefix="gensrc-numba-")
        os.environ["CRASHSTUDY_KERNEL_CACHE"] = tempfile.mkdtemp(prefix="gensrc-kernels-")
    sys.path.insert(0, str(args.tests))
    from crashstudy.kernel.generated import _shape, _source_key, run_generated
    from twins import CASES, record_case

    def compile_cpu(batch: object, plan: object, record: tuple[int, ...], key: str) -> float:
        pattern = os.path.join(os.environ["NUMBA_CACHE_DIR"], "**", f"k_{key}*")
        for f in glob.glob(pattern, recursive=True):
            os.remove(f)
        h = plan.topology.histories  # type: ignore[attr-defined]
        t0 = time.process_time()
        run_generated(batch, h, plan.n_out, record=record)  # type: ignore[arg-type, attr-defined]
        t1 = time.process_time()
        run_generated(batch, h, plan.n_out, record=record)  # type: ignore[arg-type, attr-defined]
        return (t1 - t0) - (time.process_time() - t1)

    seen: set[str] = set()
    first = True
    print("| case | code chars | code lines | total chars | compile CPU s | load 1 min |")
    print("|---|---|---|---|---|---|")
    for case in args.cases or list(CASES):
        batch, plan, record = record_case(case)
        src, key = _source_key(_shape(batch, plan.topology.histories, None, record=record))
        if key in seen:
            continue
        seen.add(key)
        cpu = float("nan")
        if args.compile:
            if first:  # the laws (and numba itself) compile here, untimed: a kernel of another shape
                run_generated(batch, (), plan.n_out)  # type: ignore[attr-defined]
                first = False
            cpu = compile_cpu(batch, plan, record, key)
        chars, lines = code_size(src)
        print(
            f"| {case} | {chars} | {lines} | {len(src)} | {cpu:.1f} | {os.getloadavg()[0]:.1f} |", flush=True
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
