"""Curve pairs (test, model) for the ISO/TS 18571 comparison, NumPy only: imported by
tests/test_iso18571.py and by scripts/make_iso18571_reference.py (run in a separate environment with the
``objective-rating-metrics`` package), so both rate the very same samples. All at 10 kHz."""

from __future__ import annotations

import numpy as np

DT = 1e-4


def _t(duration: float) -> np.ndarray:
    return np.arange(int(round(duration / DT)) + 1) * DT


def _half_sine(t: np.ndarray, t0: float, width: float, peak: float) -> np.ndarray:
    s = (t - t0) / width
    return np.where((s >= 0) & (s <= 1), peak * np.sin(np.pi * np.clip(s, 0, 1)), 0.0)


def _pulse(t: np.ndarray, shift: float = 0.0, scale: float = 1.0, stretch: float = 1.0) -> np.ndarray:
    """A crash-like deceleration: a main half-sine with a second hump and a small ringing."""
    u = (t - shift) / stretch
    main = _half_sine(u, 0.005, 0.06, 300.0) + _half_sine(u, 0.03, 0.03, 120.0)
    ring = 20.0 * np.sin(2 * np.pi * 90 * u) * np.exp(-30 * np.clip(u, 0, None)) * (u > 0)
    return scale * (main + ring)


def _trapezoid(t: np.ndarray, rise: float, flat: float, fall: float, peak: float) -> np.ndarray:
    return peak * np.interp(
        t,
        [0.0, 0.004, 0.004 + rise, 0.004 + rise + flat, 0.004 + rise + flat + fall, 1.0],
        [0, 0, 1, 1, 0, 0],
    )


def _damped(t: np.ndarray, f: float, zeta: float, amp: float, phase: float = 0.0) -> np.ndarray:
    w = 2 * np.pi * f
    return amp * np.exp(-zeta * w * t) * np.sin(w * np.sqrt(1 - zeta**2) * t + phase)


def pairs() -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """name -> (test, model), each a 1-D array sampled every :data:`DT` from the same first time."""
    rng = np.random.default_rng(18571)
    t1, t2 = _t(0.1), _t(0.2)
    base = _pulse(t1)
    out: dict[str, tuple[np.ndarray, np.ndarray]] = {
        "identical": (base, base.copy()),
        "scaled_0.9": (base, 0.9 * base),
        "scaled_1.3": (base, 1.3 * base),
        "shift_+1ms": (base, _pulse(t1, shift=0.001)),
        "shift_-3ms": (base, _pulse(t1, shift=-0.003)),
        "shift_+8ms": (base, _pulse(t1, shift=0.008)),
        "shift_+25ms": (base, _pulse(t1, shift=0.025)),
        "stretch_1.1": (base, _pulse(t1, stretch=1.1)),
        "stretch_0.8_scale_1.2": (base, _pulse(t1, stretch=0.8, scale=1.2)),
        "noise_1pct": (base, base + rng.normal(0, 3.0, base.shape)),
        "noise_10pct": (base, base + rng.normal(0, 30.0, base.shape)),
        "noisy_test": (base + rng.normal(0, 10.0, base.shape), base),
        "offset_20": (base, base + 20.0),
        "sign_flip": (base, -base),
        "trapezoid_vs_pulse": (_trapezoid(t1, 0.01, 0.03, 0.02, 250.0), base),
        "trapezoid_rise": (
            _trapezoid(t1, 0.01, 0.03, 0.02, 250.0),
            _trapezoid(t1, 0.015, 0.025, 0.02, 240.0),
        ),
        "damped_freq": (_damped(t2, 25.0, 0.1, 5.0), _damped(t2, 27.0, 0.12, 5.5)),
        "damped_phase": (_damped(t2, 25.0, 0.1, 5.0), _damped(t2, 25.0, 0.1, 5.0, phase=0.4)),
        "damped_noise": (
            _damped(t2, 25.0, 0.1, 5.0),
            _damped(t2, 25.0, 0.1, 5.0) + rng.normal(0, 0.3, t2.shape),
        ),
        "velocity_ramp": (15.0 - np.cumsum(base) * DT, 15.5 - np.cumsum(_pulse(t1, 0.002, 0.95)) * DT),
        "displacement": (
            np.cumsum(15.0 - np.cumsum(base) * DT) * DT,
            np.cumsum(14.0 - np.cumsum(_pulse(t1, stretch=1.05)) * DT) * DT,
        ),
        "random_walks": (np.cumsum(rng.normal(0, 1, 1500)), np.cumsum(rng.normal(0, 1, 1500))),
        "unrelated_sine": (np.sin(2 * np.pi * 30 * t1), np.cos(2 * np.pi * 47 * t1) * 0.5),
        "short_curves": (base[:60], 1.1 * base[3:63]),
        # two nearly straight rises: every shift correlates to ~1 (an ill-conditioned phase search)
        "near_linear_ramps": (
            np.sqrt(200.0) * np.sin(t1[:501] * np.sqrt(50.0)),
            10.0 * np.sin(10.0 * t1[:501]),
        ),
    }
    return out


def fingerprint(test: np.ndarray, model: np.ndarray) -> list[float]:
    """Sum, root sum of squares and index-weighted sum of each curve: the committed reference stores them
    so that tests/test_iso18571.py sees a pair whose samples changed after its scores were generated
    (compared to 1e-9 relative: not the last bits, which np.sin and friends may vary across machines)."""
    out: list[float] = []
    for y in (test, model):
        k = np.arange(len(y)) / len(y)
        out += [float(np.sum(y)), float(np.sqrt(np.sum(y * y))), float(np.sum(k * y))]
    return out
