"""A batch of variants as the kernel sees it: contiguous arrays, variants on the last axis.

:func:`build_batch` derives everything the kernel needs from a topology and a parameter matrix
``P`` (n_params, V): masses, initial state, curve ramp coefficients, unit wall normals and the time
step of every variant. Nothing here knows about YAML or pydantic.

Curves are evaluated branch-free as a sum of ramps,
``y(e) = y_0 + s_0 (e - x_0) + sum_k ds_k max(0, e - x_k)`` over the interior knots ``k``, which is
the piecewise-linear interpolant with linear extrapolation beyond both ends.

Knot peaks: between knots a curve is linear, so along an elongation path the largest |force| is at
the path's ends or at an interior knot that is a local maximum of |curve|. ``knot_y`` holds those
knots' forces per variant (0 elsewhere) and ``knot_check`` marks the knots that are such a maximum
for at least one variant; the kernels test only those (see docs/solver.md, "Peaks").
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, fields

import numpy as np

from crashstudy.arrays.compiler import (
    CRUSH,
    DAMPER,
    ELASTOPLASTIC,
    GENERAL,
    LINEAR,
    MATERIAL_CODES,
    NONLINEAR,
    NONLINEAR_DAMPER,
    Topology,
)
from crashstudy.arrays.timestep import MAX_STEPS, StepChoice, choose_steps, spring_stiffness_bound
from crashstudy.kernel.preload import preload
from crashstudy.schema.signs import (
    SIGNED_TYPES,
    behind_message,
    depth_behind_walls,
    sign_message,
    wrong_sign_points,
)
from crashstudy.units import UNIT_SYSTEMS

MATERIAL_NAMES = {code: name for name, code in MATERIAL_CODES.items()}


@dataclass
class Batch:
    """Kernel input. Shapes use N nodes, D axes, S springs, C curves, K knots in all, V variants."""

    # shared topology (int64 / float64)
    spring_i: np.ndarray  # (S,)
    spring_j: np.ndarray  # (S,)
    material: np.ndarray  # (S,)
    curve_a: np.ndarray  # (S,) loading / elastic curve index, -1 none
    curve_b: np.ndarray  # (S,) unloading curve index, -1 none
    curve_off: np.ndarray  # (C + 1,)
    free: np.ndarray  # (N, D) 1.0 where the dof moves under forces, else 0.0
    load_node: np.ndarray  # (L,)
    load_curve: np.ndarray  # (L,)
    pm_node: np.ndarray  # (P,)
    pm_dir: np.ndarray  # (P,)
    pm_kind: np.ndarray  # (P,)
    pm_curve: np.ndarray  # (P,)
    wall_nodes: np.ndarray  # (W, N) float 1.0 / 0.0
    # per variant
    mass: np.ndarray  # (N, V) [mass]
    inv_mass: np.ndarray  # (N, D, V) 1/m on free dofs, 0 elsewhere [1/mass]
    x0: np.ndarray  # (N, D, V) initial positions [length]
    v0: np.ndarray  # (N, D, V) initial velocities [length/time]
    length0: np.ndarray  # (S, V) initial spring length [length]
    sign: np.ndarray  # (S, V) 1-D orientation s = sign(X_j - X_i)
    kpar: np.ndarray  # (S, V) stiffness / damping / unloading stiffness
    yield_t: np.ndarray  # (S, V) tension yield [force] (+inf: never)
    yield_c: np.ndarray  # (S, V) compression yield [force] (-inf: never)
    cx: np.ndarray  # (K, V) knot abscissae
    cy: np.ndarray  # (K, V) knot ordinates
    cds: np.ndarray  # (K, V) slope increment at interior knots (0 at the two ends)
    cs0: np.ndarray  # (C, V) slope of the first segment
    cs1: np.ndarray  # (C, V) slope of the last segment
    gravity: np.ndarray  # (D, V) [length/time^2]
    load_force: np.ndarray  # (L, D, V) [force]
    pm_scale: np.ndarray  # (P, V)
    wall_point: np.ndarray  # (W, D, V) [length]
    wall_normal: np.ndarray  # (W, D, V) unit normal
    wall_stiffness: np.ndarray  # (W, V) contact stiffness [force/length]: 0 a rigid wall, > 0 a penalty wall
    dt: np.ndarray  # (V,) [time]
    n_steps: np.ndarray  # (V,) int
    out_every: np.ndarray  # (V,) int
    ke_fraction: np.ndarray  # (V,) termination threshold on KE / KE0 (0: no early termination)
    min_time: np.ndarray  # (V,) [time]
    invalid: np.ndarray  # (V,) int reason code: 0 ok, see INVALID_REASONS
    energy_floor: np.ndarray  # (V,) [energy] round-off floor of the instability test (1e-9 of the model's scale)
    knot_y: np.ndarray  # (K, V) [force] cy at interior knots of a spring curve that are a local maximum of
    # |curve| for that variant (|y| >= |y| of both neighbour knots, y != 0, not flat on both sides), else 0.0
    knot_check: np.ndarray  # (K,) bool, shared: knot_y[k] != 0 for some variant (only these knots are tested)
    # (V,) int, odd: steps per block of the metric nodes' record (crash criteria); row r of the record holds the
    # mean of a^n over the steps n with (n + (k - 1) // 2) // k == r, centred on t = r k dt (1: every step)
    rec_block: np.ndarray
    # SPEC v2 spring features
    ktan: np.ndarray  # (S, V) elastoplastic tangent stiffness KT [force/length] (0 for other materials)
    fy: np.ndarray  # (S, V) elastoplastic yield force FY [force] (0 for other materials)
    e0: np.ndarray  # (S, V) initial elongation [length]
    fail_t: np.ndarray  # (S, V) tension failure elongation [length] (+inf: never)
    fail_c: np.ndarray  # (S, V) compression failure elongation [length] (-inf: never)
    state0: np.ndarray  # (S, NSTATE, V) material state at t = 0 (kernel.preload), (0, NSTATE, V) if no preload
    ie0: np.ndarray  # (S, V) [energy] energy stored in each spring at t = 0 (IE0)
    rate0: np.ndarray  # (S, V) [length/time] elongation rate at t = 0 (a preload's first half step)
    # a curve's shape and its per-variant factors (curve_shapes): cx = bx xs, cy = by ys, slopes = shape's slopes ys/xs
    bx: np.ndarray  # (K, V) knot abscissae as written
    by: np.ndarray  # (K, V) knot ordinates as written
    cfac: np.ndarray  # (3, C, V) force scale ys, abscissa scale xs, slope factor ys / xs

    @property
    def n_variants(self) -> int:
        return int(self.dt.shape[0])

    def take(self, idx: np.ndarray) -> Batch:
        """The sub-batch of variants ``idx`` (arrays copied contiguous)."""
        out = {}
        V = self.n_variants
        for f in fields(self):
            a = getattr(self, f.name)
            if f.name in _SHARED:
                out[f.name] = a
            else:
                assert a.shape[-1] == V, f.name
                out[f.name] = np.ascontiguousarray(a[..., idx])
        return Batch(**out)


_SHARED = {"spring_i", "spring_j", "material", "curve_a", "curve_b", "curve_off", "free", "load_node",
           "load_curve", "pm_node", "pm_dir", "pm_kind", "pm_curve", "wall_nodes", "knot_check"}  # fmt: skip

INVALID_REASONS = {
    1: "fixed dt is above the critical step",
    2: "a curve's x is not strictly increasing",
    3: "a node needs mass > 0",
    4: "a spring has zero initial length",
    5: "a wall normal is the zero vector",
    6: "end_time must be > 0",
    7: f"more than {MAX_STEPS:.2g} time steps (end_time / dt, or the sampling interval / dt): the step is too small "
       "for end_time; check the masses, stiffnesses and end_time",
}


def build_batch(topo: Topology, P: np.ndarray, interval: float) -> tuple[Batch, StepChoice]:
    """Derive the kernel arrays for the variants in ``P`` (n_params, V)."""
    b = topo.blocks
    V = P.shape[1]
    N, D, S = topo.n_nodes, topo.dim, topo.n_springs
    mass = np.ascontiguousarray(P[b["mass"]])
    x0 = np.ascontiguousarray(P[b["position"]].reshape(N, D, V))
    v0 = np.ascontiguousarray(P[b["velocity"]].reshape(N, D, V))
    free = (~topo.fixed).astype(np.float64)
    if len(topo.pm_node):
        free[topo.pm_node, topo.pm_dir] = 0.0
    invalid = np.zeros(V, dtype=np.int64)
    movable = np.asarray(~topo.fixed.all(axis=1))
    bad_mass = np.any(movable[:, None] & ~(mass > 0), axis=0)
    with np.errstate(divide="ignore"):
        inv_mass = np.where((free[:, :, None] > 0) & (mass[:, None, :] > 0), 1.0 / mass[:, None, :], 0.0)

    i, j = topo.spring_nodes[:, 0], topo.spring_nodes[:, 1]
    dx = x0[j] - x0[i]  # (S, D, V)
    length0 = np.sqrt(np.sum(dx * dx, axis=1))
    sign = np.sign(dx[:, 0, :]) if D == 1 else np.ones((S, V))

    bx, by, cfac = curve_shapes(topo, P)
    cx, cy = curve_points(topo, P)
    off = topo.curve_offsets
    C = len(topo.curve_ids)
    cds = np.zeros_like(cx)
    cs0 = np.zeros((C, V))
    cs1 = np.zeros((C, V))
    bad_curve = np.zeros(V, dtype=bool)
    for c in range(C):  # the shape's slopes times the variant's slope factor (one law: kernel.gen_shape)
        a, e = int(off[c]), int(off[c + 1])
        dxk = np.diff(bx[a:e], axis=0)
        bad_curve |= np.any(~(np.diff(cx[a:e], axis=0) > 0), axis=0)
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            shape = np.diff(by[a:e], axis=0) / dxk
            cs0[c], cs1[c] = shape[0] * cfac[2, c], shape[-1] * cfac[2, c]
            cds[a + 1 : e - 1] = np.diff(shape, axis=0) * cfac[2, c]

    kpar = np.ascontiguousarray(P[b["k"]])
    ktan, fy, e0 = (np.ascontiguousarray(P[b[k]]) for k in ("kt", "fy", "e0"))
    yield_t, yield_c = np.ascontiguousarray(P[b["ty"]]), np.ascontiguousarray(P[b["cy"]])
    with np.errstate(all="ignore"):  # a variant with bad parameters is refused by check_parameters
        state0, ie0 = preload(topo.material, topo.spring_curves[:, 0], topo.spring_curves[:, 1], e0, kpar, yield_t,
                              yield_c, ktan, fy, cx, cy, cds, cs0, cs1, off)  # fmt: skip
    kmax, damp = spring_stiffness_bound(topo, kpar, cx, cy)
    W = len(topo.wall_ids)
    normal = P[b["wall_normal"]].reshape(W, D, V)
    nlen = np.sqrt(np.sum(normal * normal, axis=1))
    bad_normal = np.any(nlen == 0, axis=0)
    with np.errstate(divide="ignore", invalid="ignore"):
        unit = np.where(nlen[:, None, :] > 0, normal / nlen[:, None, :], 0.0)
    end_time = P[b["end_time"].start]
    spacing = time_curve_spacing(topo, cx)
    wall_k = np.ascontiguousarray(P[b["wall_k"]])
    steps = choose_steps(topo, mass, kmax, damp, end_time, P[b["time_step"].start], interval, spacing, wall_k)

    too_many = steps.too_many if steps.too_many is not None else np.zeros(V, dtype=bool)
    for code, bad in ((7, too_many), (6, ~(end_time > 0)), (5, bad_normal), (4, np.any(length0 == 0, axis=0)),
                      (3, bad_mass), (2, bad_curve), (1, steps.refused)):  # fmt: skip
        invalid = np.where(bad, code, invalid)
    steps.n_steps = np.where(invalid > 0, 0, steps.n_steps)

    batch = Batch(
        spring_i=i.copy(), spring_j=j.copy(), material=topo.material, curve_a=topo.spring_curves[:, 0].copy(),
        curve_b=topo.spring_curves[:, 1].copy(), curve_off=off, free=free, load_node=topo.load_node,
        load_curve=topo.load_curve, pm_node=topo.pm_node, pm_dir=topo.pm_dir, pm_kind=topo.pm_kind,
        pm_curve=topo.pm_curve, wall_nodes=topo.wall_nodes.astype(np.float64),
        mass=mass, inv_mass=np.ascontiguousarray(inv_mass), x0=x0, v0=v0, length0=length0,
        sign=np.ascontiguousarray(sign), kpar=kpar, yield_t=yield_t, yield_c=yield_c, cx=cx, cy=cy, cds=cds, cs0=cs0, cs1=cs1,
        gravity=np.ascontiguousarray(P[b["gravity"]].reshape(D, V)) if topo.has_gravity else np.zeros((D, V)),
        load_force=np.ascontiguousarray(P[b["load"]].reshape(len(topo.load_node), D, V)),
        pm_scale=np.ascontiguousarray(P[b["pm_scale"]]),
        wall_point=np.ascontiguousarray(P[b["wall_point"]].reshape(W, D, V)),
        wall_normal=np.ascontiguousarray(unit), wall_stiffness=wall_k, dt=steps.dt, n_steps=steps.n_steps,
        out_every=steps.out_every, ke_fraction=P[b["ke_fraction"].start].copy(),
        min_time=P[b["min_time"].start].copy(), invalid=invalid,
        energy_floor=_energy_floor(kmax, length0, mass, v0), rec_block=np.ones(V, dtype=np.int64),
        **knot_peaks(topo, cx, cy),
        ktan=ktan, fy=fy, e0=e0, fail_t=np.ascontiguousarray(P[b["fail_t"]]),
        fail_c=np.ascontiguousarray(P[b["fail_c"]]), state0=state0, ie0=ie0, rate0=_rate0(dx, length0, v0, i, j),
        bx=bx, by=by, cfac=cfac,
    )  # fmt: skip
    return batch, steps


def curve_shapes(topo: Topology, P: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The curves' points as written (their shape, (K, V) x and y) and each variant's factors
    ``cfac`` (3, C, V): force scale ``ys``, abscissa scale ``xs`` and slope factor ``ys / xs``
    (``curves.<id>.scale`` and ``x_scale``)."""
    b, V, C = topo.blocks, P.shape[1], len(topo.curve_ids)
    fac = P[b["cfac"]].reshape(C, 2, V) if "cfac" in b else np.ones((C, 2, V))
    with np.errstate(all="ignore"):
        cfac = np.ascontiguousarray(np.stack([fac[:, 0], fac[:, 1], fac[:, 0] / fac[:, 1]]))
    return np.ascontiguousarray(P[b["cx"]]), np.ascontiguousarray(P[b["cy_"]]), cfac


