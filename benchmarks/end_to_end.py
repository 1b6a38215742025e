"""End to end: ``crashstudy run`` of summary-only frontal studies against a scipy loop and the
hand-specialised loop, and where the time goes.

1. Accuracy calibration on a sample of variants (corners and centre of the study's ranges): the
   largest ``time_step: {tolerance}`` whose peak force and peak deceleration errors are at most
   ``--target`` (1e-3) on every sampled variant, and the loosest scipy DOP853 rtol (hybrid solver of
   :mod:`scipy_models`, events at every branch change) that reaches the same target. Reference: scipy
   DOP853 rtol 1e-11 with events (validated against crashstudy at safety_factor 0.00025 to ~1e-7 on
   the frontal model in the work-precision benchmark). Error = largest relative error over springs /
   nodes whose reference value is at least 1% of the largest.
2. ``crashstudy run`` as a subprocess under ``/usr/bin/time -v`` (wall time from process start to exit,
   i.e. after results.nc and summary.csv are written; peak RSS) for 10^4, 10^5 and 10^6 variants of
   frontal-9mass.yaml: engine mass x survival-room mass x impact velocity,
   ``set: {output: {histories: none}, time_step: {tolerance: <calibrated>}}``, default threads.
3. scipy per variant at the same error: mean time of ``--scipy-sample`` random variants of the study
   (integration and event handling only, peak search not charged) x number of variants.
4. The 10^5 study against the hand-specialised loop (:mod:`frontal_specialised`) integrating the same
   variants with the same steps (element-steps equal), kernel time only, same threads.
5. Where the time goes: a study (``--profile-size``, default 10^5) run again in a fresh process with timers around the pipeline
   stages (imports, study loading, batch building, kernel calls (the first one includes the numba cache
   load), the rest of ``run_chunk``, result writing), plus the bare interpreter start-up.

Run: ``python benchmarks/end_to_end.py [--sizes 10000 100000 1000000] [--tolerance T --rtol R]``
(given both, the calibration is skipped). Writes ``benchmarks/results/<name>.{csv,md}``.
"""

from __future__ import annotations

import argparse
import copy
import json
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np
import yaml

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from common import FRONTAL, RESULTS, load, machine, machine_md, md_table, write_csv  # noqa: E402

QUANT = ("peak_force", "peak_deceleration")
TOLERANCES = (2e-2, 1e-2, 5e-3, 2e-3, 1e-3, 5e-4, 2e-4, 1e-4)
RTOLS = (1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10)
ENGINE = (120.0, 210.0)  # kg
ROOM = (700.0, 1000.0)  # kg, survival room (the model has 865)
SPEED = (10.0, 20.0)  # m/s


