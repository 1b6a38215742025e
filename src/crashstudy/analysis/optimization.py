"""Optimisation and calibration over a study's model: every population (or finite-difference set) is
one batched run of the kernel (docs/optimize.md).

Both work on the study's model after ``set``; its ``matrix``, ``zip`` and ``design`` are not used.
Candidates are evaluated by :class:`Evaluator`: the variables become one zip group of the candidates'
values (both bounds validated once), computed as one chunk like any study (deduplicated, the kernel
chosen as usual) in memory, and tabulated like ``summary.parquet`` (histories kept for calibration).

- ``optimize``: :func:`scipy.optimize.differential_evolution` with ``vectorized=True`` (a whole
  population per call) minimises a summary column. Constraints are handled by ranking: a candidate
  that violates one (or fails) scores ``INFEASIBLE * (1 + its summed relative violation)``, worse
  than every feasible candidate (objectives must stay below ``INFEASIBLE``), so the search is pushed
  back to the feasible side, least-violating first. No polishing step (it would evaluate one point at
  a time).
- ``calibrate``: :func:`scipy.optimize.least_squares` (trust region, within the bounds) fits the
  variables to a measured channel; its Jacobian is a forward difference whose ``d + 1`` runs are one
  batch. Residual = model channel (linear interpolation of the history) - data, at the data's times.
"""

from __future__ import annotations

import dataclasses
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from crashstudy import interrupt
from crashstudy.exchange.testcurve import DataFileError  # the one "a test curve is unusable" error
from crashstudy.schema.study import CONSTRAINT

INFEASIBLE = 1e15


@dataclasses.dataclass
class Evaluator:
    """Runs batches of candidates of ``variables`` (axis path -> bounds) on the study's model, in memory:
    the plan is validated once (both bounds of every variable), then each batch is the chunk of a plan
    whose one zip group holds the candidates (:func:`crashstudy.run.runner.run_chunk`, no files)."""

    study: dict[str, Any]  # the study as loaded (model path made absolute)
    variables: dict[str, list[float]]
    histories: list[str] | None = None  # calibration: keep these histories
    interval: float | None = None
    expected_batches: float = 20.0  # for the kernel choice: loading a compiled kernel pays over all of them
    evaluations: int = 0
    batches: int = 0

    def __post_init__(self) -> None:
        from crashstudy.study.plan import load_study

        setting = dict(self.study.get("set") or {})
        if self.histories is not None:
            out = dict(setting.get("output") or {})
            out["histories"] = self.histories
            if self.interval is not None:
                out["interval"] = self.interval
            setting["output"] = out
        corners = {
            "name": self.study["name"],
            "model": self.study["model"],
            "set": setting,
            "zip": [{p: [float(v) for v in b] for p, b in self.variables.items()}],
        }
        self.plan = load_study(corners)

    def run(self, x: np.ndarray) -> tuple[pd.DataFrame, Any]:
        """(summary table, ChunkResult) of the candidates ``x`` (n_candidates, n_variables)."""
        from crashstudy.results.tables import chunk_frame
        from crashstudy.run.runner import run_chunk
        from crashstudy.study.plan import Axis

        axes = tuple(
            Axis(a.path, np.ascontiguousarray(x[:, k], dtype=np.float64), 0, a.ref)
            for k, a in enumerate(self.plan.axes)
        )
        plan = dataclasses.replace(self.plan, axes=axes, shape=(len(x),))
        res = run_chunk(plan, 0, len(x), repeat=max(self.expected_batches - self.batches, 1.0))
        self.evaluations += len(x)
        self.batches += 1
        return chunk_frame(plan, res), res


def evaluate_columns(ev: Evaluator, x: np.ndarray, columns: list[str]) -> pd.DataFrame:
    """The summary ``columns`` (plus status) of candidates ``x``."""
    df, _ = ev.run(x)
    missing = [c for c in columns if c not in df.columns]
    if missing:
        raise ValueError(
            f"no summary column {missing[0]!r}; columns: {[c for c in df.columns if '.' in c][:12]} ..."
        )
    return df[["status", *columns]].reset_index(drop=True)