def curve_points(topo: Topology, P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The curves' points of each variant, (K, V) x and y: the shape's points times the variant's
    abscissa and force scales (what every check and every kernel sees)."""
    bx, by, cfac = curve_shapes(topo, P)
    c = np.repeat(np.arange(len(topo.curve_ids)), np.diff(topo.curve_offsets))
    with np.errstate(over="ignore", invalid="ignore"):
        return bx * cfac[1, c], by * cfac[0, c]


def _rate0(dx: np.ndarray, length0: np.ndarray, v0: np.ndarray, i: np.ndarray, j: np.ndarray) -> np.ndarray:
    """(S, V) elongation rate at t = 0: ``s (v_j - v_i)`` in 1-D, the unit axis times ``v_j - v_i`` in 2-D
    (summed over the axes in order, as the kernels sum it)."""
    dv = v0[j] - v0[i]  # (S, D, V)
    if dx.shape[1] == 1:
        return np.ascontiguousarray(np.sign(dx[:, 0, :]) * dv[:, 0, :])
    with np.errstate(divide="ignore", invalid="ignore"):
        axis = dx / np.where(length0 > 0, length0, 1.0)[:, None, :]
    out = np.zeros(length0.shape)
    for d in range(dx.shape[1]):
        out = out + axis[:, d, :] * dv[:, d, :]
    return out


def knot_peaks(topo: Topology, cx: np.ndarray, cy: np.ndarray) -> dict[str, np.ndarray]:
    """``knot_y`` (K, V) and ``knot_check`` (K,) of :class:`Batch` (see the module docstring).

    Only the interior knots of curves that springs follow by elongation (``nonlinear_elastic``, the
    loading curve of ``crush`` and ``general_nonlinear``) can be flagged. A knot whose |curve| is flat on
    one side (a plateau's end) is flagged too: a step can pass over a whole plateau between two samples.
    """
    K, V = cx.shape
    knot_y = np.zeros((K, V))
    off = topo.curve_offsets
    curves = {int(topo.spring_curves[s, 0]) for s in range(topo.n_springs)
              if topo.material[s] in (NONLINEAR, CRUSH, GENERAL) and topo.spring_curves[s, 0] >= 0}  # fmt: skip
    for c in curves:
        a, e = int(off[c]), int(off[c + 1])
        for k in range(a + 1, e - 1):
            y, yl, yr = cy[k], cy[k - 1], cy[k + 1]
            sg = np.sign(y)
            with np.errstate(invalid="ignore"):
                peak = (y != 0) & (sg * (y - yl) >= 0) & (sg * (y - yr) >= 0) & ~((y == yl) & (y == yr))
            knot_y[k] = np.where(peak, y, 0.0)
    return {"knot_y": knot_y, "knot_check": np.any(knot_y != 0.0, axis=1)}


def _energy_floor(kmax: np.ndarray, length0: np.ndarray, mass: np.ndarray, v0: np.ndarray) -> np.ndarray:
    """1e-9 of the model's energy scale (springs' k L0^2 and the initial m v0^2), per variant."""
    with np.errstate(over="ignore", invalid="ignore"):
        return 1e-9 * (np.sum(kmax * length0 * length0, axis=0) + np.sum(mass[:, None, :] * v0 * v0, axis=(0, 1)))


def time_curve_spacing(topo: Topology, cx: np.ndarray) -> np.ndarray:
    """Per-variant shortest segment of the load / prescribed-motion curves [time], (V,)."""
    ids = {int(c) for c in topo.load_curve if c >= 0} | {int(c) for c in topo.pm_curve}
    V = cx.shape[1]
    out = np.full(V, np.inf)
    for c in ids:
        a, e = int(topo.curve_offsets[c]), int(topo.curve_offsets[c + 1])
        out = np.minimum(out, np.min(np.diff(cx[a:e], axis=0), axis=0))
    return out


@dataclass
class ParameterCheck:
    """Which variants of a parameter matrix break a rule of the model schema (see :func:`check_parameters`)."""

    bad: np.ndarray  # (V,) bool
    rules: list[tuple[np.ndarray, Callable[[int, int], str]]]  # (R, V) broken-rule masks, text(row, column)

    def reason(self, column: int) -> str:
        """What the first broken rule of variant ``column`` expected (``""`` if it breaks none)."""
        for mask, text in self.rules:
            if mask[:, column].any():
                return text(int(np.argmax(mask[:, column])), column)
        return ""


def check_parameters(topo: Topology, P: np.ndarray, interval: float) -> ParameterCheck:
    """The rules a model file obeys, checked on the parameter matrix ``P`` (n_params, V), vectorised.

    The same rules as the schema (:mod:`crashstudy.schema`: signs and ranges of fields, curves
    strictly increasing, every material curve through the origin, an increasing unloading curve and a
    non-decreasing damper curve, a crush curve with a compression part, failure elongations on either
    side of the initial elongation, non-zero spring lengths and wall normals, no initial
    velocity along a fixed axis, output.interval <= end_time) plus what only numbers can break: every
    value finite (a scale factor can overflow) and a step count that fits (:data:`MAX_STEPS`). A study
    checks every distinct value of each axis with it; one value costs a column, not a model validation.
    """
    b, V = topo.blocks, P.shape[1]
    N, D = topo.n_nodes, topo.dim
    name = {ref.slots[0]: path for path, ref in topo.paths.items() if ref.op == "set" and len(ref.slots) == 1}
    rules: list[tuple[np.ndarray, Callable[[int, int], str]]] = []

    def rule(mask: np.ndarray, text: Callable[[int, int], str]) -> None:
        rules.append((np.asarray(mask, dtype=bool).reshape(-1, V), text))

    def ranged(block: str, rows: np.ndarray, bad: np.ndarray, expect: str) -> None:
        start = b[block].start
        rule(bad[rows], lambda r, c: f"{name.get(start + int(rows[r]), block)}: expected {expect}, "
             f"got {P[start + int(rows[r]), c]:g}")  # fmt: skip

    unbounded = ("ty", "cy", "fail_t", "fail_c")  # +-inf: never yields / never breaks
    plain = np.array([s for blk, sl in b.items() if blk not in unbounded for s in range(sl.start, sl.stop)], dtype=np.int64)
    rule(~np.isfinite(P[plain]), lambda r, c: f"{name.get(int(plain[r]), 'a parameter')} is not finite "
         f"({P[plain[r], c]:g}): an axis value or a scale factor made it overflow")  # fmt: skip
    mass = P[b["mass"]]
    movable = np.asarray(~topo.fixed.all(axis=1), dtype=bool)
    ranged("mass", np.arange(N), (movable[:, None] & ~(mass > 0)) | (mass < 0), "a mass > 0")
    k, mat = P[b["k"]], topo.material
    stiff, damper, general = np.isin(mat, (LINEAR, CRUSH, ELASTOPLASTIC)), mat == DAMPER, mat == GENERAL
    ranged("k", np.flatnonzero(stiff), ~(k > 0), "a value > 0")
    ranged("k", np.flatnonzero(damper), ~(k >= 0), "a value >= 0")
    ranged("ty", np.flatnonzero(general), ~(P[b["ty"]] > 0), "a tension_yield > 0")
    ranged("cy", np.flatnonzero(general), ~(P[b["cy"]] < 0), "a compression_yield < 0")
    _v2_rules(topo, P, rule, ranged)
    _curve_rules(topo, P, rule)
    x0 = P[b["position"]].reshape(N, D, V)
    dx = x0[topo.spring_nodes[:, 1]] - x0[topo.spring_nodes[:, 0]]
    rule(np.all(dx == 0, axis=1), lambda r, c: f"springs.{topo.spring_ids[r]}: its nodes are at the same position "
         "(a spring needs a non-zero initial length)")  # fmt: skip
    v0 = P[b["velocity"]].reshape(N * D, V)
    fixed = np.flatnonzero(topo.fixed.reshape(-1))
    rule(v0[fixed] != 0, lambda r, c: f"initial_velocity.{topo.node_ids[fixed[r] // D]}.{fixed[r] % D}: the node is "
         "fixed along this axis; its initial velocity there must be 0")  # fmt: skip
    normal = P[b["wall_normal"]].reshape(len(topo.wall_ids), D, V)
    rule(np.all(normal == 0, axis=1), lambda r, c: f"rigid_walls.{r}.normal must not be the zero vector")
    _wall_side_rule(topo, P, x0, normal, rule)
    end, step = P[b["end_time"].start], P[b["time_step"].start]
    rule(~(end > 0), lambda r, c: f"end_time: expected a value > 0, got {end[c]:g}")
    if topo.output_interval is not None:
        rule(~(end >= topo.output_interval), lambda r, c: f"end_time: expected an end_time no shorter than "
             f"output.interval ({topo.output_interval:g}), got {end[c]:g}")  # fmt: skip
    low, high = {"safety_factor": (0.0, 1.0), "dt": (0.0, np.inf), "tolerance": (0.0, 1.0)}[topo.time_step_mode]
    ok = (step > low) & ((step <= high) if topo.time_step_mode == "safety_factor" else (step < high))
    rule(~ok, lambda r, c: f"time_step.{topo.time_step_mode}: expected a value in ({low:g}, {high:g}"
         f"{']' if topo.time_step_mode == 'safety_factor' else ')'}, got {step[c]:g}")  # fmt: skip
    if topo.termination:
        f, t = P[b["ke_fraction"].start], P[b["min_time"].start]
        rule(~((f > 0) & (f < 1)), lambda r, c: f"termination.kinetic_energy_fraction: expected a value in (0, 1), got {f[c]:g}")
        rule(~(t >= 0), lambda r, c: f"termination.min_time: expected a value >= 0, got {t[c]:g}")
    bad = np.zeros(V, dtype=bool)
    for mask, _ in rules:
        bad |= mask.any(axis=0)
    pcx, pcy = curve_points(topo, P)
    kmax, damp = spring_stiffness_bound(topo, k, pcx, pcy)
    steps = choose_steps(topo, mass, kmax, damp, end, step, interval, time_curve_spacing(topo, pcx), P[b["wall_k"]])
    assert steps.too_many is not None
    over = steps.too_many & ~bad  # a variant that breaks another rule has no meaningful step
    def too_small(c: int) -> str:
        n = int(steps.control_node[c])
        crit = ("0: stiffness / mass overflows" if steps.dt_crit[c] == 0 else f"{steps.dt_crit[c]:.3g}") + (
            f", node {topo.node_ids[n]}" if n >= 0 else "")  # fmt: skip
        return (f"end_time {end[c]:g} (sampled every {interval:g}) needs more than {MAX_STEPS:.2g} time steps at the "
                f"critical step ({crit}): check the masses, stiffnesses and end_time")  # fmt: skip

    rule(over, lambda r, c: too_small(c))
    return ParameterCheck(bad | over, rules)


def _v2_rules(topo: Topology, P: np.ndarray, rule: Callable[..., None], ranged: Callable[..., None]) -> None:
    """elastoplastic parameters (K > 0 is checked with the other stiffnesses) and the spring options."""
    b, mat = topo.blocks, topo.material
    k, kt, e0, ft, fc = (P[b[name]] for name in ("k", "kt", "e0", "fail_t", "fail_c"))
    plastic = np.flatnonzero(mat == ELASTOPLASTIC)
    ranged("kt", plastic, ~((kt >= 0) & (kt < k)), "a tangent_stiffness >= 0 and below stiffness")
    ranged("fy", plastic, ~(P[b["fy"]] > 0), "a yield_force > 0")
    every = np.arange(topo.n_springs)
    ranged("fail_t", every, ~(ft > 0), "a tension failure elongation > 0")
    ranged("fail_c", every, ~(fc < 0), "a compression failure elongation < 0")
    ids = topo.spring_ids
    rule((ft > 0) & ~(e0 < ft), lambda r, c: f"springs.{ids[r]}.failure.tension: expected an elongation above "
         f"initial_elongation ({e0[r, c]:g}), got {ft[r, c]:g}: the spring would be broken at t = 0")  # fmt: skip
    rule((fc < 0) & ~(e0 > fc), lambda r, c: f"springs.{ids[r]}.failure.compression: expected an elongation below "
         f"initial_elongation ({e0[r, c]:g}), got {fc[r, c]:g}: the spring would be broken at t = 0")  # fmt: skip


def _wall_side_rule(topo: Topology, P: np.ndarray, x0: np.ndarray, normal: np.ndarray,
                    rule: Callable[..., None]) -> None:  # fmt: skip
    """Every node a wall stops starts on its front side (:func:`~crashstudy.schema.signs.depth_behind_walls`):
    an axis on a node position or a wall point or normal must keep it there."""
    W, D, V = normal.shape
    if not W:
        return
    point = P[topo.blocks["wall_point"]].reshape(W, D, V)
    depth = depth_behind_walls(x0, ~topo.fixed, point, normal, topo.wall_nodes)  # (W, N, V)
    length = UNIT_SYSTEMS[topo.units].length

    def text(r: int, c: int) -> str:
        bad = np.flatnonzero(depth[r, :, c] > 0)
        k = int(bad[0])
        return f"rigid_walls.{r}.point: " + behind_message(topo.node_ids[k], float(depth[r, k, c]),
                                                            topo.wall_ids[r], length, bad.size - 1)

    rule(np.any(depth > 0, axis=1), text)


def _curve_rules(topo: Topology, P: np.ndarray, rule: Callable[..., None]) -> None:
    """Curves: x strictly increasing; every material curve through the origin (a preload is written with
    initial_elongation); the general_nonlinear unloading curve increasing, a nonlinear_damper curve
    non-decreasing; a crush loading curve starting in compression (x < 0)."""
    off = topo.curve_offsets
    cx, cy = curve_points(topo, P)
    ids = topo.curve_ids
    for c, cid in enumerate(ids):
        a, e = int(off[c]), int(off[c + 1])
        xs = cx[a:e]
        for pts, axis in ((xs, "x"), (cy[a:e], "y")):  # a point times its curve's scale
            rule(~np.isfinite(pts), lambda r, col, cid=cid, pts=pts, axis=axis: f"curves.{cid}.{axis}.{r} is not "
                 f"finite ({pts[r, col]:g}): an axis value or a scale factor made it overflow")  # fmt: skip
        rule(~(np.diff(xs, axis=0) > 0), lambda r, col, cid=cid, xs=xs: f"curves.{cid}.x must be strictly increasing "
             f"(x.{r} = {xs[r, col]:g} is followed by {xs[r + 1, col]:g})")  # fmt: skip
    origin: dict[int, str] = {}  # curve -> material type of a spring that uses it
    signed: dict[int, str] = {}  # curve -> a material whose force has the sign of the elongation
    rising, crush, damper = set(), set(), set()
    for s in range(topo.n_springs):
        c0, c1 = (int(v) for v in topo.spring_curves[s])
        kind = int(topo.material[s])
        origin.update({c: MATERIAL_NAMES[kind] for c in (c0, c1) if c >= 0})
        if MATERIAL_NAMES[kind] in SIGNED_TYPES:  # the loading curve (an unloading one is increasing)
            signed[c0] = MATERIAL_NAMES[kind] + (" loading" if kind == GENERAL else "")
        if kind == GENERAL:
            rising.add(c1)
        elif kind == CRUSH:
            crush.add(c0)
        elif kind == NONLINEAR_DAMPER:
            damper.add(c0)
    for c, kind_name in sorted(origin.items()):
        a, e = int(off[c]), int(off[c + 1])
        at0 = _value_at_zero(cx[a:e], cy[a:e])
        scale = np.max(np.abs(cy[a:e]), axis=0)
        scale = np.where(scale > 0, scale, 1.0)
        why = ("a damper carries no force at rest; a preload belongs on a spring, with initial_elongation"
               if kind_name == "nonlinear_damper" else "a spring that carries force at t = 0 says so with "
               "initial_elongation, never with a shifted curve")  # fmt: skip
        rule(np.abs(at0) > 1e-9 * scale, lambda r, col, cid=ids[c], at0=at0, kn=kind_name, why=why: f"curves.{cid} "
             f"must pass through the origin (a {kn} curve; its force at 0 is {at0[col]:g}): {why}")  # fmt: skip
    for c, kind_name in sorted(signed.items()):
        a, e = int(off[c]), int(off[c + 1])
        wrong = wrong_sign_points(cx[a:e], cy[a:e])

        def signed_text(r: int, col: int, cid: str = ids[c], a: int = a, wrong: np.ndarray = wrong,
                        use: str = kind_name) -> str:  # fmt: skip
            k = int(np.argmax(wrong[:, col]))
            return f"curves.{cid}: " + sign_message(cid, k, float(cx[a + k, col]), float(cy[a + k, col]), use)

        rule(np.any(wrong, axis=0), signed_text)
    for c in sorted(rising):
        a, e = int(off[c]), int(off[c + 1])
        rule(~(np.diff(cy[a:e], axis=0) > 0), lambda r, col, cid=ids[c]: f"curves.{cid}.y must be strictly increasing "
             "(the unloading curve of a general_nonlinear spring)")  # fmt: skip
    for c in sorted(damper):
        a, e = int(off[c]), int(off[c + 1])
        rule(~(np.diff(cy[a:e], axis=0) >= 0), lambda r, col, cid=ids[c]: f"curves.{cid}.y must be non-decreasing "
             "(the force vs elongation rate curve of a nonlinear_damper)")  # fmt: skip
    for c in sorted(crush):
        a = int(off[c])
        rule(~(cx[a] < 0), lambda r, col, cid=ids[c], a=a: f"curves.{cid} needs a compression part (x < 0): the "
             f"loading curve of a crush spring starts at x = {cx[a, col]:g}")  # fmt: skip


def _value_at_zero(xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
    """Piecewise-linear value at 0 of curves with knots ``xs``, ``ys`` (n, V), extrapolated along the ends."""
    n, V = xs.shape
    k = np.clip(np.sum(xs <= 0.0, axis=0) - 1, 0, n - 2)
    cols = np.arange(V)
    x0, x1, y0, y1 = xs[k, cols], xs[k + 1, cols], ys[k, cols], ys[k + 1, cols]
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        return y0 + (y1 - y0) / (x1 - x0) * (0.0 - x0)
