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

from dataclasses import dataclass, fields

import numpy as np

from crashstudy.arrays.compiler import Topology
from crashstudy.arrays.preload import preload
from crashstudy.arrays.timestep import (
    MAX_STEPS,
    StepChoice,
    choose_steps,
    critical_steps,
    dt_refused,
    spring_stiffness_bound,
)
from crashstudy.vocabulary.batch_fields import SHARED_FIELDS
from crashstudy.vocabulary.materials import KNOT_MATERIALS


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
    energy_floor: (
        np.ndarray
    )  # (V,) [energy] round-off floor of the instability test (1e-9 of the model's scale)
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
    state0: (
        np.ndarray
    )  # (S, NSTATE, V) material state at t = 0 (arrays.preload), (0, NSTATE, V) if no preload
    ie0: np.ndarray  # (S, V) [energy] energy stored in each spring at t = 0 (IE0)
    rate0: np.ndarray  # (S, V) [length/time] elongation rate at t = 0 (a preload's first half step)
    # a curve's shape and its per-variant factors (curve_shapes): cx = bx xs, cy = by ys, slopes = shape's slopes ys/xs
    bx: np.ndarray  # (K, V) knot abscissae as written
    by: np.ndarray  # (K, V) knot ordinates as written
    cfac: np.ndarray  # (3, C, V) force scale ys, abscissa scale xs, slope factor ys / xs
    # rate_elastic: its curves in rate order, all springs' after another (R,), each spring's range (S + 1,)
    rate_curve: np.ndarray  # (R,) int64 curve index, shared
    rate_off: np.ndarray  # (S + 1,) int64, shared
    rate_at: np.ndarray  # (R, V) [length/time] the rate of each of those curves

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


_SHARED = frozenset(SHARED_FIELDS)

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
        state0, ie0 = preload(
            topo.material,
            topo.spring_curves[:, 0],
            topo.spring_curves[:, 1],
            e0,
            kpar,
            yield_t,
            yield_c,
            ktan,
            fy,
            cx,
            cy,
            cds,
            cs0,
            cs1,
            off,
        )
    kmax, damp, steps = _steps(topo, P, mass, kpar, cx, cy, interval)
    W = len(topo.wall_ids)
    normal = P[b["wall_normal"]].reshape(W, D, V)
    nlen = np.sqrt(np.sum(normal * normal, axis=1))
    bad_normal = np.any(nlen == 0, axis=0)
    with np.errstate(divide="ignore", invalid="ignore"):
        unit = np.where(nlen[:, None, :] > 0, normal / nlen[:, None, :], 0.0)
    end_time = P[b["end_time"].start]
    wall_k = np.ascontiguousarray(P[b["wall_k"]])

    too_many = steps.too_many if steps.too_many is not None else np.zeros(V, dtype=bool)
    for code, bad in (
        (7, too_many),
        (6, ~(end_time > 0)),
        (5, bad_normal),
        (4, np.any(length0 == 0, axis=0)),
        (3, bad_mass),
        (2, bad_curve),
        (1, steps.refused),
    ):
        invalid = np.where(bad, code, invalid)
    steps.n_steps = np.where(invalid > 0, 0, steps.n_steps)

    batch = Batch(
        spring_i=i.copy(),
        spring_j=j.copy(),
        material=topo.material,
        curve_a=topo.spring_curves[:, 0].copy(),
        curve_b=topo.spring_curves[:, 1].copy(),
        curve_off=off,
        free=free,
        load_node=topo.load_node,
        load_curve=topo.load_curve,
        pm_node=topo.pm_node,
        pm_dir=topo.pm_dir,
        pm_kind=topo.pm_kind,
        pm_curve=topo.pm_curve,
        wall_nodes=topo.wall_nodes.astype(np.float64),
        mass=mass,
        inv_mass=np.ascontiguousarray(inv_mass),
        x0=x0,
        v0=v0,
        length0=length0,
        sign=np.ascontiguousarray(sign),
        kpar=kpar,
        yield_t=yield_t,
        yield_c=yield_c,
        cx=cx,
        cy=cy,
        cds=cds,
        cs0=cs0,
        cs1=cs1,
        gravity=np.ascontiguousarray(P[b["gravity"]].reshape(D, V)) if topo.has_gravity else np.zeros((D, V)),
        load_force=np.ascontiguousarray(P[b["load"]].reshape(len(topo.load_node), D, V)),
        pm_scale=np.ascontiguousarray(P[b["pm_scale"]]),
        wall_point=np.ascontiguousarray(P[b["wall_point"]].reshape(W, D, V)),
        wall_normal=np.ascontiguousarray(unit),
        wall_stiffness=wall_k,
        dt=steps.dt,
        n_steps=steps.n_steps,
        out_every=steps.out_every,
        ke_fraction=P[b["ke_fraction"].start].copy(),
        min_time=P[b["min_time"].start].copy(),
        invalid=invalid,
        energy_floor=_energy_floor(kmax, length0, mass, v0),
        rec_block=np.ones(V, dtype=np.int64),
        **knot_peaks(topo, cx, cy),
        ktan=ktan,
        fy=fy,
        e0=e0,
        fail_t=np.ascontiguousarray(P[b["fail_t"]]),
        fail_c=np.ascontiguousarray(P[b["fail_c"]]),
        state0=state0,
        ie0=ie0,
        rate0=_rate0(dx, length0, v0, i, j),
        bx=bx,
        by=by,
        cfac=cfac,
        rate_curve=topo.rate_curves,
        rate_off=_rate_offsets(topo),
        rate_at=np.ascontiguousarray(P[b["rate"]]) if "rate" in b else np.zeros((0, V)),
    )
    return batch, steps


