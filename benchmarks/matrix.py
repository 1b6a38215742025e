"""The benchmark matrix: models x axis kinds x sizes x warm / cold caches, each cell beside a
hand-specialised loop of the same model taking the same per-variant inputs (issue 25 item 4).

Models: ``2spring`` (1-D, two ``nonlinear_elastic`` springs, curves of 5 and 6 points, the outer one
stiffening to 1 MN; fixed dt 1e-4 s, 8695 steps, or 86 steps at >= 10^6 variants), ``frontal``
(studies/models/frontal-9mass.yaml; 0.12 s, or 6 ms at >= 10^6 variants), ``helicopter``
(studies/models/helicopter-subfloor.yaml, 2-D, gravity) and ``grid`` (a 2-D grid of ~1000 springs).
Axis kinds: ``masses`` (two masses), ``scale`` / ``x_scale`` (a curve's force / abscissa scale), ``stiffness``
(a spring's stiffness), ``impact_velocity`` (each crossed with a mass axis) and ``design`` (Latin-hypercube
rows over a mass, a curve scale and the impact velocity).

Each cell runs in its own process: ``load_study`` + ``run_plan`` end to end (histories none), with the
time inside the kernel calls (``kernel.entry.run_batch``) summed separately; "outside" = everything
else per variant (expansion, checks, hashing, set-up, writing). ``cold``: fresh numba and kernel caches
(the compile is in the time); ``warm``: a second run on the caches of a first one (whose background
compile was waited for). Then, in the same process, the hand loop (``chain_specialised`` for
``2spring``, ``frontal_specialised`` for ``frontal``, ``helicopter_specialised`` for ``helicopter``,
``grid_specialised`` for ``grid``) integrates the same variants
with crashstudy's steps, timing its kernel only (batches are built outside the timing), and its peak
forces are checked against crashstudy's (``check``: largest relative difference). ratio = crashstudy end
to end / loop kernel.

Run: ``python benchmarks/matrix.py [--models 2spring frontal] [--kinds ...] [--sizes 1000 100000]
[--caches warm cold] [--quick] [--threads 2]``. ``--quick``: 2spring and frontal, 10^3 and 10^5, warm.
Writes ``benchmarks/results/matrix.md`` (and ``.csv``) with the cells that ran.
"""

from __future__ import annotations

import argparse
import importlib
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from common import FRONTAL, MODELS, RESULTS, load, machine, machine_md, md_table, wait_for_kernels, write_csv  # noqa: E402

TWO_SPRING = """name: two-spring-curves
units: SI
curves:
  inner: {x: [-0.3, -0.1, 0.0, 0.1, 0.3], y: [-2.0e5, -5.0e4, 0.0, 5.0e4, 2.0e5]}
  outer: {x: [-0.2, -0.1, -0.05, 0.0, 0.05, 0.1], y: [-1.0e6, -2.0e5, -4.0e4, 0.0, 4.0e4, 2.0e5]}
nodes:
  wall: {position: [0.0], fixed: true}
  m1: {position: [0.5], mass: 1.0}
  m2: {position: [1.0], mass: 2.0}
springs:
  s1: {nodes: [wall, m1], material: {type: nonlinear_elastic, curve: inner}}
  s2: {nodes: [m1, m2], material: {type: nonlinear_elastic, curve: outer}}
initial_velocity: {m2: [-5.0]}
end_time: END
time_step: {dt: 1.0e-4}
output: {histories: none, interval: END}
"""


