"""Time step selection (docs/format.md, time_step; docs/solver.md), vectorised over variants.

Critical step: the nodal bound ``omega_max^2 <= max_n 2 K_n / m_n`` where ``K_n`` sums, over the
springs at node ``n``, the steepest slope ``k_max`` any curve of the spring can use. It is safe for
the whole assembly in 1-D and 2-D: for any displacement field ``u``,
``u^T K u = sum_s k_s (n_s . (u_j - u_i))^2 <= sum_s 2 k_s (|u_i|^2 + |u_j|^2) = sum_n 2 K_n |u_n|^2``.
Dampers enter as the nodal damping rate ``gamma_n = 2 C_n / m_n`` (``C_n`` the sum of damping
coefficients at the node; the same bound as for the stiffness) with the damped limit
``dt <= (2 / omega) (sqrt(1 + xi^2) - xi)``, ``xi = gamma / omega`` (``-> 1/gamma`` for a pure damper,
the limit of the kernel's second-order damper velocity ``v^{n-1/2} + dt/2 a^{n-1}``). A spring whose
force rises with the elongation rate (``rate_elastic``) is a damper too, ``c = dF/d(rate)``: its
steepest force change per unit rate between neighbouring curves (:func:`rate_damping`) enters ``C_n``.
A penalty wall of contact stiffness ``k_w`` is a spring to the ground at each node it holds:
``k_w |u_n|^2 = 2 (k_w / 2) |u_n|^2``; ``k_w / 2`` in ``K_n`` would bound ``omega_w = sqrt(k_w / m)``
exactly, which keeps a node that stays in contact stable, but not one that hits the wall: the contact
switches on and off within a step, and the rebound of one impact (central difference, entry at any
phase of a step) has up to 0.23 x the impact's kinetic energy more than it came with for
``omega_w dt <= 1``, but 0.56 at 1.2 .. 1.5, 1.4 at 1.6, 5.8 at 1.9 (tests/test_wall_passive.py,
``_impact_gain``; 2-D oblique runs at 0.83 .. 0.99 of that bound failed their energy balance, KE+IE
110 J from 53 J after the impact). So a penalty wall adds ``PENALTY_SHARE x k_w = 2 k_w`` to ``K_n``:
``dt_crit <= 0.99 / omega_w``, the contact's half period ``pi / omega_w`` resolved by >= 3 steps.

Accuracy (``tolerance`` mode): central difference is second order, and the relative error of the
reported peaks behaves as ``~ (omega dt)^2 / 8``; the step ``dt = min(dt_crit, 2 sqrt(2 tol) / omega)``
(i.e. ``sqrt(2 tol) * dt_crit``) keeps it under ``tol``. Time curves (loads, prescribed motion)
additionally limit the step to a quarter of their shortest segment. A peak at a kink of a spring curve
would be a first-order error of the sampled peaks that no such step controls; the kernels therefore
include the knots passed over between two steps in the peaks (docs/solver.md, "Peaks"), which keeps
the estimate above valid for them too.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from crashstudy.arrays.compiler import Topology
from crashstudy.vocabulary.materials import spec

CRITICAL_MARGIN = 0.99  # the nodal bound is attained exactly by two free masses on one spring,
# where omega dt = 2 is neutrally unstable (linear growth): dt_crit keeps a 1% margin below 2 / omega
PENALTY_SHARE = 2.0  # a penalty wall's k_w enters K_n x 2 (not / 2): omega_w dt <= 0.99 (module docstring)
TOLERANCE_FACTOR = 2.0  # dt = TOLERANCE_FACTOR * sqrt(tol / 2) * dt_crit  (calibrated in benchmarks)
MAX_STEPS = 2.0**53  # most time steps of a variant (and steps between two samples): counts stay exact int64


@dataclass
class StepChoice:
    """Per-variant step data (arrays of shape (V,))."""

    dt: np.ndarray  # step used [time]
    dt_crit: np.ndarray  # critical step bound [time]
    control_node: np.ndarray  # int index of the node that controls dt_crit (-1: none)
    control_spring: np.ndarray  # int index of the stiffest spring at that node (-1: none)
    out_every: np.ndarray  # int steps between history samples
    n_steps: np.ndarray  # int steps to end_time
    refused: np.ndarray  # bool: fixed dt above dt_crit
    too_many: np.ndarray | None = None  # bool: more than MAX_STEPS steps (or dt 0): n_steps is 0, not run


def curve_max_slope(cx: np.ndarray, cy: np.ndarray, off: np.ndarray, c: int) -> np.ndarray:
    """Largest |slope| of curve ``c`` per variant; ``cx``, ``cy`` are (Ptot, V) knot arrays."""
    a, b = int(off[c]), int(off[c + 1])
    with np.errstate(
        divide="ignore", invalid="ignore", over="ignore"
    ):  # a bad curve is refused by its caller
        slopes = np.diff(cy[a:b], axis=0) / np.diff(cx[a:b], axis=0)
    return np.max(np.abs(slopes), axis=0)


def curve_values(cx: np.ndarray, cy: np.ndarray, off: np.ndarray, c: int, x: np.ndarray) -> np.ndarray:
    """Curve ``c`` at points ``x`` (n, V), per variant, linearly extrapolated beyond its end knots."""
    a, b = int(off[c]), int(off[c + 1])
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        s = np.diff(cy[a:b], axis=0) / np.diff(cx[a:b], axis=0)  # (segments, V)
        y = cy[a] + s[0] * (x - cx[a])
        for k in range(1, b - a - 1):  # the ramp sum: each interior knot adds its slope change beyond it
            y = y + (s[k] - s[k - 1]) * np.maximum(0.0, x - cx[a + k])
    return y


def rate_damping(
    cx: np.ndarray, cy: np.ndarray, off: np.ndarray, curves: np.ndarray, rates: np.ndarray
) -> np.ndarray:
    """``rate_elastic``'s damping bound per variant: the steepest force change per unit rate,
    ``max |C_{k+1}(e) - C_k(e)| / (r_{k+1} - r_k)`` over neighbouring curves and the elongations both
    curves draw (the difference is piecewise linear with its kinks at their knots, so the knots of both
    give its maximum there). ``curves`` (n,) the spring's curves in rate order, ``rates`` (n, V)."""
    c_eff = np.zeros(cx.shape[1])
    for k in range(len(curves) - 1):
        c0, c1 = int(curves[k]), int(curves[k + 1])
        x = np.concatenate([cx[int(off[c0]) : int(off[c0 + 1])], cx[int(off[c1]) : int(off[c1 + 1])]])
        with np.errstate(
            divide="ignore", invalid="ignore", over="ignore"
        ):  # a bad curve is refused elsewhere
            gap = np.max(np.abs(curve_values(cx, cy, off, c1, x) - curve_values(cx, cy, off, c0, x)), axis=0)
            c_eff = np.maximum(c_eff, gap / (rates[k + 1] - rates[k]))
    return c_eff


