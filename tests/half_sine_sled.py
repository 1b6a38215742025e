"""What the ``metrics:`` tests (tests/test_metrics_*.py) share: the half-sine sled (``pulse_model``) and its
pulse's constants (its closed-form HIC is checked in tests/test_metrics_closed_form.py).

The truth is a pulse imposed exactly with prescribed acceleration: a half-sine deceleration
``A sin(pi t / T)`` for ``0 <= t <= T`` on a node moving at ``v0``. Its criteria have closed forms:
``peak_g = A / g``; ``delta_v = 2 A T / pi``; HIC over a window ``L`` centred on the pulse is
``L^-1.5 (2 A T / pi)^2.5 sin^2.5(pi L / 2T)`` (A in g, time in s), largest at ``tan x = 5x/3`` with
``x = pi L / 2T`` (``x = 1.0528``), or at the longest window allowed when that is shorter. The pulse
is slow (T = 10 ms) next to CFC 1000 (-3 dB at 1650 Hz), whose gain at the pulse's frequencies differs
from 1 by less than 1e-5, so the filter does not move these numbers past the tolerances stated."""

from __future__ import annotations

import math

import numpy as np

G = 9.80665
T_PULSE = 0.010  # [s]
A_G = 60.0  # pulse amplitude [g]


def pulse_model(units: str = "SI", metrics: str = "", scale_a: float = 1.0, extra: str = "") -> str:
    """A sled at 10 m/s (or 10 mm/ms) under the half-sine deceleration, in ``units`` (SI or mm-ms-kg-kN)."""
    ms = units == "mm-ms-kg-kN"
    t_scale = 1e3 if ms else 1.0  # s -> model time
    a_unit = 1e-3 if ms else 1.0  # m/s^2 -> model acceleration (mm/ms^2)
    ts = np.linspace(0.0, T_PULSE, 201)
    xs = ", ".join(f"{t * t_scale:.12g}" for t in ts)
    ys = ", ".join(f"{math.sin(math.pi * t / T_PULSE):.12g}" for t in ts)
    amp = -A_G * G * a_unit * scale_a
    metrics = metrics or "  - {node: sled, cfc: 1000, criteria: [peak_g, hic15, hic36, delta_v]}"
    return f"""\
name: half-sine
units: {units}
curves:
  pulse: {{x: [{xs}], y: [{ys}]}}
nodes:
  base: {{position: [0.0], fixed: true}}
  sled: {{position: [1.0], mass: 1.0}}
  other: {{position: [2.0], mass: 1.0}}
springs:
  s: {{nodes: [base, sled], material: {{type: linear_elastic, stiffness: 1.0}}}}
prescribed_motion:
  - {{node: sled, quantity: acceleration, direction: x, curve: pulse, scale: {amp:.12g}}}
initial_velocity: {{sled: [10.0], other: [10.0]}}
metrics:
{metrics}
end_time: {0.03 * t_scale:g}
time_step: {{dt: {1e-5 * t_scale:g}}}
{extra}"""