def grid_model(nx: int = 20, ny: int = 25) -> str:
    """A 2-D grid of nx x ny nodes (bottom row fixed) joined by linear springs along x and y, with a
    crush spring on every vertical link of the bottom row; the top row moves down at 5 m/s."""
    lines = [
        "name: grid",
        "units: SI",
        "curves:",
        "  crush: {x: [-0.5, -0.01, 0.0], y: [-2.0e4, -1.5e4, 0.0]}",
        "nodes:",
    ]
    for j in range(ny):
        for i in range(nx):
            fixed = ", fixed: true" if j == 0 else ", mass: 0.5"
            lines.append(f"  n{i}_{j}: {{position: [{0.1 * i:.1f}, {0.1 * j:.1f}]{fixed}}}")
    lines.append("springs:")
    for j in range(ny):
        for i in range(nx):
            if i + 1 < nx and j > 0:
                lines.append(
                    f"  h{i}_{j}: {{nodes: [n{i}_{j}, n{i + 1}_{j}], material: {{type: linear_elastic, "
                    f"stiffness: 1.0e5}}}}"
                )
            if j + 1 < ny:
                mat = (
                    "{type: crush, loading: crush, unloading_stiffness: 1.0e6}"
                    if j == 0
                    else "{type: linear_elastic, stiffness: 1.0e5}"
                )
                lines.append(f"  v{i}_{j}: {{nodes: [n{i}_{j}, n{i}_{j + 1}], material: {mat}}}")
    lines.append("initial_velocity: {" + ", ".join(f"n{i}_{ny - 1}: [0.0, -5.0]" for i in range(nx)) + "}")
    lines += ["end_time: END", "time_step: {safety_factor: 0.9}", "output: {histories: none, interval: END}"]
    return "\n".join(lines) + "\n"


# model: (model source, end time long / short [s], {kind: axis path}, mass axis crossed with the kind,
#         loop family)
MODEL_SPECS: dict[str, dict[str, Any]] = {
    "2spring": {
        "text": TWO_SPRING,
        "end": (0.8695, 0.0086),
        "loop": "chain",
        "mass": ("nodes.m1.mass", 0.5, 2.0),
        "kinds": {
            "masses": ("nodes.m2.mass", 1.0, 3.0),
            "scale": ("curves.outer.scale", 0.5, 2.0),
            "x_scale": ("curves.outer.x_scale", 0.8, 1.5),
            "impact_velocity": ("impact_velocity", 2.0, 8.0),
        },
    },
    "frontal": {
        "file": FRONTAL,
        "end": (0.12, 0.006),
        "loop": "frontal",
        "mass": ("nodes.engine.mass", 120.0, 210.0),
        "kinds": {
            "masses": ("nodes.bumper.mass", 10.0, 30.0),
            "scale": ("curves.rail-loading.scale", 0.8, 1.6),
            "x_scale": ("curves.rail-loading.x_scale", 0.8, 1.3),
            "stiffness": ("springs.gearbox-flange.material.stiffness", 1.0e6, 4.0e6),
            "impact_velocity": ("impact_velocity", 10.0, 20.0),
        },
    },
    "helicopter": {
        "file": MODELS / "helicopter-subfloor.yaml",
        "end": (0.15, 0.01),
        "loop": "helicopter",
        "mass": ("nodes.troop_compartment.mass", 250.0, 350.0),
        "kinds": {
            "masses": ("nodes.transmission.mass", 80.0, 120.0),
            "scale": ("curves.underfloor-loading.scale", 0.9, 1.1),
            "x_scale": ("curves.underfloor-loading.x_scale", 0.9, 1.1),
            "impact_velocity": ("impact_velocity", 5.0, 8.2),
        },
    },
    "grid": {
        "text": grid_model(),
        "end": (0.02, 0.002),
        "loop": "grid",
        "mass": ("nodes.n0_24.mass", 0.4, 0.6),
        "kinds": {
            "masses": ("nodes.n1_24.mass", 0.4, 0.6),
            "scale": ("curves.crush.scale", 0.8, 1.2),
            "stiffness": ("springs.h0_1.material.stiffness", 5.0e4, 2.0e5),
            "impact_velocity": ("impact_velocity", 3.0, 6.0),
        },
    },
}
KINDS = ("masses", "scale", "x_scale", "stiffness", "impact_velocity", "design")
SHORT_FROM = 10**6  # variants from which a cell runs the short end time


