"""The stranded-run case (issue 25.3): a large model simulated on a fresh machine while another process
holds the compile lock, against the same simulate alone, measured in one run of this script.

The model: a 2-D grid of 20 x 21 nodes (the bottom row fixed, 400 masses) joined by 1179 linear springs
(rows, columns and one diagonal per cell), its top row hit downwards; about 56,000 time steps, one
variant, histories none, ``CRASHSTUDY_BACKGROUND_COMPILE=0`` for the simulate (it would leave the grid's own
generated kernel compiling after it, on the next case's cores; the kernel choice is the same). On an empty cache the NumPy reference would take ~3000 s by the cost model,
the generic kernel ~24 s to compile and < 1 s to run, so the run compiles the generic kernel first.

Cases, each on its own EMPTY caches (fresh ``HOME``, ``NUMBA_CACHE_DIR``, ``CRASHSTUDY_KERNEL_CACHE``):

- ``alone``: ``crashstudy simulate grid.yaml``;
- ``other compiles generic``: a background compile of another model's kernels (the generic kernel, then
  that model's generated one: what a study started just before leaves running) holds the compile lock
  when the simulate starts; the simulate waits for the generic kernel from it;
- ``other compiles its generated kernel``: the background compile holds the lock for another model
  shape's generated kernel only; the simulate compiles the generic kernel itself beside it.

Before the fix (06520e6) both contended cases ran on the NumPy reference (the issue: > 10 min for this
size). Goal: each contended case at most 1.5x ``alone``. Wall time of the whole ``simulate`` process.

Run: ``python benchmarks/stranded.py``. Writes ``benchmarks/results/stranded.md``.
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from common import RESULTS, load, machine, machine_md, md_table  # noqa: E402

NX, NY = 20, 21
OTHER = """name: other
units: SI
nodes:
  a: {position: [0.0], fixed: true}
  b: {position: [0.1], mass: 1.0}
  c: {position: [0.2], mass: 2.0}
springs:
  s1: {nodes: [a, b], material: {type: linear_elastic, stiffness: 1.0e5}}
  s2: {nodes: [b, c], material: {type: linear_elastic, stiffness: 2.0e5}}