def spring_stiffness_bound(
    topo: Topology, k: np.ndarray, cx: np.ndarray, cy: np.ndarray, rates: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """(k_max, c) per spring and variant, shape (S, V): steepest usable slope and damping.
    ``rates`` (R, V): the rates of the ``rate_elastic`` curves (parameter block ``rate``; None: none)."""
    S = topo.n_springs
    V = k.shape[1] if k.ndim == 2 else cx.shape[1]
    kmax = np.zeros((S, V))
    damp = np.zeros((S, V))
    off = topo.curve_offsets
    for s in range(S):
        rule = spec(topo.material[s]).step  # the material table's stable-step rule
        c0, c1 = topo.spring_curves[s]
        if rule == "stiffness":  # elastoplastic: K bounds the tangent KT and the unloading slope
            kmax[s] = k[s]
        elif rule == "curve_damping":  # the steepest slope of the force vs rate curve acts as c
            damp[s] = curve_max_slope(cx, cy, off, c0)
        elif rule == "damping":
            damp[s] = k[s]
        elif rule == "curve_slope":
            kmax[s] = curve_max_slope(cx, cy, off, c0)
        elif rule == "curve_slopes":  # every curve of the material
            kmax[s] = np.maximum(curve_max_slope(cx, cy, off, c0), curve_max_slope(cx, cy, off, c1))
        elif rule == "curve_slope_or_stiffness":  # crush: its curve or its unloading stiffness
            kmax[s] = np.maximum(curve_max_slope(cx, cy, off, c0), k[s])
        elif rule == "rate_curves":  # rate_elastic: a spring (any curve's steepest slope) and a damper
            ro = topo.rate_offsets if topo.rate_offsets is not None else np.zeros(S + 1, dtype=np.int64)
            mine = topo.rate_curves[int(ro[s]) : int(ro[s + 1])]
            for c in mine:
                kmax[s] = np.maximum(kmax[s], curve_max_slope(cx, cy, off, int(c)))
            if len(mine) > 1 and rates is not None:  # c = dF/d(rate) between the curves
                damp[s] = rate_damping(cx, cy, off, mine, rates[int(ro[s]) : int(ro[s + 1])])
    return kmax, damp


def critical_steps(
    topo: Topology, mass: np.ndarray, kmax: np.ndarray, damp: np.ndarray, wall_k: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """(dt_crit, the controlling node or -1), each (V,): the nodal bound of the module docstring, what
    :func:`choose_steps` and the pre-run check of a fixed ``dt`` (:func:`dt_refused`) both use.
    ``mass`` (N, V); ``kmax``, ``damp`` (S, V); ``wall_k`` (W, V) or None."""
    N, V = mass.shape
    K = np.zeros((N, V))
    i, j = topo.spring_nodes[:, 0], topo.spring_nodes[:, 1]
    for s in range(len(i)):  # row adds over the variants (np.add.at is ~10x slower for few springs)
        K[i[s]] += kmax[s]
        K[j[s]] += kmax[s]
    for w in range(len(wall_k) if wall_k is not None else 0):
        assert wall_k is not None
        K[np.asarray(topo.wall_nodes[w], dtype=bool)] += PENALTY_SHARE * wall_k[w]
    movable = np.asarray(~topo.fixed.all(axis=1))
    damped = bool(np.any(damp != 0))
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        m = np.where(movable[:, None], mass, np.inf)
        omega = np.sqrt(2.0 * K / m)
        if damped or not np.all(m > 0):  # a damper (or a zero / NaN mass, gamma = 0/0): the damped limit
            Cn = np.zeros((N, V))
            for s in range(len(i)):
                Cn[i[s]] += damp[s]
                Cn[j[s]] += damp[s]
            gamma = 2.0 * Cn / m  # nodal bound on the damping rate, like 2 K_n / m_n for the stiffness
            xi = np.where(omega > 0, gamma / omega, np.inf)
            dt_node = np.where(
                omega > 0,
                (2.0 / omega) * (np.sqrt(1.0 + xi * xi) - xi),
                np.where(gamma > 0, 1.0 / gamma, np.inf),
            )
        else:  # gamma = 0 everywhere: the same limit with xi = 0, (2 / omega) * 1.0, bitwise
            dt_node = np.where(omega > 0, 2.0 / omega, np.inf)
    dt_node = np.where(np.isfinite(dt_node), CRITICAL_MARGIN * dt_node, np.inf)
    if not N:
        return np.full(V, np.inf), np.full(V, -1, dtype=np.int64)
    ctrl = np.argmin(dt_node, axis=0)
    dt_crit = np.min(dt_node, axis=0)  # the value at ctrl (no NaN in dt_node)
    return dt_crit, np.where(np.isfinite(dt_crit), ctrl, -1).astype(np.int64)


def dt_refused(dt: np.ndarray, dt_crit: np.ndarray) -> np.ndarray:
    """Bool (V,): a fixed step ``dt`` above the critical step (beyond rounding)."""
    return dt > dt_crit * (1.0 + 1e-12)


def choose_steps(
    topo: Topology,
    mass: np.ndarray,
    kmax: np.ndarray,
    damp: np.ndarray,
    end_time: np.ndarray,
    step_value: np.ndarray,
    interval: float,
    time_curve_spacing: np.ndarray,
    wall_k: np.ndarray | None = None,
) -> StepChoice:
    """Choose the step of every variant.

    Parameters
    ----------
    mass : (N, V) nodal masses [mass]; kmax, damp : (S, V) [force/length], [force*time/length].
    end_time, step_value : (V,) end time [time] and the ``time_step`` value of the topology's mode.
    interval : history sampling interval [time]; the step divides it exactly.
    time_curve_spacing : (V,) shortest segment of any load/prescribed-motion curve [time] (inf if none).
    wall_k : (W, V) contact stiffness of each wall [force/length] (0: rigid); None: no penalty wall.
    """
    N, V = mass.shape
    i, j = topo.spring_nodes[:, 0], topo.spring_nodes[:, 1]
    dt_crit, ctrl = critical_steps(topo, mass, kmax, damp, wall_k)
    # stiffest spring at the controlling node
    ctrl_spring = np.full(V, -1, dtype=np.int64)
    if topo.n_springs:
        at = (i[:, None] == ctrl[None, :]) | (j[:, None] == ctrl[None, :])
        score = np.where(at, kmax + damp, -1.0)
        best = np.argmax(score, axis=0)
        ctrl_spring = np.where(at[best, np.arange(V)], best, -1)

    mode = topo.time_step_mode
    refused = np.zeros(V, dtype=bool)
    if mode == "safety_factor":
        dt = step_value * dt_crit
    elif mode == "dt":
        dt = step_value.copy()
        refused = dt_refused(dt, dt_crit)
    else:
        dt = np.minimum(dt_crit, TOLERANCE_FACTOR * np.sqrt(step_value / 2.0) * dt_crit)
        dt = np.minimum(dt, 0.25 * time_curve_spacing)
    # a model with nothing stiff (free flight): step at the sampling interval / 10
    dt = np.where(np.isfinite(dt), dt, interval / 10.0)
    # a step of 0 (stiffness / mass overflowed) or a count beyond int64: refused, never cast to garbage
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        every = np.maximum(1, np.ceil(interval / dt - 1e-9))
        steps = np.ceil(end_time / (interval / every) - 1e-9)
        too_many = ~(every <= MAX_STEPS) | ~(steps <= MAX_STEPS)
        out_every = np.where(too_many, 1, every).astype(np.int64)
        dt = interval / out_every
        n_steps = np.where(too_many, 0, np.ceil(end_time / dt - 1e-9)).astype(np.int64)
    return StepChoice(dt, dt_crit, ctrl.astype(np.int64), ctrl_spring, out_every, n_steps, refused, too_many)
