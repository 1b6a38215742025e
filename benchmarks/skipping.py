"""What skipping costs and saves: one feature toggled at a time, same physics (issue 4, item 3).

Every comparison runs its cases side by side in the same process and interleaved (repeat 1 of every
case, then repeat 2, ...; the order rotates each repeat), so load from other users hits all cases
alike. Each case is warmed up (compiled, caches filled) before it is timed; the medians of
``--repeats`` runs (default 5) of CPU time (``time.process_time``, kernel on one thread via
``crashstudy.kernel.compiled.set_threads(1)``) and wall time are reported, with the time per
element-step (one spring advanced one step for one variant: springs x steps actually computed) and
the load average before and after each comparison.

1. histories ``none`` vs ``[spring_force]`` vs ``all`` (frontal model, 2000 variants), with the
   bytes of the history arrays (the kernel's energy buffer included).
2. the frontal model in 1-D vs the same model drawn in 2-D along x (positions [x, 0], velocities
   [v, 0]), once with every node fixed in y and once free in y; peaks must agree to 1e-9. Both are
   drawn twice as long as in the file (see ``cmp_geometry``: as drawn, the crash box passes zero
   length, which 2-D treats differently).
3. a rigid wall that is never reached / a load with zero force vs neither (both cost the fused
   1-D node update); peaks must agree to 1e-12.
4. material state: every curve-driven spring as ``nonlinear_elastic`` vs ``crush`` vs
   ``general_nonlinear`` on the same curves (different physics: cost only).
5. early termination (``kinetic_energy_fraction: 0.01``, and 0.05) with end_time 0.3 s vs the same
   run without; steps computed (from ``t_end``) and peaks (must agree to 1e-12).
6. ``run_chunk`` over 10^4 variants of which 100 are unique vs 10^4 unique (a study file in a
   temporary folder); the duplicated variants must equal a run of the 100 unique ones exactly.
7. the numba cache: process wall and CPU time of a first ``crashstudy simulate`` of a small model
   (``NUMBA_CACHE_DIR`` an empty folder) and of a second one reusing it.

Usage::

    python benchmarks/skipping.py                  # default run (~3 CPU-minutes), writes the report
    python benchmarks/skipping.py --quick          # small sizes, 2 repeats: checks the script only
    python benchmarks/skipping.py --only 1,5       # some of the comparisons

Options: ``--variants N`` (comparisons 2-5, default 2000), ``--history-variants N`` (comparison 1,
default 2000), ``--dedup-axis N`` (comparison 6: 10 x 10 x N variants, default 100), ``--repeats N``
(default 5), ``--cold-repeats N`` (first-call processes of comparison 7, default 3 to stay within
~8 minutes: each compiles the kernel, ~25 s of CPU), ``--report FILE`` (default
benchmarks/results/skipping.md, with a PNG beside it; ``-`` prints only), ``--no-plot``,
``--source-note TEXT`` (recorded with the crashstudy source measured). To measure a fixed commit
while the checkout changes: ``git archive COMMIT src | tar -x -C /tmp/cs`` and run with
``PYTHONPATH=/tmp/cs/src``.

Modules: this one (the command line), skipping_measure.py (timing cases side by side, comparing their
outputs), skipping_kernel_cases.py (comparisons 1-5), skipping_run_cases.py (6-7) and skipping_report.py."""

from __future__ import annotations

import argparse
import resource
import time
from collections.abc import Callable
from pathlib import Path

from crashstudy.kernel.compiled import set_threads
from skipping_kernel_cases import cmp_geometry, cmp_histories, cmp_material, cmp_termination, cmp_wall_load
from skipping_measure import PLOTTED, ROOT, Row, loadavg
from skipping_report import plot, write_report
from skipping_run_cases import cmp_cache, cmp_dedup

REPORT = ROOT / "benchmarks" / "results" / "skipping.md"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--variants", type=int, default=2000, help="variants of comparisons 2-5 (default 2000)")
    ap.add_argument("--history-variants", type=int, default=2000)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--cold-repeats", type=int, default=3)
    ap.add_argument(
        "--dedup-axis", type=int, default=100, help="values of the repeated axis (10 x 10 x N variants)"
    )
    ap.add_argument("--only", default="1,2,3,4,5,6,7")
    ap.add_argument("--quick", action="store_true", help="small sizes, 2 repeats (a check of the script)")
    ap.add_argument("--report", default=str(REPORT))
    ap.add_argument("--no-plot", action="store_true")
    ap.add_argument(
        "--source-note", default="", help="a note on the crashstudy source measured, for the report"
    )
    args = ap.parse_args(argv)
    if args.quick:
        args.variants, args.history_variants, args.repeats, args.cold_repeats, args.dedup_axis = (
            256,
            256,
            2,
            1,
            10,
        )
    set_threads(1)
    only = {int(x) for x in args.only.split(",")}
    t0, load0 = time.perf_counter(), loadavg()
    rows: list[Row] = []
    log: list[str] = []
    steps: list[tuple[int, Callable[[], list[Row]]]] = [
        (1, lambda: cmp_histories(args.history_variants, args.repeats, log)),
        (2, lambda: cmp_geometry(args.variants, args.repeats, log)),
        (3, lambda: cmp_wall_load(args.variants, args.repeats, log)),
        (4, lambda: cmp_material(args.variants, args.repeats, log)),
        (5, lambda: cmp_termination(args.variants, args.repeats, log)),
        (6, lambda: cmp_dedup(args.dedup_axis, args.repeats, log)),
        (7, lambda: cmp_cache(args.cold_repeats, args.repeats, log)),
    ]
    for k, fn in steps:
        if k in only:
            print(f"comparison {k} ... (load {loadavg()})", flush=True)
            new = fn()
            rows += new
            for r in new:
                print(f"  {r.feature}: {r.gain}; {r.check}", flush=True)
    seconds = time.perf_counter() - t0
    png = None
    if not args.no_plot and args.report != "-" and PLOTTED:
        png_path = Path(args.report).with_suffix(".png")
        png_path.parent.mkdir(parents=True, exist_ok=True)
        if plot(PLOTTED, png_path):
            png = png_path.name
    text = write_report(rows, log, args, seconds, load0, loadavg(), png)
    if args.report != "-":
        Path(args.report).parent.mkdir(parents=True, exist_ok=True)
        Path(args.report).write_text(text)
        print(f"wrote {args.report}")
    print(text)
    print(f"peak RSS {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**10:.0f} MiB")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
