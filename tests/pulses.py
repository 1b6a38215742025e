"""Acceleration pulses and the crash criteria of one pulse, for the criteria tests (tests/test_criteria_*.py,
tests/test_criteria_filter.py)."""

from __future__ import annotations

import numpy as np

from crashstudy.metrics import criteria as C

G = 9.80665


def one(acc_1d: np.ndarray, dt: float, names=C.CRITERIA, cfc: int = 1000, v0: float = 15.0, **kw):
    """compute() for one 1-D variant; returns {name: float}."""
    acc = np.asarray(acc_1d, dtype=float)[None, :, None]
    r = C.compute(
        acc, np.array([acc.shape[1]]), np.array([dt]), np.array([[v0]]), np.array([1.0]), cfc, names, G, **kw
    )
    return {k: (v[0] if k == "criteria_note" else float(v[0])) for k, v in r.items()}


def half_sine(t: np.ndarray, peak: float, tau: float) -> np.ndarray:
    return np.where(t <= tau, peak * np.sin(np.pi * np.clip(t, 0.0, tau) / tau), 0.0)


def trapezoid(
    t: np.ndarray, start: float, rise: float, flat: float, fall: float, peak: float, base: float = 0.0
):
    return base + (peak - base) * np.interp(
        t,
        [start, start + rise, start + rise + flat, start + rise + flat + fall],
        [0.0, 1.0, 1.0, 0.0],
        left=0.0,
        right=0.0,
    )