def _steps(
    topo: Topology,
    P: np.ndarray,
    mass: np.ndarray,
    kpar: np.ndarray,
    cx: np.ndarray,
    cy: np.ndarray,
    interval: float,
) -> tuple[np.ndarray, np.ndarray, StepChoice]:
    """(k_max, damping, the step choice) of the variants in ``P``: what :func:`build_batch` and
    :func:`variant_steps` both use."""
    b = topo.blocks
    kmax, damp = _bounds(topo, P, kpar, cx, cy)
    steps = choose_steps(
        topo,
        mass,
        kmax,
        damp,
        P[b["end_time"].start],
        P[b["time_step"].start],
        interval,
        time_curve_spacing(topo, cx),
        np.ascontiguousarray(P[b["wall_k"]]),
    )
    return kmax, damp, steps


def _bounds(
    topo: Topology, P: np.ndarray, kpar: np.ndarray, cx: np.ndarray, cy: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """(k_max, damping) of each spring and variant of ``P`` (the rate curves' rates from ``P``)."""
    b = topo.blocks
    return spring_stiffness_bound(topo, kpar, cx, cy, P[b["rate"]] if "rate" in b else None)


def variant_steps(topo: Topology, P: np.ndarray, interval: float) -> StepChoice:
    """The step choice of the variants in ``P`` alone (what ``build_batch(topo, P, interval)[1]`` holds),
    without the rest of the batch: the runner's step order and the study's work estimate."""
    cx, cy = curve_points(topo, P)
    b = topo.blocks
    return _steps(
        topo, P, np.ascontiguousarray(P[b["mass"]]), np.ascontiguousarray(P[b["k"]]), cx, cy, interval
    )[2]


def fixed_dt_check(topo: Topology, P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(refused, dt_crit) of the variants in ``P`` under a fixed ``dt``: ``variant_steps``'s ``refused``
    and ``dt_crit`` through the same :func:`~crashstudy.arrays.timestep.critical_steps`, without the rest
    of the step choice (controlling spring, sample and step counts): the pre-run check (study.sanity)."""
    cx, cy = curve_points(topo, P)
    b = topo.blocks
    kmax, damp = _bounds(topo, P, np.ascontiguousarray(P[b["k"]]), cx, cy)
    dt_crit, _ = critical_steps(
        topo, np.ascontiguousarray(P[b["mass"]]), kmax, damp, np.ascontiguousarray(P[b["wall_k"]])
    )
    return dt_refused(P[b["time_step"].start], dt_crit), dt_crit


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


def _rate_offsets(topo: Topology) -> np.ndarray:
    """(S + 1,) each spring's range in ``topo.rate_curves`` (all empty for a topology without them)."""
    return (
        topo.rate_offsets if topo.rate_offsets is not None else np.zeros(topo.n_springs + 1, dtype=np.int64)
    )


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
    curves = {
        int(topo.spring_curves[s, 0])
        for s in range(topo.n_springs)
        if topo.material[s] in KNOT_MATERIALS and topo.spring_curves[s, 0] >= 0
    }
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
        return 1e-9 * (
            np.sum(kmax * length0 * length0, axis=0) + np.sum(mass[:, None, :] * v0 * v0, axis=(0, 1))
        )


def time_curve_spacing(topo: Topology, cx: np.ndarray) -> np.ndarray:
    """Per-variant shortest segment of the load / prescribed-motion curves [time], (V,)."""
    ids = {int(c) for c in topo.load_curve if c >= 0} | {int(c) for c in topo.pm_curve}
    V = cx.shape[1]
    out = np.full(V, np.inf)
    for c in ids:
        a, e = int(topo.curve_offsets[c]), int(topo.curve_offsets[c + 1])
        out = np.minimum(out, np.min(np.diff(cx[a:e], axis=0), axis=0))
    return out
