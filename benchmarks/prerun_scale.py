"""Pre-run cost and memory of big studies (issue 24 item 9, issue 25 item 2): everything before the first
kernel call must scale with the distinct axis values, not with the variants.

Two measurements, each case in its own process:

``--prerun``: the 2-spring 1-D model of issue 25 (``nonlinear_elastic`` curves of 5 and 6 points, the
outer one stiffening to ~1 MN; ``time_step: {safety_factor: 0.085}``, ~86 steps), a matrix over a mass x
``curves.outer.scale`` x ``impact_velocity`` of 10^6 (100^3) and 10^7 (1000 x 100 x 100) variants, WARM
caches (a small run of the same model first). Times (after the imports every run pays once, reported apart) ``load_study`` + ``check_plan`` (what ``run`` does
before it writes anything) + ``run_plan`` up to the first call of ``kernel.entry.run_batch`` (the call
raises to stop the run there). Goal: <= 1 us per variant, < 0.5 s at 10^6.

``--memory``: peak RSS (``/usr/bin/time -f %M``) of ``crashstudy validate`` and ``crashstudy run
--dry-run`` for a design (lhs, n rows over 2 axes) crossed with matrix axes: 10^6, 10^7 and 10^8 variants
at n = 10^4 (matrix 100, 1000, 100 x 100), and n = 10^6 x a 100-value matrix (10^8, the issue's case),
plus saltelli with n = 10^6 (6 x 10^6 rows). The design rows (n x k floats) are inherent; the rest must
not grow with the matrix product.

Run: ``python benchmarks/prerun_scale.py [--prerun] [--memory]`` (both by default). Writes
``benchmarks/results/prerun_scale.md``.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from common import RESULTS, load, machine, machine_md, md_table, wait_for_kernels  # noqa: E402

MODEL = """\
name: two-spring
units: SI
curves:
  inner: {x: [-0.3, -0.1, -0.05, 0.0, 0.05], y: [-3.0e5, -1.2e5, -5.0e4, 0.0, 5.0e4]}
  outer: {x: [-0.4, -0.2, -0.1, -0.05, 0.0, 0.05], y: [-1.0e6, -3.0e5, -1.0e5, -4.0e4, 0.0, 4.0e4]}
nodes:
  wall: {position: [0.0], fixed: true}
  m1: {position: [0.5], mass: 20.0}
  m2: {position: [1.0], mass: 100.0}
springs:
  s1: {nodes: [wall, m1], material: {type: nonlinear_elastic, curve: outer}}
  s2: {nodes: [m1, m2], material: {type: nonlinear_elastic, curve: inner}}