initial_velocity: {c: [-5.0]}
end_time: 0.05
output: {histories: none}
"""
HOLD = """
import sys, time
from crashstudy.arrays.batch import build_batch
from crashstudy.kernel import choice
from crashstudy.schema import parse_model
from crashstudy.schema.yamlio import loads_yaml
from crashstudy.study.plan import plan_from_model
plan = plan_from_model(parse_model(loads_yaml(open(sys.argv[1]).read(), file=sys.argv[1])))
batch, _ = build_batch(plan.topology, plan.params(0, 1), plan.interval)
proc = choice.start_background(tuple(sys.argv[2].split(",")), batch, plan.topology.histories, None)
print(proc.pid, flush=True)
proc.wait()
"""


def grid(end_time: float) -> str:
    """The grid model as YAML."""
    lines = ["name: grid-400", "units: SI", "nodes:"]
    for j in range(NY):
        for i in range(NX):
            fixed = "fixed: true" if j == 0 else "mass: 1.0"
            lines.append(f"  n{i}_{j}: {{position: [{0.1 * i:.3f}, {0.1 * j:.3f}], {fixed}}}")
    lines.append("springs:")
    pairs = [((i, j), (i + 1, j)) for j in range(NY) for i in range(NX - 1)]
    pairs += [((i, j), (i, j + 1)) for j in range(NY - 1) for i in range(NX)]
    pairs += [((i, j), (i + 1, j + 1)) for j in range(NY - 1) for i in range(NX - 1)]
    for k, ((i, j), (p, q)) in enumerate(pairs):
        lines.append(
            f"  s{k}: {{nodes: [n{i}_{j}, n{p}_{q}], material: {{type: linear_elastic, stiffness: 2.0e4}}}}"
        )
    lines.append("initial_velocity: {" + ", ".join(f"n{i}_{NY - 1}: [0.0, -2.0]" for i in range(NX)) + "}")
    lines += [f"end_time: {end_time}", "output: {histories: none}"]
    return "\n".join(lines) + "\n"


def fresh_env(root: Path) -> dict[str, str]:
    for d in ("home", "numba", "kernels"):
        (root / d).mkdir(parents=True, mode=0o700)
    env = dict(
        os.environ,
        HOME=str(root / "home"),
        NUMBA_CACHE_DIR=str(root / "numba"),
        CRASHSTUDY_KERNEL_CACHE=str(root / "kernels"),
    )
    env.pop("CRASHSTUDY_KERNEL", None)
    env["CRASHSTUDY_BACKGROUND_COMPILE"] = "0"  # the simulate leaves no compile of the grid's own generated
    return env  # kernel (~470 s) running after it, to eat the next case's cores (the same decision otherwise)


def simulate(model: Path, root: Path, env: dict[str, str]) -> tuple[float, str]:
    t0 = time.perf_counter()
    done = subprocess.run(
        [sys.executable, "-m", "crashstudy.cli", "simulate", str(model), "-o", str(root / "out")],
        capture_output=True,
        text=True,
        env=env,
        timeout=1800,
    )
    seconds = time.perf_counter() - t0
    if done.returncode != 0:
        raise SystemExit(done.stderr)
    notes = [line[6:] for line in done.stderr.splitlines() if line.startswith("note: ")]
    return seconds, " / ".join(notes)


def hold_lock(other: Path, kernels: str, env: dict[str, str], root: Path) -> subprocess.Popen[str]:
    """Start a background compile of ``kernels`` for the other model; return once it holds the lock."""
    from crashstudy.kernel.compile_lock import read_holder

    proc = subprocess.Popen(
        [sys.executable, "-c", HOLD, str(other), kernels],
        stdout=subprocess.PIPE,
        text=True,
        env=dict(env, CRASHSTUDY_BACKGROUND_COMPILE="1"),
    )
    lock = root / "kernels" / "compile.lock"
    for _ in range(600):
        holder = read_holder(lock) if lock.exists() else None
        if holder is not None and holder.pid is not None:
            return proc
        time.sleep(0.05)
    raise SystemExit("the other compile never took the lock")


def main() -> None:
    start = load()
    rows = []
    with tempfile.TemporaryDirectory(prefix="stranded-") as tmp:
        base = Path(tmp)
        other = base / "other.yaml"
        other.write_text(OTHER)
        model = base / "grid.yaml"
        model.write_text(grid(10.0))  # dt 1.8e-4 s: ~55,000 steps
        for case, kernels in (
            ("alone", ""),
            ("other compiles generic", "generic,generated"),
            ("other compiles its generated kernel", "generated"),
        ):
            root = base / case.replace(" ", "-")
            env = fresh_env(root)
            holder = hold_lock(other, kernels, env, root) if kernels else None
            seconds, notes = simulate(model, root, env)
            if holder is not None:
                holder.wait(timeout=600)
            rows.append(
                {
                    "case": case,
                    "simulate wall [s]": seconds,
                    "load (1 min) after": os.getloadavg()[0],
                    "what it said": notes,
                }
            )
            print(rows[-1], flush=True)
    alone = rows[0]["simulate wall [s]"]
    for r in rows:
        r["ratio to alone"] = r["simulate wall [s]"] / alone
    info = machine(start)
    text = (
        "# Stranded run: simulate of a 400-mass, 1179-spring grid (~56,000 steps) on empty caches while "
        "another process compiles\n\n"
        + (__doc__ or "").split("\n\n", 1)[1]
        + "\n"
        + md_table(
            rows, ["case", "simulate wall [s]", "ratio to alone", "load (1 min) after", "what it said"]
        )
        + "\n"
        + machine_md(info)
    )
    RESULTS.mkdir(parents=True, exist_ok=True)
    (RESULTS / "stranded.md").write_text(text)
    print(text)


if __name__ == "__main__":
    main()
