"""Cold compile time of each kernel per model shape: what the kernel choice (``kernel/choice.py``)
must predict before a run on a fresh machine.

For each example model, a one-variant study (``histories: none``, the model as it is) runs in a
fresh process on EMPTY caches (fresh ``HOME``, ``NUMBA_CACHE_DIR``, ``CRASHSTUDY_KERNEL_CACHE``) with
``CRASHSTUDY_KERNEL`` set to the kernel measured, then once more on the caches it left (warm). The
compile time is ``cold - warm`` wall time (import, YAML and writing cancel). The generic kernel is one
compile per machine; it is measured on the first model and on a 2-D one. A model with a ``metrics:``
block also compiles the criteria (once per machine): its row says so.

Run: ``python benchmarks/compile_costs.py [--models NAME ...] [--kernels generated generic]``.
Writes ``benchmarks/results/compile_costs.{csv,md}``.
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

from common import MODELS, RESULTS, load, machine, machine_md, md_table, write_csv  # noqa: E402

DEFAULT_MODELS = (
    "linear-spring",
    "nonlinear-elastic",
    "general-nonlinear-tension",
    "helicopter-subfloor",
    "helicopter-seat",
    "frontal-9mass",
    "frontal-occupant",
)


def shape(model: Path) -> dict[str, Any]:
    from crashstudy.arrays.compiler import compile_model
    from crashstudy.schema import load_model

    topo, _ = compile_model(load_model(str(model)).model)
    return {
        "springs": len(topo.spring_ids),
        "dim": topo.dim,
        "walls": len(topo.wall_nodes),
        "metrics": bool(topo.metrics),
    }


def timed(cmd: list[str], env: dict[str, str]) -> float:
    t0 = time.perf_counter()
    p = subprocess.run(cmd, env=env, capture_output=True, text=True)
    if p.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed:\n{p.stderr[-2000:]}")
    return time.perf_counter() - t0


def measure(model: Path, kernel: str, tmp: Path) -> dict[str, Any]:
    home = tmp / f"{model.stem}-{kernel}"
    home.mkdir()
    study = home / "study.yaml"
    study.write_text(
        f"name: one\nmodel: {model}\nmatrix:\n  impact_velocity: [1.0]\n"
        "set: {output: {histories: none}}\n"
    )
    env = dict(
        os.environ,
        HOME=str(home / "home"),
        NUMBA_CACHE_DIR=str(home / "numba"),
        CRASHSTUDY_KERNEL_CACHE=str(home / "kernels"),
        CRASHSTUDY_KERNEL=kernel,
        CRASHSTUDY_BACKGROUND_COMPILE="0",
    )
    cmd = [sys.executable, "-m", "crashstudy.cli", "run", str(study), "-o", str(home / "out"), "--force"]
    cold = timed(cmd, env)
    warm = timed(cmd, env)
    row = {
        "model": model.stem,
        "kernel": kernel,
        **shape(model),
        "cold_s": cold,
        "warm_s": warm,
        "compile_s": cold - warm,
        "load": load(),
    }
    print(row, flush=True)
    return row


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--models", nargs="+", default=list(DEFAULT_MODELS))
    ap.add_argument("--kernels", nargs="+", default=["generated", "generic"])
    args = ap.parse_args(argv)
    start = load()
    rows: list[dict[str, Any]] = []
    with tempfile.TemporaryDirectory(prefix="compile-costs-") as t:
        for name in args.models:
            for kernel in args.kernels:
                if kernel == "generic" and name not in (args.models[0], "helicopter-subfloor"):
                    continue  # one compile per machine: measured on the first model and a 2-D one
                rows.append(measure(MODELS / f"{name}.yaml", kernel, Path(t)))
    info = machine(start)
    write_csv(RESULTS / "compile_costs.csv", rows, info)
    text = (
        "# Cold compile time per kernel and model shape\n\n"
        + machine_md(info)
        + "\n"
        + __doc__.split("\n\n", 1)[1]
        + "\n"
        + md_table(rows)
    )
    (RESULTS / "compile_costs.md").write_text(text)
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
