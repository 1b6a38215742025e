"""``calibrate: {objective: iso18571}``: the variables that maximise the ISO/TS 18571 rating R of the model's
channel against the data (docs/optimize.md, docs/correlation.md).

R is not smooth in the variables (the phase shift is a whole number of samples, the warping path jumps),
so the search is :func:`scipy.optimize.differential_evolution` as in ``optimize``: a population per
batch of runs, every candidate's channel rated in one vectorised call (:func:`crashstudy.analysis.iso18571.rate_histories`),
minimising ``1 - R`` (a failed candidate scores 2), within ``budget`` model evaluations.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from crashstudy import interrupt

POPSIZE = 15


def calibrate_iso18571(
    ev: Any,
    spec: dict[str, Any],
    t_data: np.ndarray,
    y_data: np.ndarray,
    second: float,
    units: dict[str, str],
    progress: Any,
    channel_history: Any,
) -> dict[str, Any]:
    """The calibration result (as :func:`crashstudy.analysis.optimization.calibrate` returns it, plus
    ``objective``, ``iso18571``: R, Z, EP, EM, ES and the grade at the fit). ``channel_history(plan, res,
    channel)`` is the calibrated channel of every run (the caller's, so that this module does not import it)."""
    from scipy.optimize import differential_evolution

    from crashstudy.analysis.iso18571 import grade, rate_histories

    channel = spec["channel"]
    variables = list(spec["variables"])
    bounds = [(float(a), float(b)) for a, b in spec["variables"].values()]
    d = len(variables)
    maxiter = max(1, int(spec.get("budget", 600)) // (POPSIZE * d) - 1)
    best = [float("-inf")]

    def rated(x: np.ndarray) -> tuple[dict[str, np.ndarray], np.ndarray, np.ndarray]:  # x: (S, d)
        df, res = ev.run(x)
        t, h = channel_history(ev.plan, res, channel)
        h = np.where((df["status"] == "ok").to_numpy()[:, None], h, np.nan)
        return rate_histories(t, h, t_data, y_data, second), t, h

    def f(x: np.ndarray) -> np.ndarray:  # x: (d, S), one population
        scores, _, _ = rated(x.T)
        r = scores["R"]
        best[0] = max(best[0], float(np.nanmax(r))) if np.isfinite(r).any() else best[0]
        print(
            f"  generation {ev.batches - 1}: {x.shape[1]} candidates, best R so far {best[0]:.4f}, "
            f"{ev.evaluations} evaluations, {time.perf_counter() - t0:.1f} s",
            file=progress,
            flush=True,
        )
        interrupt.check()  # a stop request: after the whole generation
        return np.where(np.isfinite(r), 1.0 - r, 2.0)

    print(
        f"calibrating {d} variable(s) to {len(t_data)} data points by the ISO/TS 18571 rating (a line per "
        "generation; the first may compile the kernel)",
        file=progress,
        flush=True,
    )
    t0 = time.perf_counter()
    fit = differential_evolution(
        f,
        bounds,
        vectorized=True,
        updating="deferred",
        popsize=POPSIZE,
        maxiter=maxiter,
        seed=0,
        polish=False,
        tol=1e-8,
        atol=0.0,
        init="latinhypercube",
    )
    seconds = time.perf_counter() - t0
    evaluations, batches = ev.evaluations, ev.batches
    scores, t, h = rated(np.array([fit.x]))
    model = np.interp(t_data, t, h[0])
    if not np.isfinite(scores["R"][0]):
        raise FloatingPointError(
            f"the model failed at the best candidate {dict(zip(variables, fit.x, strict=True))}"
        )
    iso: dict[str, Any] = {k: round(float(scores[k][0]), 6) for k in ("R", "Z", "EP", "EM", "ES")}
    iso["grade"] = grade(float(scores["R"][0]))
    iso["interval"] = [float(scores["t0"]), float(scores["t1"])]
    return {
        "variables": {k: float(v) for k, v in zip(variables, fit.x, strict=True)},
        "objective": "iso18571",
        "iso18571": iso,
        "rms_error": float(np.sqrt(np.mean((model - y_data) ** 2))),
        "correlation": float(np.corrcoef(model, y_data)[0, 1]),
        "data_points": int(len(t_data)),
        "evaluations": int(evaluations),
        "batches": int(batches),
        "seconds": round(seconds, 3),
        "message": str(fit.message),
        "_fit": (t_data, y_data, model, units),
    }