def grid(n_variants: int) -> dict[str, list[float]]:
    """engine mass x survival-room mass x impact velocity with ``n_variants`` points in all."""
    sizes = {10_000: (100, 1, 100), 100_000: (100, 10, 100), 1_000_000: (100, 100, 100)}
    if n_variants in sizes:
        a, b, c = sizes[n_variants]
    else:
        c = int(round(n_variants ** (1 / 3)))
        a = c
        b = max(1, n_variants // (a * c))
    axes = {}
    for path, (lo, hi), n in (
        ("nodes.engine.mass", ENGINE, a),
        ("nodes.survival_room.mass", ROOM, b),
        ("impact_velocity", SPEED, c),
    ):
        axes[path] = [float(x) for x in np.linspace(lo, hi, n)] if n > 1 else [float(0.5 * (lo + hi))]
    return axes


def study(n_variants: int, tol: float) -> dict[str, Any]:
    return {
        "name": f"frontal-{n_variants}",
        "model": str(FRONTAL),
        "matrix": grid(n_variants),
        "set": {"output": {"histories": "none"}, "time_step": {"tolerance": tol}},
    }


def base_model() -> dict[str, Any]:
    from crashstudy.schema.yamlio import load_yaml

    return load_yaml(str(FRONTAL)).data


def variant_model(engine: float, room: float, speed: float) -> dict[str, Any]:
    """The model dict of one variant (the study axes applied by hand, as docs/format.md defines them)."""
    m = copy.deepcopy(base_model())
    m["nodes"]["engine"]["mass"] = engine
    m["nodes"]["survival_room"]["mass"] = room
    for n, vel in m["initial_velocity"].items():
        v = np.asarray(vel, float)
        m["initial_velocity"][n] = [float(x) for x in v / np.linalg.norm(v) * speed]
    return m


def sample_points(rng: np.random.Generator | None = None, n: int = 0) -> list[tuple[float, float, float]]:
    if rng is None:  # corners of the speed x engine ranges, and the centre
        return [(e, 865.0, s) for e in ENGINE for s in SPEED] + [(165.0, 865.0, 15.0), (165.0, ROOM[1], 20.0)]
    return [
        (float(rng.uniform(*ENGINE)), float(rng.uniform(*ROOM)), float(rng.uniform(*SPEED))) for _ in range(n)
    ]


def rel_err(values: dict[str, np.ndarray], ref: dict[str, np.ndarray]) -> float:
    out = 0.0
    for q in QUANT:
        r = np.abs(ref[q])
        keep = r >= 0.01 * r.max()
        out = max(out, float(np.max(np.abs(values[q][keep] - ref[q][keep]) / r[keep])))
    return out


def calibrate(target: float) -> tuple[float, float, list[dict[str, Any]]]:
    """(crashstudy tolerance, scipy rtol, table rows) reaching ``target`` on every sampled variant."""
    import scipy_models
    from work_precision import run_cs, sm_values

    pts = sample_points()
    refs = [sm_values(scipy_models.solve(variant_model(*p), "DOP853", 1e-11, 1e-14)) for p in pts]
    rows = []
    chosen_tol = TOLERANCES[-1]
    for tol in TOLERANCES:
        errs = [
            rel_err(run_cs(variant_model(*p), {"tolerance": tol}, 1, 0)["values"], r)
            for p, r in zip(pts, refs, strict=True)
        ]
        rows.append(
            {
                "solver": "crashstudy tolerance",
                "setting": tol,
                "max_peak_error": max(errs),
                "median_peak_error": float(np.median(errs)),
                "mean_time_s": float("nan"),
            }
        )
    ok = [r["setting"] for r in rows if r["max_peak_error"] <= target]
    chosen_tol = max(ok) if ok else TOLERANCES[-1]
    scipy_ok = []
    for rtol in RTOLS:
        errs, times = [], []
        for p, r in zip(pts, refs, strict=True):
            t0 = time.perf_counter()
            sol = scipy_models.solve(variant_model(*p), "DOP853", rtol, rtol * 1e-3)
            times.append(time.perf_counter() - t0)
            errs.append(rel_err(sm_values(sol), r))
        rows.append(
            {
                "solver": "scipy DOP853 + events",
                "setting": rtol,
                "max_peak_error": max(errs),
                "median_peak_error": float(np.median(errs)),
                "mean_time_s": float(np.mean(times)),
            }
        )
        if max(errs) <= target:
            scipy_ok.append(rtol)
    # the loosest rtol that reaches the target (cost grows as rtol shrinks; picking by measured time
    # would let timing noise choose a tighter, slower setting)
    chosen_rtol = max(scipy_ok) if scipy_ok else RTOLS[-1]
    return chosen_tol, chosen_rtol, rows


def run_cli(study_file: Path, out: Path, env: dict[str, str] | None = None) -> dict[str, Any]:
    """``crashstudy run`` in a subprocess under /usr/bin/time -v: wall [s], peak RSS [MiB], output."""
    cmd = [
        sys.executable,
        "-m",
        "crashstudy.cli",
        "run",
        str(study_file),
        "-o",
        str(out),
        "--progress",
        "off",
        "--force",
    ]
    timer = ["/usr/bin/time", "-v"] if Path("/usr/bin/time").exists() else []
    t0 = time.perf_counter()
    p = subprocess.run(timer + cmd, capture_output=True, text=True, env=env)
    wall = time.perf_counter() - t0
    if p.returncode != 0:
        raise RuntimeError(f"crashstudy run failed ({p.returncode}): {p.stderr[-2000:]}")
    rss = re.search(r"Maximum resident set size \(kbytes\): (\d+)", p.stderr)
    return {
        "wall_s": wall,
        "peak_rss_MiB": int(rss.group(1)) / 1024 if rss else float("nan"),
        "stdout": p.stdout.strip(),
    }


def scipy_time(rtol: float, n: int) -> tuple[float, float]:
    """Mean and median time per variant of the scipy loop on ``n`` random variants of the study."""
    import scipy_models

    times = []
    for p in sample_points(np.random.default_rng(4), n):
        m = variant_model(*p)
        t0 = time.perf_counter()
        scipy_models.solve(m, "DOP853", rtol, rtol * 1e-3)
        times.append(time.perf_counter() - t0)
    return float(np.mean(times)), float(np.median(times))


def specialised_time(n_variants: int, tol: float, threads: int, repeats: int = 3) -> tuple[float, float]:
    """(median kernel wall s, element-steps) of the specialised loop on the study's variants."""
    from crashstudy.arrays.batch import build_batch
    from crashstudy.study.plan import load_study
    from frontal_specialised import run_specialised
    from frontal_specialised import set_threads as spec_threads

    plan = load_study(study(n_variants, tol))
    b, _ = build_batch(plan.topology, plan.params(0, plan.n_variants), plan.interval)
    spec_threads(threads)
    run_specialised(b.take(np.arange(4)), (), plan.n_out)  # warm: cache load / compile excluded
    ts = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        run_specialised(b, (), plan.n_out)
        ts.append(time.perf_counter() - t0)
    return float(np.median(ts)), float(plan.topology.n_springs * b.n_steps.sum())


def profile_child(study_file: str, out: str) -> None:
    """Run a study in this (fresh) process with timers around the pipeline stages; print JSON."""
    t_start = time.perf_counter()
    import crashstudy.cli.main  # noqa: F401
    import crashstudy.results.store
    import crashstudy.run.runner as runner
    from crashstudy.study.plan import load_study

    t_import = time.perf_counter() - t_start
    t0 = time.perf_counter()
    import crashstudy.kernel.compiled  # noqa: F401  (numba)

    t_numba = time.perf_counter() - t0
    acc: dict[str, Any] = {"build_batch": 0.0, "kernel": [], "run_chunk": 0.0, "write": 0.0, "finish": 0.0}

    def timed(key: str, fn: Any) -> Any:
        def wrapper(*a: Any, **k: Any) -> Any:
            t = time.perf_counter()
            r = fn(*a, **k)
            dt = time.perf_counter() - t
            if isinstance(acc[key], list):
                acc[key].append(dt)
            else:
                acc[key] += dt
            return r

        return wrapper

    runner.build_batch = timed("build_batch", runner.build_batch)
    runner.run_kernel = timed("kernel", runner.run_kernel)
    runner.run_chunk = timed("run_chunk", runner.run_chunk)
    W = crashstudy.results.store.ResultWriter
    W.write = timed("write", W.write)  # type: ignore[method-assign]
    W.finish = timed("finish", W.finish)  # type: ignore[method-assign]
    t0 = time.perf_counter()
    plan = load_study(study_file)
    t_load = time.perf_counter() - t0
    t0 = time.perf_counter()
    runner.run_plan(plan, out, force=True, progress=False)
    t_run = time.perf_counter() - t0
    k = acc["kernel"]
    print(
        json.dumps(
            {
                "import crashstudy (cli, runner, results, study)": t_import,
                "import numba kernel module": t_numba,
                "load_study (validate, expand)": t_load,
                "build_batch (all chunks)": acc["build_batch"],
                "first kernel call (incl. numba cache load)": k[0] if k else 0.0,
                "median later kernel call": float(np.median(k[1:])) if len(k) > 1 else 0.0,
                "kernel (all chunks)": float(sum(k)),
                "kernel calls": len(k),
                "rest of run_chunk (unique, reorder, reasons)": acc["run_chunk"]
                - acc["build_batch"]
                - sum(k),
                "ResultWriter.write (all chunks)": acc["write"],
                "ResultWriter.finish (netCDF, summary.csv)": acc["finish"],
                "run_plan other (open results, backend)": t_run
                - acc["run_chunk"]
                - acc["write"]
                - acc["finish"],
                "run_plan total": t_run,
                "process total (after interpreter start)": time.perf_counter() - t_start,
            }
        )
    )


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument(
        "--sizes",
        type=int,
        nargs="+",
        default=[10_000, 100_000, 1_000_000],
        help="study sizes (variants)",
    )
    ap.add_argument(
        "--profile-size",
        type=int,
        default=100_000,
        help="study size of the where-the-time-goes run (0: none)",
    )
    ap.add_argument("--name", default="end_to_end", help="result file stem")
    ap.add_argument("--target", type=float, default=1e-3, help="peak error to reach (crashstudy and scipy)")
    ap.add_argument("--scipy-sample", type=int, default=20)
    ap.add_argument("--tolerance", type=float, help="skip the calibration and use this tolerance")
    ap.add_argument("--rtol", type=float, help="skip the calibration and use this scipy rtol")
    ap.add_argument("--profile-child", nargs=2, metavar=("STUDY", "OUT"), help=argparse.SUPPRESS)
    ap.add_argument("--out", type=Path, default=RESULTS)
    args = ap.parse_args(argv)
    if args.profile_child:
        profile_child(*args.profile_child)
        return 0
    start_load = load()
    t_start = time.perf_counter()
    args.out.mkdir(parents=True, exist_ok=True)
    calib: list[dict[str, Any]] = []
    if args.tolerance and args.rtol:
        tol, rtol = args.tolerance, args.rtol
    else:
        tol, rtol, calib = calibrate(args.target)
        tol, rtol = args.tolerance or tol, args.rtol or rtol
    print(
        f"calibrated: tolerance {tol:g}, scipy rtol {rtol:g} ({time.perf_counter() - t_start:.0f} s)",
        flush=True,
    )
    sp_mean, sp_median = scipy_time(rtol, args.scipy_sample)
    print(f"scipy: {sp_mean:.3f} s per variant (mean of {args.scipy_sample})", flush=True)
    threads = os.cpu_count() or 1
    rows: list[dict[str, Any]] = []
    prof: dict[str, Any] = {}
    spec: tuple[float, float] | None = None
    with tempfile.TemporaryDirectory(prefix="e2e-") as tmp:
        tmpd = Path(tmp)
        # a cold kernel cache: the first run of this model shape compiles its generated kernel (once per
        # machine); measured on an 8-variant study forced onto the generated kernel, then the timed runs
        # (which choose it themselves: > 5e9 element-steps) load it from the cache
        os.environ["CRASHSTUDY_KERNEL_CACHE"] = str(tmpd / "kernels")
        small = tmpd / "study-small.yaml"
        small.write_text(yaml.safe_dump(study(8, tol), sort_keys=False))
        env = dict(os.environ, CRASHSTUDY_KERNEL="generated")
        first = run_cli(small, tmpd / "out-small-1", env)["wall_s"]
        again = run_cli(small, tmpd / "out-small-2", env)["wall_s"]
        print(
            f"first run of the model shape (compiles the generated kernel): {first:.1f} s; again: {again:.1f} s",
            flush=True,
        )
        t_py = []
        for _ in range(3):
            t0 = time.perf_counter()
            subprocess.run([sys.executable, "-c", "pass"], check=True)
            t_py.append(time.perf_counter() - t0)
        for V in args.sizes:
            f = tmpd / f"study-{V}.yaml"
            f.write_text(yaml.safe_dump(study(V, tol), sort_keys=False))
            load0 = load()
            r = run_cli(f, tmpd / f"out-{V}")
            size_mb = sum(p.stat().st_size for p in (tmpd / f"out-{V}").rglob("*") if p.is_file()) / 2**20
            row = {
                "variants": V,
                "tolerance": tol,
                "wall_s": r["wall_s"],
                "peak_rss_MiB": r["peak_rss_MiB"],
                "result_files_MiB": size_mb,
                "scipy_rtol": rtol,
                "scipy_s_per_variant": sp_mean,
                "scipy_loop_s (mean x N)": sp_mean * V,
                "speedup_vs_scipy": sp_mean * V / r["wall_s"],
                "load_before": load0,
                "load_after": load(),
                "cli_says": r["stdout"].splitlines()[-1],
            }
            if V == 100_000:
                spec = specialised_time(V, tol, threads)
                row["specialised_kernel_s"] = spec[0]
                row["element_steps"] = spec[1]
                row["cli_over_specialised"] = r["wall_s"] / spec[0]
            if V == args.profile_size:
                out = subprocess.run(
                    [
                        sys.executable,
                        str(HERE / "end_to_end.py"),
                        "--profile-child",
                        str(f),
                        str(tmpd / "out-profile"),
                    ],
                    capture_output=True,
                    text=True,
                    check=True,
                )
                prof = json.loads(out.stdout.strip().splitlines()[-1])
                prof["python -c pass (interpreter start, median of 3)"] = float(np.median(t_py))
            rows.append(row)
            print(
                f"V={V}: {r['wall_s']:.1f} s, {r['peak_rss_MiB']:.0f} MiB, x{row['speedup_vs_scipy']:.0f} vs scipy "
                f"(load {row['load_after']})",
                flush=True,
            )

    info = machine(start_load)
    write_csv(args.out / f"{args.name}.csv", rows, info)
    text = [
        "# End to end: `crashstudy run`, summary only, frontal-9mass\n\n",
        machine_md(info),
        f"- threads (crashstudy default = os.cpu_count()): {threads}\n",
        f"- total script time: {time.perf_counter() - t_start:.0f} s\n\n",
        __doc__.split("\n\n", 1)[1],
        "\n",
        f"## Calibration (target peak error {args.target:g})\n\nChosen: tolerance {tol:g}, scipy DOP853 rtol {rtol:g}.\n\n",
        md_table(calib) if calib else "(given on the command line)\n",
        f"\n## Compilation\n\nThe runs below use the generated kernel of the model shape from a cache filled "
        f"by a first run of an 8-variant study: that first run took {first:.1f} s (compiling the generated "
        f"kernel on a cold cache), the same study again {again:.1f} s (cache load).\n",
        f"\nscipy time per variant at rtol {rtol:g}: mean {sp_mean:.4g} s, median {sp_median:.4g} s "
        f"({args.scipy_sample} random variants of the study).\n\n## Runs\n\n",
        md_table([{k: v for k, v in r.items() if k != "cli_says"} for r in rows]) if rows else "",
        "\n",
        "".join(f"- {r['variants']}: `{r['cli_says']}`\n" for r in rows),
        f"\n## Where the time goes ({args.profile_size}-variant study, fresh process, in-process timers)\n\n",
        md_table([{"stage": k, "seconds": v} for k, v in prof.items()]) if prof else "(not run)\n",
    ]
    if spec:
        text.append(
            f"\nHand-specialised loop on the same 10^5 variants ({spec[1]:.3g} element-steps, {threads} threads): "
            f"{spec[0]:.3g} s (median of 3).\n"
        )
    (args.out / f"{args.name}.md").write_text("".join(text))
    print(f"wrote {args.out / (args.name + '.md')} ({time.perf_counter() - t_start:.0f} s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