initial_velocity: {m1: [-5.0], m2: [-5.0]}
end_time: 0.02
time_step: {safety_factor: 0.085}
output: {histories: none, interval: 0.02}
"""


def _values(lo: float, hi: float, n: int) -> str:
    return "[" + ", ".join(repr(round(float(v), 9)) for v in np.linspace(lo, hi, n)) + "]"


def matrix_study(model: Path, sizes: tuple[int, int, int], name: str = "prerun") -> str:
    a, b, c = sizes
    return (
        f"name: {name}\nmodel: {model}\nmatrix:\n  nodes.m2.mass: {_values(80.0, 120.0, a)}\n"
        f"  curves.outer.scale: {_values(0.7, 1.6, b)}\n  impact_velocity: {_values(3.0, 8.0, c)}\n"
    )


def design_study(model: Path, method: str, n: int, matrix: list[int]) -> str:
    text = (
        f"name: design\nmodel: {model}\ndesign:\n  method: {method}\n  n: {n}\n  axes:\n"
        "    nodes.m1.mass: {uniform: [15.0, 25.0]}\n    curves.inner.scale: {uniform: [0.8, 1.2]}\n"
    )
    if matrix:
        text += "matrix:\n"
        paths = ["impact_velocity", "nodes.m2.mass"]
        for k, size in enumerate(matrix):
            lo, hi = (3.0, 8.0) if k == 0 else (80.0, 120.0)
            text += f"  {paths[k]}: {_values(lo, hi, size)}\n"
    return text


MEMORY_CAP = 8 * 2**30  # address space of a measured command


class _FirstKernelCall(Exception):
    pass


def prerun_one(study: Path) -> dict[str, Any]:
    """In this process: seconds from load_study to the first kernel call (run_plan stopped there)."""
    import crashstudy.kernel.entry as entry
    from crashstudy.run.runner import run_plan
    from crashstudy.study.plan import load_study
    from crashstudy.study.sanity import check_plan

    marks: dict[str, float] = {}

    def stop(*args: Any, **kwargs: Any) -> Any:
        marks["kernel"] = time.perf_counter()
        marks["kernel_cpu"] = time.process_time()
        raise _FirstKernelCall

    entry.run_batch = stop  # type: ignore[assignment]  # runner and run_ordered call it through the module
    t_imp = time.perf_counter()  # what every run imports (numba, netCDF4, the criteria): a fixed cost, apart
    import netCDF4  # noqa: F401
    import numba  # noqa: F401

    import crashstudy.kernel.choice  # noqa: F401
    import crashstudy.metrics.criteria  # noqa: F401
    import crashstudy.results.store  # noqa: F401

    imports = time.perf_counter() - t_imp
    t0, c0 = time.perf_counter(), time.process_time()
    plan = load_study(study)
    marks["load_study"] = time.perf_counter()
    problems, _ = check_plan(plan)
    assert not problems, problems
    marks["check_plan"] = time.perf_counter()
    with tempfile.TemporaryDirectory() as out:
        try:
            run_plan(plan, Path(out) / "r", progress=False)
        except _FirstKernelCall:
            pass
    end = marks.get("kernel", time.perf_counter())
    return {
        "variants": plan.n_variants,
        "imports_s": imports,
        "load_study_s": marks["load_study"] - t0,
        "check_plan_s": marks["check_plan"] - marks["load_study"],
        "run_plan_s": end - marks["check_plan"],
        "total_s": end - t0,
        "total_cpu_s": marks.get("kernel_cpu", time.process_time()) - c0,
        "reached_kernel": "kernel" in marks,
    }


def _peak(cmd: list[str]) -> tuple[int, float, int]:
    """(exit code, wall seconds, peak RSS MiB) of a command."""
    t0 = time.perf_counter()

    def cap() -> (
        None
    ):  # a command that materialises the variants fails here instead of filling a shared machine
        import resource

        resource.setrlimit(resource.RLIMIT_AS, (MEMORY_CAP, MEMORY_CAP))

    p = subprocess.run(["/usr/bin/time", "-f", "%M", *cmd], capture_output=True, text=True, preexec_fn=cap)
    rss = int(p.stderr.strip().splitlines()[-1]) // 1024
    return p.returncode, time.perf_counter() - t0, rss


def memory_cases(work: Path, model: Path) -> list[dict[str, Any]]:
    cases = [
        ("lhs", 10_000, [100]),
        ("lhs", 10_000, [1000]),
        ("lhs", 10_000, [100, 100]),
        ("lhs", 1_000_000, [100]),
        ("saltelli", 1_000_000, []),
    ]
    rows = []
    for method, n, matrix in cases:
        path = work / f"design-{method}-{n}-{'x'.join(map(str, matrix)) or '1'}.yaml"
        path.write_text(design_study(model, method, n, matrix))
        for command in (["validate", str(path)], ["run", str(path), "--dry-run"]):
            code, secs, rss = _peak([sys.executable, "-m", "crashstudy.cli", *command])
            from crashstudy.study.design import n_rows

            rows_n = n_rows(method, n, 2)
            rows.append(
                {
                    "command": command[0] + (" --dry-run" if len(command) > 2 else ""),
                    "design": f"{method} n={n:,} ({rows_n:,} rows)",
                    "matrix": " x ".join(map(str, matrix)) or "-",
                    "variants": f"{rows_n * int(np.prod(matrix)):.0e}",
                    "exit": code,
                    "seconds": round(secs, 1),
                    "peak_rss_mib": rss,
                }
            )
            print(rows[-1], flush=True)
    return rows


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--prerun", action="store_true")
    ap.add_argument("--memory", action="store_true")
    ap.add_argument("--one", help=argparse.SUPPRESS)
    ap.add_argument("--wait", help=argparse.SUPPRESS)
    ap.add_argument("--report", default=str(RESULTS / "prerun_scale.md"))
    args = ap.parse_args()
    if args.one:
        print(json.dumps(prerun_one(Path(args.one))))
        return
    if args.wait:
        from crashstudy.study.plan import load_study

        wait_for_kernels(load_study(Path(args.wait)))
        return
    both = not (args.prerun or args.memory)
    start = load()
    sections = []
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        model = work / "two-spring.yaml"
        model.write_text(MODEL)
        if args.prerun or both:
            warm = work / "warm.yaml"
            warm.write_text(matrix_study(model, (4, 4, 4), "warm"))
            subprocess.run(
                [sys.executable, "-m", "crashstudy.cli", "run", str(warm), "-o", str(work / "w")],
                check=True,
                capture_output=True,
            )
            subprocess.run(
                [sys.executable, __file__, "--wait", str(warm)], check=True
            )  # its background compile
            rows = []
            for sizes in ((100, 100, 100), (1000, 100, 100)):
                path = work / f"m{np.prod(sizes)}.yaml"
                path.write_text(matrix_study(model, sizes))
                out = subprocess.run(
                    [sys.executable, __file__, "--one", str(path)], capture_output=True, text=True
                )
                r = (
                    json.loads(out.stdout.strip().splitlines()[-1])
                    if out.returncode == 0
                    else {"error": out.stderr[-300:]}
                )
                if "total_s" in r:
                    r["us_per_variant"] = round(r["total_s"] / r["variants"] * 1e6, 3)
                    r = {k: round(v, 3) if isinstance(v, float) else v for k, v in r.items()}
                rows.append({"matrix": " x ".join(map(str, sizes)), **r})
                print(rows[-1], flush=True)
            sections.append("## Time before the first kernel call (warm caches)\n\n" + md_table(rows))
        if args.memory or both:
            sections.append(
                "## Peak memory of validate and run --dry-run\n\n" + md_table(memory_cases(work, model))
            )
    text = (
        "# Pre-run cost and memory of big studies\n\n`python benchmarks/prerun_scale.py` (see its docstring)."
        "\n\n" + "\n\n".join(sections) + "\n\n" + machine_md(machine(start)) + "\n"
    )
    if args.report != "-":
        Path(args.report).write_text(text)
    print(text)


if __name__ == "__main__":
    main()