def study_text(model: str, kind: str, size: int, model_file: Path) -> str:
    spec = MODEL_SPECS[model]
    end = spec["end"][1 if size >= SHORT_FROM else 0]
    mpath, mlo, mhi = spec["mass"]
    if kind == "design":
        sp = spec["kinds"]["scale"]
        return (
            f"name: m-{model}-{kind}-{size}\nmodel: {model_file}\ndesign:\n  method: lhs\n  n: {size}\n  seed: 1\n"
            f"  axes:\n    {mpath}: {{uniform: [{mlo}, {mhi}]}}\n    {sp[0]}: {{uniform: [{sp[1]}, {sp[2]}]}}\n"
            f"    impact_velocity: {{uniform: {list(spec['kinds']['impact_velocity'][1:])}}}\n"
            f"set: {{end_time: {end}, output: {{histories: none, interval: {end}}}}}\n"
        )
    path, lo, hi = spec["kinds"][kind]
    a = int(round(np.sqrt(size)))
    while size % a:
        a -= 1
    axes = {path: np.linspace(lo, hi, size // a), mpath: np.linspace(mlo, mhi, a)}
    body = "\n".join(f"  {k}: {[round(float(v), 9) for v in vals]}" for k, vals in axes.items())
    return (
        f"name: m-{model}-{kind}-{size}\nmodel: {model_file}\nmatrix:\n{body}\n"
        f"set: {{end_time: {end}, output: {{histories: none, interval: {end}}}}}\n"
    )


def one(cell: dict[str, Any]) -> dict[str, Any]:
    """Run ``cell`` (model, kind, size, cache) in this process; times in seconds."""
    from crashstudy.kernel import choice, entry
    from crashstudy.kernel.compiled import set_threads
    from crashstudy.run import runner
    from crashstudy.study.plan import load_study

    set_threads(cell["threads"])
    folder = Path(cell["folder"])
    spec = MODEL_SPECS[cell["model"]]
    model_file = folder / f"{cell['model']}.yaml"
    end = spec["end"][1 if cell["size"] >= SHORT_FROM else 0]
    model_file.write_text(
        spec["text"].replace("END", str(end)) if "text" in spec else Path(spec["file"]).read_text()
    )
    study = folder / "study.yaml"
    study.write_text(study_text(cell["model"], cell["kind"], cell["size"], model_file))
    spent = {"kernel": 0.0, "kernel_cpu": 0.0, "steps": 0.0}
    real = entry.run_batch

    def timed(batch, *a, **k):  # type: ignore[no-untyped-def]
        t0, c0 = time.perf_counter(), time.process_time()
        out = real(batch, *a, **k)
        spent["kernel"] += time.perf_counter() - t0
        spent["kernel_cpu"] += time.process_time() - c0
        spent["steps"] += float(np.sum(batch.n_steps)) * len(batch.spring_i)
        return out

    entry.run_batch = timed
    picked: set[str] = set()
    real_pick = choice.pick

    def pick(*a, **k):  # type: ignore[no-untyped-def]
        kind = real_pick(*a, **k)
        picked.add(kind)
        return kind

    choice.pick = pick
    t0, c0 = time.perf_counter(), time.process_time()
    plan = load_study(study)
    rep = runner.run_plan(plan, folder / "out", force=True, progress=False)
    total = time.perf_counter() - t0
    cpu = time.process_time() - c0
    row = {
        "model": cell["model"],
        "kind": cell["kind"],
        "variants": plan.n_variants,
        "cache": cell["cache"],
        "steps_per_variant": spent["steps"] / max(plan.n_variants, 1) / max(len(plan.topology.spring_ids), 1),
        "end_to_end_s": total,
        "cpu_s": cpu,
        "kernel_s": spent["kernel"],
        "kernel_cpu_s": spent["kernel_cpu"],
        "code": _code(),
        "outside_us_per_variant": 1e6 * (total - spent["kernel"]) / plan.n_variants,
        "element_steps_per_s": spent["steps"] / max(spent["kernel"], 1e-9),
        "failed": rep.n_failed,
        "kernel": "+".join(sorted(picked)),
    }
    if (
        cell["cache"] == "cold"
    ):  # the next (warm) run finds this shape's kernels compiled (as after a background compile)
        wait_for_kernels(plan)
    if spec["loop"] is not None:
        ids = plan.topology.spring_ids
        ours = np.array(rep.results.summary[[f"peak_force.{s}" for s in ids]].to_numpy(dtype=float).T)
        ours[:, rep.results.summary["status"].to_numpy() != "ok"] = (
            np.nan
        )  # failed variants stop early: not compared
        row.update(hand_loop(spec["loop"], plan, ours, cell["threads"]))
        row["ratio"] = total / row["loop_s"]
        row["cpu_ratio"] = cpu / max(row["loop_cpu_s"], 1e-9)
    return row


def _code() -> str:
    """The commit of the crashstudy code this cell ran (+ "+edits" when src/ had uncommitted changes)."""
    import crashstudy

    if os.environ.get("MATRIX_CODE"):  # a snapshot of the code (git archive) names its commit
        return os.environ["MATRIX_CODE"]
    src = Path(crashstudy.__file__).resolve().parent
    git = ["git", "-C", str(src)]
    head = subprocess.run(
        [*git, "rev-parse", "--short", "HEAD"], capture_output=True, text=True
    ).stdout.strip()
    dirty = subprocess.run(
        [*git, "status", "--porcelain", "--", "."], capture_output=True, text=True
    ).stdout.strip()
    return head + ("+edits" if dirty else "")


def hand_loop(family: str, plan: Any, ours: np.ndarray, threads: int) -> dict[str, Any]:
    """The hand loop over the plan's variants (batches built outside the timing), checked against
    crashstudy's peak forces ``ours`` (S, V)."""
    from crashstudy.arrays.batch import build_batch

    spent, cpu, worst, knots, chunk = 0.0, 0.0, 0.0, 0.0, 1 << 16
    compared = False
    for lo in range(0, plan.n_variants, chunk):
        hi = min(lo + chunk, plan.n_variants)
        b, _ = build_batch(plan.topology, plan.params(lo, hi), plan.interval)
        if family == "chain":
            import chain_specialised as cs

            shapes, inp = cs.shapes(b), cs.inputs(b)
            cs.run(
                shapes, {k: np.ascontiguousarray(v[..., :256]) for k, v in inp.items()}, threads
            )  # compile
            t0, c0 = time.perf_counter(), time.process_time()
            pf = cs.run(shapes, inp, threads)["peak_force"]
        elif family in ("helicopter", "grid"):
            loop = importlib.import_module(f"{family}_specialised")
            loop.run_specialised(b.take(np.arange(min(8, hi - lo))), threads)  # compile
            t0, c0 = time.perf_counter(), time.process_time()
            pf = loop.run_specialised(b, threads).peak_force
        else:
            import frontal_specialised as fs

            fs.set_threads(threads)
            fs.run_specialised(b.take(np.arange(min(8, hi - lo))), (), 1)  # compile / load
            t0, c0 = time.perf_counter(), time.process_time()
            pf = fs.run_specialised(b, (), 1).peak_force
        spent += time.perf_counter() - t0
        cpu += time.process_time() - c0
        ref = ours[:, lo:hi]
        # a difference relative to the force itself, but not below 1e-6 of the chunk's largest force: a spring
        # the wave has not reached has a peak of 0 in one and a rounding residue (~1e-11 N) in the other
        floor = max(1e-6 * float(np.nanmax(np.abs(ref), initial=0.0)), 1e-300)
        if family != "chain":  # the frontal loop has no knot-peak search: springs whose curve has one apart
            knot = _knot_springs(b)
            knots = max(
                knots,
                float(np.nanmax(np.abs(pf - ref)[knot] / np.maximum(np.abs(ref[knot]), floor), initial=0.0)),
            )
            pf, ref = pf[~knot], ref[~knot]
        compared = compared or pf.size > 0
        worst = max(worst, float(np.nanmax(np.abs(pf - ref) / np.maximum(np.abs(ref), floor), initial=0.0)))
    # no spring without a knot peak (helicopter): no "check" (an empty max is not a perfect agreement)
    return {
        "loop_s": spent,
        "loop_cpu_s": cpu,
        "check": worst if compared else None,
        "check_knot_springs": knots,
    }


def _knot_springs(b: Any) -> np.ndarray:
    """(S,) the springs whose loading curve has a knot peak: crashstudy's ``peak_force`` counts a knot passed
    between two steps (docs/format.md), a hand loop without that search only the forces at steps
    (benchmarks/frontal_check.py: the frontal rear-rail, up to 1.1e-4 below)."""
    out = np.zeros(len(b.spring_i), dtype=bool)
    for s, c in enumerate(b.curve_a):
        out[s] = c >= 0 and bool(np.any(b.knot_check[b.curve_off[c] : b.curve_off[c + 1]]))
    return out


def run_cell(cell: dict[str, Any]) -> dict[str, Any] | None:
    env = cell.pop("env")
    proc = subprocess.run(
        [sys.executable, __file__, "--one", json.dumps(cell)],
        capture_output=True,
        text=True,
        env=env,
        timeout=3600,
    )
    if proc.returncode != 0:
        print(proc.stderr[-3000:], file=sys.stderr)
        return None
    return dict(json.loads(proc.stdout.strip().splitlines()[-1]))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--one", help=argparse.SUPPRESS)
    ap.add_argument("--models", nargs="+", default=list(MODEL_SPECS), choices=list(MODEL_SPECS))
    ap.add_argument("--kinds", nargs="+", default=list(KINDS), choices=list(KINDS))
    ap.add_argument("--sizes", type=int, nargs="+", default=[1000, 100_000, 1_000_000])
    ap.add_argument("--caches", nargs="+", default=["warm", "cold"], choices=["warm", "cold"])
    ap.add_argument(
        "--cold-sizes",
        type=int,
        nargs="+",
        default=[1000],
        help="the sizes that also get a cold cell (fresh caches; default 10^3 only)",
    )
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--quick", action="store_true", help="2spring and frontal, 10^3 and 10^5 variants, warm")
    ap.add_argument("--out", type=Path, default=RESULTS / "matrix")
    ap.add_argument(
        "--table", action="store_true", help="only write the table from the rows of an earlier run (.jsonl)"
    )
    args = ap.parse_args(argv)
    if args.table:
        lines = args.out.with_suffix(".jsonl").read_text().splitlines()
        write(
            [json.loads(x) for x in lines],
            args.out,
            machine(lines and json.loads(lines[0])["load"] or load()),
        )
        return 0
    if args.one:
        print(json.dumps(one(json.loads(args.one))))
        return 0
    if args.quick:
        args.models, args.sizes, args.caches = ["2spring", "frontal"], [1000, 100_000], ["warm"]
    start_load, rows = load(), []
    args.out.with_suffix(".jsonl").unlink(missing_ok=True)
    for model in args.models:
        kinds = [k for k in args.kinds if k == "design" or k in MODEL_SPECS[model]["kinds"]]
        with tempfile.TemporaryDirectory(prefix="csmatrix-") as shared:
            for kind in kinds:
                warm = [s for s in args.sizes if "warm" in args.caches]
                if "cold" in args.caches:  # fresh caches per cold cell, then its warm run on them
                    for size in [s for s in args.sizes if s in args.cold_sizes]:
                        with tempfile.TemporaryDirectory(prefix="csmatrix-") as tmp:
                            rows += cells(args, model, kind, [size], tmp, ["cold", "warm"])
                        warm = [s for s in warm if s != size]
                if warm:  # one first run of this shape on the model's caches (not kept), then the warm cells
                    rows += cells(args, model, kind, [min(1000, *args.sizes)], shared, ["cold"], keep=False)
                    rows += cells(args, model, kind, warm, shared, ["warm"])
    write(rows, args.out, machine(start_load))
    return 0


def cells(
    args: Any, model: str, kind: str, sizes: list[int], caches: str, runs: list[str], keep: bool = True
) -> list[dict[str, Any]]:
    """Run the cells (model, kind, size) on the numba / kernel caches in folder ``caches``; the rows of the
    runs asked for (``keep``)."""
    env = dict(os.environ, NUMBA_CACHE_DIR=f"{caches}/numba", CRASHSTUDY_KERNEL_CACHE=f"{caches}/kernels")
    out = []
    for size in sizes:
        for run in runs:
            folder = Path(tempfile.mkdtemp(prefix=f"{run}-", dir=caches))
            cell = {
                "model": model,
                "kind": kind,
                "size": size,
                "cache": run,
                "threads": args.threads,
                "folder": str(folder),
                "env": env,
            }
            row = run_cell(cell)
            if row is None or not keep or run not in args.caches:
                continue
            row["load"] = load()
            out.append(row)
            print(json.dumps(row), flush=True)
            with open(
                args.out.with_suffix(".jsonl"), "a"
            ) as fh:  # rows so far (the table is written at the end)
                fh.write(json.dumps(row) + "\n")
    return out


def write(rows: list[dict[str, Any]], out: Path, info: dict[str, str]) -> None:
    cols = (
        "model kind variants cache kernel steps_per_variant end_to_end_s cpu_s kernel_s kernel_cpu_s "
        "outside_us_per_variant element_steps_per_s loop_s loop_cpu_s ratio cpu_ratio check check_knot_springs "
        "failed load code"
    ).split()
    write_csv(out.with_suffix(".csv"), [{c: r.get(c) for c in cols} for r in rows], info)
    looped = [r for r in rows if r.get("ratio") is not None]
    worst = max(looped, key=lambda r: r["ratio"]) if looped else None
    head = ["# Benchmark matrix (benchmarks/matrix.py)", "", machine_md(info), ""]
    if worst is not None:
        head += [
            f"**Worst cell: {worst['model']} / {worst['kind']} / {worst['variants']} variants / {worst['cache']}: "
            f"{worst['ratio']:.2f}x its hand-specialised loop end to end** ({worst['end_to_end_s']:.2f} s vs "
            f"{worst['loop_s']:.2f} s).",
            "",
        ]
        warm = [r for r in looped if r["cache"] != "cold"]  # a cold cell's compile runs in a child process
        if warm:
            w = max(warm, key=lambda r: r["ratio"])
            head += [
                f"Worst warm cell: {w['model']} / {w['kind']} / {w['variants']} variants: {w['ratio']:.2f}x "
                f"({w['end_to_end_s']:.2f} s vs {w['loop_s']:.2f} s).",
                "",
            ]
        by_cpu = max(warm or looped, key=lambda r: r.get("cpu_ratio") or 0.0)
        if by_cpu.get("cpu_ratio") is not None:
            head += [
                f"Worst by CPU seconds (steadier under load): {by_cpu['model']} / {by_cpu['kind']} / "
                f"{by_cpu['variants']} variants / {by_cpu['cache']}: {by_cpu['cpu_ratio']:.2f}x "
                f"({by_cpu['cpu_s']:.2f} CPU s vs {by_cpu['loop_cpu_s']:.2f}).",
                "",
            ]
    head += [
        "ratio = crashstudy end to end / the hand loop's kernel time (same variants, same steps, same process); "
        "check = largest relative difference of the loop's peak forces to crashstudy's (each relative to the force, but to no less than 1e-6 of the chunk's largest; frontal, helicopter, grid: over "
        "the springs whose loading curve has no knot peak; check_knot_springs: the others, where crashstudy counts a knot "
        "passed between steps and the loop does not: benchmarks/frontal_check.py); failed variants "
        "(a 2-D spring crushed to zero) are not compared. Only the cells listed ran. cpu_s / kernel_cpu_s / "
        "loop_cpu_s: process CPU seconds (all threads) of the same spans, without child processes (a cold cell's "
        "compile); cpu_ratio = cpu_s / loop_cpu_s. code: the commit each row ran.",
        "",
        "",
    ]
    out.with_suffix(".md").write_text("\n".join(head) + md_table(rows, cols) + "\n")


if __name__ == "__main__":
    sys.exit(main())
