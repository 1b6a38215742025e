"""Work-precision: error of peak force / peak deceleration / absorbed energy versus run time per variant.

For every model of :mod:`wp_models` (the six example models and four built there: 2-D smooth chain,
damped chain, crush with rebound, general_nonlinear yielding both ways):

- crashstudy at ``time_step`` ``safety_factor`` 0.9 / 0.5 / 0.1 / 0.01 and ``tolerance`` 1e-2 ... 1e-6.
  Histories off and ``output.interval = end_time`` so that the sampling interval never shortens the
  step. Time per variant: one ``run_compiled`` call (1 thread, compile excluded) on a batch of
  identical-topology copies of the model, divided by the batch size; the batch is 1000 variants, or
  fewer (never under 16) when 1000 would exceed ``--budget`` element-steps. Median of ``--repeats``.
- scipy ``solve_ivp`` (RK45 and DOP853 over a range of rtol, atol = rtol x 1e-3 in model units) per
  variant, with the lean right-hand side of :mod:`scipy_models`: for the smooth models it takes the
  same steps as ``tests/reference_scipy.py`` (same state, same nfev) at about half the time; for the
  crush / general_nonlinear models it integrates the hysteresis as a hybrid system with terminal
  events at every branch change. Time per variant = median over ``--scipy-sample`` solves of
  ``scipy_models.solve`` (integration and events only: the peak search on the dense output that gives
  scipy's errors is *not* charged to it, which favours scipy).

Reference ("converged") values:
- smooth models: ``tests/reference_scipy.py`` DOP853 at rtol 1e-12, atol 1e-15 (uncertainty: the
  difference to rtol 1e-11);
- crush / general_nonlinear models: scipy DOP853 at rtol 1e-12 with branch-change events
  (:mod:`scipy_models`), an independent solution whose peaks are located on the dense output. The
  crashstudy run at ``safety_factor`` 0.001 is recorded beside it as a cross-check; it is *not* used
  as the reference because a peak at a kink of a curve (an initial crush peak) is a corner of F(t)
  that a fixed-step run samples at discrete instants, an O(dt) error (2e-4 .. 5e-4 at safety_factor
  0.001 on crush-rebound) that Richardson extrapolation does not remove;
- prescribed-motion model (general-nonlinear-tension, no scipy support): crashstudy at
  ``safety_factor`` 0.001 (uncertainty |r(0.002) - r(0.001)| / 3, Richardson's estimate for a
  second-order method). Its peak deceleration has no converged value (the prescribed displacement has
  kinks, where the exact acceleration is a delta) and is left out.
Errors below a reference's uncertainty are not resolved (dotted line in the plots).

Error of a quantity = the largest relative error over its items (springs or nodes) whose reference
value is at least 1% of the largest item's (tiny items, such as a spring that barely moves, are left
out; fixed nodes have no acceleration).

Run: ``python benchmarks/work_precision.py [--models NAME ...] [--repeats 3] [--promise-only]``.
Writes ``benchmarks/results/work_precision.{csv,md}``, ``tolerance_promise.csv`` and ``wp_<model>.png``;
``--promise-only`` runs only the references and the ``tolerance`` sweep and writes
``tolerance_promise.{csv,md}`` (work_precision.{csv,md} and the plots are left as they are).
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import yaml

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent / "tests"))  # reference_scipy (independent of crashstudy)

import scipy_models  # noqa: E402
from common import RESULTS, load, machine, machine_md, md_table, median, write_csv  # noqa: E402
from crashstudy.arrays.batch import build_batch  # noqa: E402
from crashstudy.kernel.compiled import run_compiled, set_threads  # noqa: E402
from crashstudy.schema import parse_model  # noqa: E402
from crashstudy.schema.yamlio import loads_yaml  # noqa: E402
from crashstudy.study.plan import Plan, plan_from_model  # noqa: E402
from wp_models import models  # noqa: E402

SAFETY = (0.9, 0.5, 0.1, 0.01)
TOLERANCES = (1e-2, 1e-3, 1e-4, 1e-5, 1e-6)
SCIPY = {"RK45": (1e-3, 1e-4, 1e-5, 1e-6, 1e-7), "DOP853": (1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10)}
QUANTITIES = ("peak_force", "peak_deceleration", "absorbed_energy")
SIGNIFICANT = 0.01  # items below 1% of the largest reference value are left out of the error
FLOOR = 1e-16  # errors plotted at least at this value (log axis)


def plan_for(model: dict[str, Any], time_step: dict[str, float]) -> Plan:
    m = dict(model, time_step=time_step, output={"interval": model["end_time"], "histories": "none"})
    return plan_from_model(parse_model(loads_yaml(yaml.safe_dump(m, sort_keys=False), file=m["name"])))


def cs_values(out: Any, k: int = 0) -> dict[str, np.ndarray]:
    return {
        "peak_force": out.peak_force[:, k],
        "peak_deceleration": out.peak_acceleration[:, k],
        "absorbed_energy": out.absorbed_energy[:, k],
    }


def run_cs(model: dict[str, Any], time_step: dict[str, float], repeats: int, budget: float) -> dict[str, Any]:
    """One crashstudy setting: values of variant 0, time per variant, batch size, dt, steps."""
    plan = plan_for(model, time_step)
    b1, steps = build_batch(plan.topology, plan.params(0, 1), plan.interval)
    S = plan.topology.n_springs
    n_steps = int(b1.n_steps[0])
    V = int(min(1000, max(16, budget // max(S * n_steps, 1))))
    batch, _ = build_batch(plan.topology, np.repeat(plan.base[:, None], V, axis=1), plan.interval)
    run_compiled(b1, (), plan.n_out)  # warm (compile / cache load excluded)
    times = []
    out = None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = run_compiled(batch, (), plan.n_out)
        times.append(time.perf_counter() - t0)
    assert out is not None
    assert np.all(out.status == 0), f"{model['name']} {time_step}: status {set(out.status.tolist())}"
    assert np.all(out.peak_force == out.peak_force[:, :1]), "identical variants must give identical results"
    return {
        "values": cs_values(out),
        "t_variant": median(times) / V,
        "batch": V,
        "dt": float(steps.dt[0]),
        "dt_over_crit": float(steps.dt[0] / steps.dt_crit[0]),
        "n_steps": n_steps,
    }


def ref_scipy_values(
    ref: Any, node_ids: tuple[str, ...], spring_ids: tuple[str, ...]
) -> dict[str, np.ndarray]:
    """Values of a ``tests/reference_scipy.py`` result (dense-output peaks, refined)."""
    pk = ref.dense_peaks()
    ab = ref.absorbed_energy()
    return {
        "peak_force": np.array([pk["peak_force"][s] for s in spring_ids]),
        "peak_deceleration": np.array([pk["peak_acceleration"][n] for n in node_ids]),
        "absorbed_energy": np.array([ab[s] for s in spring_ids]),
    }


def sm_values(sol: Any) -> dict[str, np.ndarray]:
    pk = sol.peaks()
    return {
        "peak_force": pk["peak_force"],
        "peak_deceleration": pk["peak_deceleration"],
        "absorbed_energy": sol.absorbed_energy(),
    }


def run_scipy(model: dict[str, Any], method: str, rtol: float, atol: float, sample: int) -> dict[str, Any]:
    """scipy per variant (:mod:`scipy_models`): median time of ``sample`` solves (one if a solve takes
    more than 5 s); peaks from the dense output afterwards (not timed)."""
    times = []
    sol = None
    for _ in range(sample):
        t0 = time.perf_counter()
        sol = scipy_models.solve(model, method, rtol, atol)
        times.append(time.perf_counter() - t0)
        if times[-1] > 5.0:
            break
    assert sol is not None
    return {"values": sm_values(sol), "t_variant": median(times), "nfev": sol.nfev, "events": sol.n_events}


def rel_errors(values: dict[str, np.ndarray], ref: dict[str, np.ndarray]) -> dict[str, float]:
    out = {}
    for q in QUANTITIES:
        r = np.abs(ref[q])
        keep = r >= SIGNIFICANT * r.max() if r.max() > 0 else np.zeros_like(r, dtype=bool)
        out[q] = float(np.max(np.abs(values[q][keep] - ref[q][keep]) / r[keep])) if keep.any() else math.nan
    return out


def pareto(points: list[tuple[float, float]]) -> list[tuple[float, float]]:
    """Lower-left envelope of (time, error): the fastest way to each error level, time increasing."""
    pts = sorted((t, e) for t, e in points if np.isfinite(e) and e > 0)
    out: list[tuple[float, float]] = []
    for t, e in pts:
        if not out or e < out[-1][1]:
            out.append((t, e))
    return out


def time_at(env: list[tuple[float, float]], err: float) -> float:
    """Time the envelope needs for ``err`` (log-log interpolation; nan outside its error range)."""
    if not env:
        return math.nan
    es = [e for _, e in env]
    if err > es[0]:
        return env[0][0]
    if err < es[-1]:
        return math.nan
    for (t0, e0), (t1, e1) in zip(env[:-1], env[1:], strict=True):
        if e1 <= err <= e0:
            if e0 == e1:
                return t0
            f = (math.log(err) - math.log(e0)) / (math.log(e1) - math.log(e0))
            return math.exp(math.log(t0) + f * (math.log(t1) - math.log(t0)))
    return env[-1][0]


def crossover(cs_env: list[tuple[float, float]], sp_env: list[tuple[float, float]]) -> str:
    """Where crashstudy stops (or starts) beating scipy at equal error, scanned over 1e-1 .. 1e-10."""
    grid = np.logspace(-1, -10, 91)
    sign = []
    for e in grid:
        tc, ts = time_at(cs_env, e), time_at(sp_env, e)
        sign.append(None if not (np.isfinite(tc) and np.isfinite(ts)) else tc < ts)
    known = [(e, s) for e, s in zip(grid, sign, strict=True) if s is not None]
    if not known:
        return "no common error range"
    flips = [f"{e2:.1e}" for (e1, s1), (e2, s2) in zip(known[:-1], known[1:], strict=True) if s1 != s2]
    lo, hi = known[-1][0], known[0][0]
    if not flips:
        who = "crashstudy faster" if known[0][1] else "scipy faster"
        return f"{who} over the whole common range {hi:.0e} .. {lo:.0e}"
    return f"flips at error ~{', '.join(flips)} (crashstudy faster at {hi:.0e}: {known[0][1]}; at {lo:.0e}: {known[-1][1]})"


def main(argv: list[str] | None = None) -> int:
    all_models = models()
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--models", nargs="+", default=list(all_models), choices=list(all_models))
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument(
        "--budget", type=float, default=2e7, help="element-steps per timed batch (caps the batch size)"
    )
    ap.add_argument("--scipy-sample", type=int, default=3)
    ap.add_argument("--out", type=Path, default=RESULTS)
    ap.add_argument(
        "--promise-only",
        action="store_true",
        help="only the references and the tolerance sweep: writes tolerance_promise.{csv,md}",
    )
    args = ap.parse_args(argv)
    start_load = load()
    t_start = time.perf_counter()
    args.out.mkdir(parents=True, exist_ok=True)
    set_threads(1)
    rows: list[dict[str, Any]] = []
    promise: list[dict[str, Any]] = []
    cross: list[dict[str, Any]] = []
    refs: list[dict[str, Any]] = []
    for name in args.models:
        model, smooth, skip = all_models[name]
        t_model = time.perf_counter()
        plan = plan_for(model, {"safety_factor": 0.5})
        node_ids, spring_ids = plan.topology.node_ids, plan.topology.spring_ids
        hybrid = not model.get("prescribed_motion") and not model.get("rigid_walls")
        tt = np.array([0.0, model["end_time"]])
        check = ""
        if smooth:
            from reference_scipy import solve_reference

            ref = ref_scipy_values(
                solve_reference(model, t_eval=tt, rtol=1e-12, atol=1e-15), node_ids, spring_ids
            )
            ref2 = ref_scipy_values(
                solve_reference(model, t_eval=tt, rtol=1e-11, atol=1e-14), node_ids, spring_ids
            )
            ref_kind = "tests/reference_scipy DOP853 rtol 1e-12 (uncertainty: vs rtol 1e-11)"
            unc = rel_errors(ref2, ref)
            lean = rel_errors(sm_values(scipy_models.solve(model, "DOP853", 1e-12, 1e-15)), ref)
            check = "scipy_models DOP853 1e-12 vs reference: " + ", ".join(
                f"{q} {v:.1e}" for q, v in lean.items()
            )
        elif hybrid:
            ref = sm_values(scipy_models.solve(model, "DOP853", 1e-12, 1e-15))
            ref2 = sm_values(scipy_models.solve(model, "DOP853", 1e-11, 1e-14))
            ref_kind = "scipy DOP853 rtol 1e-12 with branch-change events (uncertainty: vs rtol 1e-11)"
            unc = rel_errors(ref2, ref)
            cs1 = rel_errors(run_cs(model, {"safety_factor": 0.001}, 1, 0)["values"], ref)
            check = "crashstudy safety_factor 0.001 vs reference: " + ", ".join(
                f"{q} {v:.1e}" for q, v in cs1.items()
            )
        else:
            r1 = run_cs(model, {"safety_factor": 0.001}, 1, 0)
            r2 = run_cs(model, {"safety_factor": 0.002}, 1, 0)
            ref = r1["values"]
            ref_kind = "crashstudy safety_factor 0.001 (uncertainty: |r(0.002) - r(0.001)| / 3)"
            unc = {q: v / 3.0 for q, v in rel_errors(r2["values"], ref).items()}
        for q in skip:
            unc[q] = math.nan
        refs.append(
            {
                "model": name,
                "reference": ref_kind,
                **{f"uncertainty_{q}": unc[q] for q in QUANTITIES},
                "check": check,
            }
        )

        def add(
            series: str,
            setting: float,
            res: dict[str, Any],
            ref: dict[str, np.ndarray] = ref,
            skip: tuple[str, ...] = skip,
            name: str = name,
        ) -> dict[str, Any]:
            err = rel_errors(res["values"], ref)
            for q in skip:
                err[q] = math.nan
            row = {
                "model": name,
                "series": series,
                "setting": setting,
                "t_variant_s": res["t_variant"],
                **{f"err_{q}": err[q] for q in QUANTITIES},
                "batch": res.get("batch", 1),
                "dt_over_crit": res.get("dt_over_crit", math.nan),
                "n_steps": res.get("n_steps", 0),
                "nfev": res.get("nfev", 0),
                "events": res.get("events", 0),
            }
            rows.append(row)
            return row

        for sf in () if args.promise_only else SAFETY:
            add(
                "crashstudy safety_factor",
                sf,
                run_cs(model, {"safety_factor": sf}, args.repeats, args.budget),
            )
        for tol in TOLERANCES:
            row = add(
                "crashstudy tolerance", tol, run_cs(model, {"tolerance": tol}, args.repeats, args.budget)
            )
            p = {"model": name, "tolerance": tol}
            for q in QUANTITIES:
                e = row[f"err_{q}"]
                p[f"{q}_err"] = e
                p[f"{q}_err/tol"] = e / tol
                floor = unc[q]
                p[f"{q}_verdict"] = (
                    "n/a"
                    if not np.isfinite(e)
                    else "under tol"
                    if e <= tol
                    else "within 2x"
                    if e <= 2 * tol
                    else "OVER 2x"
                )
                if np.isfinite(e) and e <= 2 * tol and floor > tol:
                    p[f"{q}_verdict"] += " (reference floor above tol)"
            promise.append(p)
        if hybrid and not args.promise_only:
            for method, rtols in SCIPY.items():
                for rtol in rtols:
                    add(
                        f"scipy {method}",
                        rtol,
                        run_scipy(model, method, rtol, rtol * 1e-3, args.scipy_sample),
                    )
            for q in QUANTITIES:
                if q in skip:
                    continue
                cs_env = pareto(
                    [
                        (r["t_variant_s"], r[f"err_{q}"])
                        for r in rows
                        if r["model"] == name and r["series"].startswith("crashstudy")
                    ]
                )
                sp_env = pareto(
                    [
                        (r["t_variant_s"], r[f"err_{q}"])
                        for r in rows
                        if r["model"] == name and r["series"].startswith("scipy")
                    ]
                )
                c = {"model": name, "quantity": q}
                for e in (1e-2, 1e-3, 1e-4, 1e-5, 1e-6):
                    tc, ts = time_at(cs_env, e), time_at(sp_env, e)
                    c[f"scipy/crashstudy time at err {e:.0e}"] = (
                        ts / tc if np.isfinite(tc) and np.isfinite(ts) else math.nan
                    )
                c["crossover"] = crossover(cs_env, sp_env)
                cross.append(c)
        if not args.promise_only:
            plot_model(
                name, [r for r in rows if r["model"] == name], unc, ref_kind, args.out / f"wp_{name}.png"
            )
        print(f"{name}: {time.perf_counter() - t_model:.0f} s (load {load()})", flush=True)

    args.out.mkdir(parents=True, exist_ok=True)
    info = machine(start_load)
    write_csv(args.out / "tolerance_promise.csv", promise, info)
    promise_table = md_table(
        promise, ["model", "tolerance"] + [f"{q}_{k}" for q in QUANTITIES for k in ("err/tol", "verdict")]
    )
    if args.promise_only:
        text = [
            "# Tolerance promise: achieved relative error vs requested tolerance\n\n",
            machine_md(info),
            f"- total script time: {time.perf_counter() - t_start:.0f} s\n",
            "- run: `python benchmarks/work_precision.py --promise-only` (references and errors as in "
            "work_precision.md)\n\n",
            "## References\n\n",
            md_table(refs),
            "\n## Tolerance promise\n\n",
            promise_table,
        ]
        (args.out / "tolerance_promise.md").write_text("".join(text))
        print(f"wrote {args.out / 'tolerance_promise.md'} ({time.perf_counter() - t_start:.0f} s)")
        return 0
    write_csv(args.out / "work_precision.csv", rows, info)
    text = [
        "# Work-precision: error vs time per variant\n\n",
        machine_md(info),
        f"- total script time: {time.perf_counter() - t_start:.0f} s\n\n",
        __doc__.split("\n\n", 1)[1],
        "\n",
        "## References\n\n",
        md_table(refs),
        "\n## Crossover: scipy time / crashstudy time at equal error\n\n",
        "Both sides are their lower envelope (best setting of any series) interpolated in log-log; > 1 means "
        "crashstudy is faster at that error; nan where a side does not reach that error.\n\n",
        md_table(cross),
        "\n## Tolerance promise: achieved relative error vs requested tolerance\n\n",
        promise_table,
        "\n## All points\n\n",
        md_table(
            rows,
            ["model", "series", "setting", "t_variant_s"]
            + [f"err_{q}" for q in QUANTITIES]
            + ["batch", "dt_over_crit", "n_steps", "nfev", "events"],
        ),
        "\n## Plots\n\n",
    ] + [f"![{m}](wp_{m}.png)\n" for m in args.models]
    (args.out / "work_precision.md").write_text("".join(text))
    print(f"wrote {args.out / 'work_precision.md'} ({time.perf_counter() - t_start:.0f} s)")
    return 0


STYLE = {
    "crashstudy safety_factor": ("C0", "o-"),
    "crashstudy tolerance": ("C2", "s-"),
    "scipy RK45": ("C1", "^--"),
    "scipy DOP853": ("C3", "v--"),
}


def plot_model(
    name: str, rows: list[dict[str, Any]], unc: dict[str, float], ref_kind: str, path: Path
) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(15, 4.6))
    for ax, q in zip(axes, QUANTITIES, strict=True):
        for series, (color, fmt) in STYLE.items():
            sel = [r for r in rows if r["series"] == series and np.isfinite(r[f"err_{q}"])]
            if not sel:
                continue
            t = [r["t_variant_s"] for r in sel]
            e = [max(r[f"err_{q}"], FLOOR) for r in sel]
            ax.plot(t, e, fmt, color=color, label=series, ms=5)
            for r, ti, ei in zip(sel, t, e, strict=True):
                ax.annotate(
                    f"{r['setting']:g}",
                    (ti, ei),
                    fontsize=6,
                    color=color,
                    xytext=(3, 2),
                    textcoords="offset points",
                )
        if np.isfinite(unc[q]) and unc[q] > 0:
            ax.axhline(max(unc[q], FLOOR), color="gray", ls=":", lw=1)
            ax.text(
                0.01,
                max(unc[q], FLOOR) * 1.3,
                "reference uncertainty",
                transform=ax.get_yaxis_transform(),
                fontsize=7,
                color="gray",
            )
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("time per variant [s]")
        ax.set_ylabel(f"relative error of {q.replace('_', ' ')}")
        ax.grid(True, which="both", alpha=0.3)
        if not any(np.isfinite(r[f"err_{q}"]) for r in rows):
            ax.text(
                0.5, 0.5, "no converged value\n(prescribed-motion kinks)", ha="center", transform=ax.transAxes
            )
    axes[0].legend(fontsize=7)
    fig.suptitle(f"{name}: work-precision (reference: {ref_kind})", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


if __name__ == "__main__":
    raise SystemExit(main())