def parse_constraints(texts: list[str]) -> list[tuple[str, str, float]]:
    out = []
    for t in texts:
        m = CONSTRAINT.match(t)
        if not m:
            raise ValueError(f"constraint {t!r}: expected 'COLUMN <= NUMBER' or 'COLUMN >= NUMBER'")
        out.append((m.group(1), m.group(2), float(m.group(3))))
    return out


def scores(
    df: pd.DataFrame, objective: str, constraints: list[tuple[str, str, float]]
) -> tuple[np.ndarray, np.ndarray]:
    """(score to minimise, feasible) per candidate; see the module docstring."""
    obj = df[objective].to_numpy(dtype=float)
    violation = np.zeros(len(df))
    for col, op, limit in constraints:
        v = df[col].to_numpy(dtype=float)
        over = (v - limit) if op == "<=" else (limit - v)
        violation += np.maximum(over, 0.0) / max(abs(limit), 1e-300)
    failed = (df["status"] != "ok").to_numpy() | ~np.isfinite(obj) | ~np.isfinite(violation)
    feasible = ~failed & (violation == 0.0)
    score = np.where(feasible, obj, INFEASIBLE * (1.0 + np.where(failed, 1e3, violation)))
    return score, feasible


def optimize(study: dict[str, Any], progress: Any = None) -> tuple[dict[str, Any], pd.DataFrame]:
    """Run the study's ``optimize:`` block (a progress line per generation to ``progress``, default
    stderr); returns the optimum and the history of every candidate (written by the caller). A stop
    request (SIGINT, SIGTERM: :mod:`crashstudy.interrupt`) ends the search after the current generation."""
    progress = progress or sys.stderr
    from scipy.optimize import differential_evolution

    spec = study["optimize"]
    variables = {k: [float(a), float(b)] for k, (a, b) in spec["variables"].items()}
    constraints = parse_constraints(list(spec.get("constraints") or []))
    columns = [spec["minimize"], *[c for c, _, _ in constraints]]
    d = len(variables)
    popsize = 15
    maxiter = max(1, int(spec.get("budget", 2000)) // (popsize * d) - 1)
    ev = Evaluator(study, variables, expected_batches=maxiter + 2)
    history: list[pd.DataFrame] = []
    mid = np.array([[(a + b) / 2.0 for a, b in variables.values()]])
    evaluate_columns(ev, mid, columns)  # names every unknown column before the search starts (ValueError)
    ev.evaluations = ev.batches = 0
    t0 = time.perf_counter()

    def f(x: np.ndarray) -> np.ndarray:  # x: (d, S), one population
        df = evaluate_columns(ev, x.T, columns)
        score, feasible = scores(df, spec["minimize"], constraints)
        rec = pd.DataFrame(x.T, columns=list(variables))
        rec.insert(0, "generation", ev.batches - 1)
        history.append(pd.concat([rec, df, pd.DataFrame({"feasible": feasible, "score": score})], axis=1))
        best = int(np.argmin(score))
        print(
            f"  generation {ev.batches - 1}: {len(score)} candidates, best of them {spec['minimize']} "
            f"{df[spec['minimize']].iloc[best]:.6g} ({'feasible' if feasible[best] else 'infeasible'}), "
            f"{ev.evaluations} evaluations, {time.perf_counter() - t0:.1f} s",
            file=progress,
            flush=True,
        )
        interrupt.check()  # a stop request: after the whole generation
        return score

    result = differential_evolution(
        f,
        [tuple(b) for b in variables.values()],
        vectorized=True,
        updating="deferred",
        popsize=popsize,
        maxiter=maxiter,
        seed=int(spec.get("seed", 0)),
        polish=False,
        tol=1e-8,
        atol=0.0,
        init="latinhypercube",
    )
    seconds = time.perf_counter() - t0
    hist = pd.concat(history, ignore_index=True)
    best = {k: float(v) for k, v in zip(variables, result.x, strict=True)}
    generations, evaluations = ev.batches, ev.evaluations
    row = evaluate_columns(ev, np.array([result.x]), columns).iloc[0]
    summary = {
        "variables": best,
        "objective": {spec["minimize"]: float(row[spec["minimize"]])},
        "constraints": {f"{c} {op} {lim:g}": float(row[c]) for c, op, lim in constraints},
        "feasible": bool(scores(pd.DataFrame([row]), spec["minimize"], constraints)[1][0]),
        "evaluations": int(evaluations),
        "generations": int(generations),
        "seconds": round(seconds, 3),
        "message": str(result.message),
    }
    return summary, hist


def optimum_study(study: dict[str, Any], values: dict[str, float]) -> dict[str, Any]:
    """A one-variant study of the optimum (or calibrated) values, to run into the output folder."""
    base = {k: v for k, v in study.items() if k in ("name", "description", "model", "set", "regression")}
    base["zip"] = [{k: [float(v)] for k, v in values.items()}]
    return base


def channel_history(plan: Any, res: Any, channel: dict[str, Any]) -> tuple[np.ndarray, np.ndarray]:
    """(times, values (variants, times)) of the calibration channel in a computed chunk."""
    topo = plan.topology
    h = res.out.histories[channel["quantity"]]  # (time, items[, axis], variants)
    if channel["quantity"].startswith("spring_"):
        v = h[:, topo.spring_ids.index(channel["spring"]), :]
    else:
        v = h[:, topo.node_ids.index(channel["node"]), "xy".index(channel.get("direction", "x")), :]
    return np.asarray(plan.times, dtype=float), np.asarray(v, dtype=float).T


def read_data(
    path: Path,
    end_time: float | None = None,
    *,
    channel: str | None = None,
    unit: str | None = None,
    quantity: str | None = None,
    system: str = "SI",
) -> tuple[np.ndarray, np.ndarray]:
    """The measured channel in model units (:func:`crashstudy.exchange.testcurve.read_curve`: a CSV
    ``time,value``, or ``channel`` of an ISO-MME test, converted from its unit or ``unit``), its missing
    (NOVALUE) samples dropped, times within 0 .. ``end_time``. A message never quotes the file's content
    (it may be a link to a secret), it says what was expected where."""
    from crashstudy.exchange.testcurve import is_isomme, read_curve

    curve = read_curve(path, channel=channel, unit=unit, quantity=quantity, system=system)
    keep = np.isfinite(curve.value) | (not is_isomme(Path(path)))  # a CSV's empty cell stays an error
    t, y = curve.time[keep], curve.value[keep]
    if len(t) < 3 or not np.all(np.isfinite(t)) or not np.all(np.isfinite(y)) or np.any(np.diff(t) <= 0):
        raise DataFileError(curve.label, "expected at least 3 rows of finite numbers with increasing time")
    if end_time is not None:
        check_span(path, t, end_time)
    return t, y


def _model_units(study: dict[str, Any]) -> str:
    """The unit system of the study's model (``set: {units: ...}`` over the model file's ``units:``)."""
    import yaml

    setting = study.get("set") or {}
    if "units" in setting:
        return str(setting["units"])
    model = (
        yaml.safe_load(Path(study["model"]).read_text(encoding="utf-8"))
        if isinstance(study["model"], str)
        else None
    )
    return str(model.get("units", "SI")) if isinstance(model, dict) else "SI"


def check_span(path: Path, t: np.ndarray, end_time: float, slack: float = 0.0) -> None:
    """Refuse data times outside 0 .. ``end_time`` (+ ``slack``): the model's channel would be clamped
    there, silently."""
    outside = np.flatnonzero((t < 0.0) | (t > end_time * (1.0 + 1e-9) + slack))
    if len(outside):
        raise DataFileError(
            f"{path}, line {int(outside[0]) + 2}",
            f"the data run from t = {t[0]:g} to {t[-1]:g}, the model from "
            f"0 to end_time {end_time:g}; {len(outside)} row(s) lie outside it (the model's channel is not "
            "defined there): remove them, or make end_time cover the data",
        )


def calibrate(study: dict[str, Any], base_dir: Path, out: Path, progress: Any = None) -> dict[str, Any]:
    """Run the study's ``calibrate:`` block (a progress line per batch of runs to ``progress``, default
    stderr); returns the fit (values, rms error, correlation, the uncertainty of each variable, ...)."""
    from scipy.optimize import least_squares

    from crashstudy.analysis.calibration_report import progress_line, uncertainty

    progress = progress or sys.stderr

    spec = study["calibrate"]
    from crashstudy.exchange.testcurve import data_block

    channel = spec["channel"]
    rel, code, data_unit = data_block(spec["data"])
    data_path = base_dir / rel
    system = _model_units(study)
    t_data, y_data = read_data(
        data_path, channel=code, unit=data_unit, quantity=channel["quantity"], system=system
    )
    variables = {k: [float(a), float(b)] for k, (a, b) in spec["variables"].items()}
    lo, hi = np.array([b[0] for b in variables.values()]), np.array([b[1] for b in variables.values()])
    interval = float(np.min(np.diff(t_data))) / 2.0  # the model sampled at least twice as often as the data
    ev = Evaluator(study, variables, histories=[channel["quantity"]], interval=interval)
    # the last history sample (end_time, up to one sampling interval): data past it would meet a clamped channel
    check_span(data_path, t_data, float(np.max(ev.plan.times)), 0.5 * ev.plan.interval)
    from crashstudy.results.attributes import units_of

    unit = units_of(ev.plan)
    kinds = {
        "acceleration": "acceleration",
        "velocity": "velocity",
        "displacement": "length",
        "spring_force": "force",
        "spring_elongation": "length",
    }
    units = {"time": unit["time"], "value": unit[kinds[channel["quantity"]]]}
    if spec.get("objective", "rms") == "iso18571":
        from crashstudy.analysis.calibration_iso import calibrate_iso18571

        second = 1000.0 if unit["time"] == "ms" else 1.0
        return calibrate_iso18571(ev, spec, t_data, y_data, second, units, progress, channel_history)
    cache: dict[bytes, np.ndarray] = {}
    best = [float("inf")]  # the smallest rms error so far, for the progress lines

    def residuals_of(x: np.ndarray) -> np.ndarray:  # x: (S, d) -> (S, n_data)
        df, res = ev.run(x)
        t, h = channel_history(ev.plan, res, channel)
        ok = (df["status"] == "ok").to_numpy()
        r = np.array([np.interp(t_data, t, h[k]) - y_data for k in range(len(x))])
        r[~ok] = np.nan
        for k in range(len(x)):
            cache[x[k].tobytes()] = r[k]
        rms = np.sqrt(np.nanmean(r**2, axis=1))
        best[0] = min(best[0], float(np.nanmin(rms))) if np.isfinite(rms).any() else best[0]
        print(
            progress_line(ev.batches, len(x), best[0], ev.evaluations, time.perf_counter() - t0),
            file=progress,
            flush=True,
        )
        interrupt.check()  # a stop request: after the whole batch
        return r

    def fun(x: np.ndarray) -> np.ndarray:
        r = cache.get(x.tobytes())
        r = residuals_of(x[None, :])[0] if r is None else r
        if not np.all(np.isfinite(r)):
            raise FloatingPointError(f"the model failed at {dict(zip(variables, x, strict=True))}")
        return r

    def jac(x: np.ndarray) -> np.ndarray:  # forward difference, one batch of d + 1 runs
        step = 1e-6 * np.maximum(np.abs(x), hi - lo)
        step = np.where(x + step > hi, -step, step)  # stay inside the bounds
        pts = np.vstack([x, x + np.diag(step)])
        r = residuals_of(pts)
        return (r[1:] - r[0]).T / step

    x0 = (lo + hi) / 2.0
    print(
        f"calibrating {len(variables)} variable(s) to {len(t_data)} data points (a line per batch of runs; the "
        "first may compile the kernel)",
        file=progress,
        flush=True,
    )
    t0 = time.perf_counter()
    fit = least_squares(
        fun, x0, jac=jac, bounds=(lo, hi), x_scale=hi - lo, xtol=1e-10, ftol=1e-12, gtol=1e-12
    )
    seconds = time.perf_counter() - t0
    model = fit.fun + y_data
    rms = float(np.sqrt(np.mean(fit.fun**2)))
    corr = float(np.corrcoef(model, y_data)[0, 1])
    return {
        "variables": {k: float(v) for k, v in zip(variables, fit.x, strict=True)},
        "rms_error": rms,
        "correlation": corr,
        "data_points": int(len(t_data)),
        "evaluations": int(ev.evaluations),
        "batches": int(ev.batches),
        "seconds": round(seconds, 3),
        "message": str(fit.message),
        "uncertainty": uncertainty(fit.jac, fit.fun, list(variables), fit.x, lo, hi),
        "_fit": (t_data, y_data, model, units),
    }
