"""Cold compile cost of a generated kernel against the number of springs it is written for.

A 1-D chain of ``n`` nonlinear_elastic springs (one 5-point curve, one mass a node, one variant, one step's
worth of run: the run itself is negligible) is simulated with ``CRASHSTUDY_KERNEL=generated`` in a fresh
process on EMPTY caches (``NUMBA_CACHE_DIR``, ``CRASHSTUDY_KERNEL_CACHE``, ``HOME``), and again with
``CRASHSTUDY_KERNEL=reference`` (no compile: imports, YAML and writing only). Recorded per ``n``: CPU seconds
(user + sys of the process, ``/usr/bin/time``) and peak RSS of both, the difference being the compile.
What it is for: the kernel choice's estimate of a generated compile (``choice.generated_compile_seconds``)
and the largest model it will compile a generated kernel for (``gen_shape.MAX_GENERATED_SPRINGS``): the
compile grows faster than linearly in the springs (one unrolled function), and a 1179-spring grid's compile
passed 11 GB of memory before it was stopped.

Run: ``python benchmarks/compile_springs.py [--sizes 8,16,32,64]``; writes
``benchmarks/results/compile_springs.md``.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import yaml

from common import load, machine, machine_md

HERE = Path(__file__).resolve().parent
REPORT = HERE / "results" / "compile_springs.md"


def chain(n: int) -> dict:
    nodes = {"n0": {"position": [0.0], "fixed": True}}
    springs = {}
    for i in range(1, n + 1):
        nodes[f"n{i}"] = {"position": [0.01 * i], "mass": 1.0}
        springs[f"s{i}"] = {
            "nodes": [f"n{i - 1}", f"n{i}"],
            "material": {"type": "nonlinear_elastic", "curve": "c"},
        }
    return {
        "name": f"chain{n}",
        "units": "SI",
        "curves": {"c": {"x": [-1.0, -0.01, 0.0, 0.01, 1.0], "y": [-2e4, -1e4, 0.0, 1e4, 2e4]}},
        "nodes": nodes,
        "springs": springs,
        "initial_velocity": {f"n{n}": [-1.0]},
        "end_time": 0.01,
        "output": {"histories": "none"},
    }


def measure(n: int, kernel: str, work: Path) -> tuple[float, float]:
    """(CPU seconds, peak RSS MiB) of one cold ``crashstudy simulate`` of the n-spring chain."""
    d = Path(tempfile.mkdtemp(dir=work))
    for sub in ("numba", "kernels", "home"):
        (d / sub).mkdir(mode=0o700)
    model = d / "chain.yaml"
    model.write_text(yaml.safe_dump(chain(n)))
    env = dict(
        os.environ,
        NUMBA_CACHE_DIR=str(d / "numba"),
        CRASHSTUDY_KERNEL_CACHE=str(d / "kernels"),
        HOME=str(d / "home"),
        CRASHSTUDY_KERNEL=kernel,
        CRASHSTUDY_BACKGROUND_COMPILE="0",
    )
    timing = d / "time.txt"
    cmd = [
        "/usr/bin/time",
        "-o",
        str(timing),
        "-f",
        "%U %S %M",
        sys.executable,
        "-m",
        "crashstudy.cli",
        "simulate",
        str(model),
        "-o",
        str(d / "out"),
    ]
    subprocess.run(cmd, env=env, check=True, capture_output=True)
    user, system, rss = timing.read_text().split()[-3:]
    return float(user) + float(system), float(rss) / 1024


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sizes", default="8,16,32,64")
    args = ap.parse_args(argv)
    rows = []
    start = load()
    with tempfile.TemporaryDirectory() as tmp:
        for n in [int(s) for s in args.sizes.split(",")]:
            la = os.getloadavg()
            gen_cpu, gen_rss = measure(n, "generated", Path(tmp))
            ref_cpu, ref_rss = measure(n, "reference", Path(tmp))
            rows.append(
                f"| {n} | {gen_cpu:.1f} | {ref_cpu:.1f} | {gen_cpu - ref_cpu:.1f} | "
                f"{(gen_cpu - ref_cpu) / n:.2f} | {gen_rss:.0f} | {ref_rss:.0f} | "
                f"{la[0]:.1f} / {la[1]:.1f} |"
            )
            print(rows[-1], flush=True)
    text = [
        "# Cold compile of a generated kernel against its springs",
        "",
        machine_md(machine(start)),
        __doc__.strip(),
        "",
        "| springs | generated CPU s | reference CPU s | compile CPU s | compile CPU s per spring | "
        "generated peak RSS MiB | reference peak RSS MiB | load 1 / 5 min |",
        "|---|---|---|---|---|---|---|---|",
        *rows,
        "",
    ]
    REPORT.write_text("\n".join(text))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
