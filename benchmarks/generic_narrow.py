"""The generic kernel on a narrow batch (1 variant, a large model) in two source trees, side by side.

The fixed cost per spring per step of the generic kernel: ``crashstudy simulate`` of one model runs one
variant (one lane), and a model over 64 springs always runs the generic kernel. Two worker processes, one per
tree, time one ``run_compiled`` call of the model's single variant each in turn (base, branch, base, ...;
the protocol and worker environment of :mod:`generic_side_by_side`, reused); CPU seconds (``process_time``),
medians of ``--repeats`` calls, and the generic kernel's cold compile (``generic_side_by_side.compiles``:
empty caches, 4 frontal variants) unless ``--no-compile``.

Models: the 1179-spring 2-D grid of :func:`stranded.grid` (end time 1.0 s, ~6000 steps) and each YAML given
by ``--models``. Run: ``python benchmarks/generic_narrow.py BASE_TREE BRANCH_TREE [--repeats 5]
[--models FILE.yaml ...] [--no-compile] [--cache-root DIR]``; writes ``benchmarks/results/generic_narrow.md``
(``--out``).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import generic_side_by_side as gsbs  # noqa: E402
import stranded  # noqa: E402
from common import RESULTS, load, machine, machine_md, md_table  # noqa: E402

WORKER = r"""
import sys, time
from crashstudy.arrays.batch import build_batch
from crashstudy.kernel.compiled import run_compiled
from crashstudy.kernel.driver import set_threads
from crashstudy.schema import parse_model
from crashstudy.schema.yamlio import loads_yaml
from crashstudy.study.plan import plan_from_model
set_threads(1)
path = sys.argv[4]
plan = plan_from_model(parse_model(loads_yaml(open(path).read(), file=path)))
b, _ = build_batch(plan.topology, plan.params(0, 1), plan.interval)
run_compiled(b, (), plan.n_out)  # warm (loads or compiles the kernel)
print("ready", flush=True)
for line in sys.stdin:
    c0 = time.process_time(); run_compiled(b, (), plan.n_out); c1 = time.process_time()
    print(c1 - c0, flush=True)
"""


def _commit(tree: str) -> str:
    out = subprocess.run(["git", "-C", tree, "log", "-1", "--format=%h %s"], capture_output=True, text=True)
    dirty = subprocess.run(
        ["git", "-C", tree, "status", "--porcelain", "src"], capture_output=True, text=True
    )
    return (out.stdout.strip()[:90] or "(not a git tree)") + (
        " + uncommitted src" if dirty.stdout.strip() else ""
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("base")
    ap.add_argument("branch")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--models", nargs="*", default=[], help="YAML models besides the grid")
    ap.add_argument("--no-compile", action="store_true")
    ap.add_argument("--compile-repeats", type=int, default=1)
    ap.add_argument("--cache-root", default=tempfile.gettempdir())
    ap.add_argument("--out", default=str(RESULTS / "generic_narrow.md"))
    a = ap.parse_args()
    start = load()
    trees = [str(Path(a.base).resolve()), str(Path(a.branch).resolve())]
    caches = [tempfile.mkdtemp(prefix=f"narrow{k}_", dir=a.cache_root) for k in range(2)]
    work = Path(tempfile.mkdtemp(prefix="narrow_models_", dir=a.cache_root))
    grid = work / "grid1.yaml"
    grid.write_text(stranded.grid(1.0))
    rows = []
    for model in [str(grid), *[str(Path(m).resolve()) for m in a.models]]:
        r = gsbs.runs(trees, caches, a.repeats, "model", model, WORKER, "1 variant, 1 thread")
        print(json.dumps(r), flush=True)
        name = "grid 1179 springs (stranded.grid(1.0))" if model == str(grid) else Path(model).name
        rows.append(
            {
                "figure": f"kernel CPU s per call, {name}",
                "base": r["base"],
                "branch": r["branch"],
                "ratio": r["ratio"],
                "paired ratio": r["paired_ratio_median"],
            }
        )
    if not a.no_compile:
        c = gsbs.compiles(trees, a.compile_repeats, a.cache_root)
        print(json.dumps(c), flush=True)
        rows.append(
            {
                "figure": "generic cold compile CPU s (4 frontal variants, empty caches)",
                "base": c["base"],
                "branch": c["branch"],
                "ratio": c["ratio"],
                "paired ratio": "",
            }
        )
    info = machine(start)
    cmd = "python benchmarks/generic_narrow.py " + " ".join(sys.argv[1:])
    text = (
        "# The generic kernel on a narrow batch (1 variant), base and branch side by side\n\n"
        f"Written by `benchmarks/generic_narrow.py` ({__doc__.splitlines()[0].lower()}). Command: `{cmd}` "
        f"(under `nice -n 19`). Medians of {a.repeats} calls per tree, trees alternated; CPU seconds.\n\n"
        f"- base: `{trees[0]}` at {_commit(trees[0])}\n- branch: `{trees[1]}` at {_commit(trees[1])}\n"
        + machine_md(info)
        + "\n"
        + md_table(rows)
    )
    Path(a.out).write_text(text)
    print(text)


if __name__ == "__main__":
    main()
