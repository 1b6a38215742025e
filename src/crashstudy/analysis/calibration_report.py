"""What a calibration can and cannot tell (docs/optimize.md, "How sure"): per variable a 95% confidence
interval from the Jacobian at the fit, and the variables the data do not determine.

With ``n`` data points, ``p`` determined variables, residuals ``r`` and the Jacobian ``J`` (n x p) of the
residuals at the fit, the linearised covariance of the fitted values is ``cov = s^2 (J^T J)^-1`` with
``s^2 = sum(r^2) / (n - p)``; the interval is ``x +- t(0.975, n - p) sqrt(diag cov)`` (Student's t).

- **undetermined**: the channel does not depend on the variable: its Jacobian column, times the width of
  its bounds, is zero or below ``UNDETERMINED`` of the largest such column. Its value is where the search
  left it (the start, the middle of the bounds) and means nothing; it is left out of the covariance.
- **poorly determined**: the interval is wider than ``POOR`` of the bounds, or the variable is
  correlated with another beyond ``CORRELATED`` (the data fix a combination, not each).
"""

from __future__ import annotations

from typing import Any

import numpy as np

UNDETERMINED = (
    1e-9  # a Jacobian column (times the bounds' width) below this fraction of the largest: no effect
)
POOR = 0.25  # a 95% interval wider than this fraction of the bounds
CORRELATED = 0.99  # |correlation| of two fitted values beyond which neither is determined alone


def uncertainty(
    jac: np.ndarray, residuals: np.ndarray, names: list[str], x: np.ndarray, lo: np.ndarray, hi: np.ndarray
) -> dict[str, dict[str, Any]]:
    """Per variable: ``value``, ``ci95`` ([low, high], None when undetermined), ``status`` (determined,
    poorly determined, undetermined) and ``note`` (why, "" when determined)."""
    from scipy import stats

    jac, r = np.asarray(jac, dtype=float), np.asarray(residuals, dtype=float)
    n = len(r)
    width = hi - lo
    effect = np.linalg.norm(jac, axis=0) * width  # the channel's first-order change across the bounds
    top = float(effect.max()) if effect.size else 0.0
    none = ~(effect > UNDETERMINED * top) if top > 0 else np.ones(len(names), dtype=bool)
    keep = np.flatnonzero(~none)
    out: dict[str, dict[str, Any]] = {}
    for k in np.flatnonzero(none):
        out[names[k]] = {
            "value": float(x[k]),
            "ci95": None,
            "status": "undetermined",
            "note": "the channel does not depend on it: its value is where the search started",
        }
    dof = n - len(keep)
    if len(keep) and dof > 0:
        jk = jac[:, keep]
        s2 = float(r @ r) / dof
        cov = s2 * np.linalg.pinv(jk.T @ jk)
        half = float(stats.t.ppf(0.975, dof)) * np.sqrt(np.maximum(np.diag(cov), 0.0))
        sd = np.sqrt(np.maximum(np.diag(cov), 0.0))
        with np.errstate(invalid="ignore", divide="ignore"):
            corr = cov / np.outer(sd, sd)
        for j, k in enumerate(keep):
            notes = []
            if half[j] > POOR * width[k]:
                notes.append(f"its 95% interval is {half[j] * 2 / width[k]:.0%} of its bounds")
            for i, other in enumerate(keep):
                if i != j and np.isfinite(corr[j, i]) and abs(corr[j, i]) > CORRELATED:
                    notes.append(
                        f"correlated with {names[other]} (r = {corr[j, i]:.4f}): the data fix a combination"
                    )
            out[names[k]] = {
                "value": float(x[k]),
                "ci95": [float(x[k] - half[j]), float(x[k] + half[j])],
                "status": "poorly determined" if notes else "determined",
                "note": "; ".join(notes),
            }
    else:
        for k in keep:
            out[names[k]] = {
                "value": float(x[k]),
                "ci95": None,
                "status": "poorly determined",
                "note": f"{n} data points for {len(keep)} variables: no interval",
            }
    return {name: out[name] for name in names}


def uncertainty_notes(report: dict[str, dict[str, Any]]) -> list[str]:
    """One warning line per variable that is not determined (for the command's output)."""
    return [
        f"warning: {name} is {v['status']}: {v['note']}"
        for name, v in report.items()
        if v["status"] != "determined"
    ]


def progress_line(batch: int, runs: int, rms: float, evaluations: int, seconds: float) -> str:
    """A line per batch of runs, so that a calibration is never silent."""
    return f"  batch {batch}: {runs} run(s), best rms error so far {rms:.6g}, {evaluations} evaluations, {seconds:.1f} s"
