"""Which variants of a parameter matrix break a rule of the model schema, checked vectorised on the
parameter matrix (n_params, V): what every distinct study-axis value goes through before a run
(:func:`check_parameters`), with the same rules and wording as the schema's own checks."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from crashstudy.arrays.batch import curve_points, time_curve_spacing
from crashstudy.arrays.compiler import Topology
from crashstudy.arrays.timestep import MAX_STEPS, choose_steps, spring_stiffness_bound
from crashstudy.schema.signs import (
    behind_message,
    depth_behind_walls,
    sign_message,
    wrong_sign_points,
)
from crashstudy.units import UNIT_SYSTEMS
from crashstudy.vocabulary.materials import MATERIALS, spec

SLOT_ORDER = ("k", "ty", "cy", "kt", "fy")  # the order of the material parameter checks' messages


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
        rule(
            bad[rows],
            lambda r, c: (
                f"{name.get(start + int(rows[r]), block)}: expected {expect}, "
                f"got {P[start + int(rows[r]), c]:g}"
            ),
        )

    unbounded = ("ty", "cy", "fail_t", "fail_c")  # +-inf: never yields / never breaks
    plain = np.array(
        [s for blk, sl in b.items() if blk not in unbounded for s in range(sl.start, sl.stop)], dtype=np.int64
    )
    rule(
        ~np.isfinite(P[plain]),
        lambda r, c: (
            f"{name.get(int(plain[r]), 'a parameter')} is not finite "
            f"({P[plain[r], c]:g}): an axis value or a scale factor made it overflow"
        ),
    )
    mass = P[b["mass"]]
    movable = np.asarray(~topo.fixed.all(axis=1), dtype=bool)
    ranged("mass", np.arange(N), (movable[:, None] & ~(mass > 0)) | (mass < 0), "a mass > 0")
    _material_rules(topo, P, ranged)
    _rate_rules(topo, P, rule)
    _option_rules(topo, P, rule, ranged)
    _curve_rules(topo, P, rule)
    x0 = P[b["position"]].reshape(N, D, V)
    dx = x0[topo.spring_nodes[:, 1]] - x0[topo.spring_nodes[:, 0]]
    rule(
        np.all(dx == 0, axis=1),
        lambda r, c: (
            f"springs.{topo.spring_ids[r]}: its nodes are at the same position "
            "(a spring needs a non-zero initial length)"
        ),
    )
    v0 = P[b["velocity"]].reshape(N * D, V)
    fixed = np.flatnonzero(topo.fixed.reshape(-1))
    rule(
        v0[fixed] != 0,
        lambda r, c: (
            f"initial_velocity.{topo.node_ids[fixed[r] // D]}.{fixed[r] % D}: the node is "
            "fixed along this axis; its initial velocity there must be 0"
        ),
    )
    normal = P[b["wall_normal"]].reshape(len(topo.wall_ids), D, V)
    rule(np.all(normal == 0, axis=1), lambda r, c: f"rigid_walls.{r}.normal must not be the zero vector")
    _wall_side_rule(topo, P, x0, normal, rule)
    end, step = P[b["end_time"].start], P[b["time_step"].start]
    rule(~(end > 0), lambda r, c: f"end_time: expected a value > 0, got {end[c]:g}")
    if topo.output_interval is not None:
        rule(
            ~(end >= topo.output_interval),
            lambda r, c: (
                f"end_time: expected an end_time no shorter than "
                f"output.interval ({topo.output_interval:g}), got {end[c]:g}"
            ),
        )
    low, high = {"safety_factor": (0.0, 1.0), "dt": (0.0, np.inf), "tolerance": (0.0, 1.0)}[
        topo.time_step_mode
    ]
    ok = (step > low) & ((step <= high) if topo.time_step_mode == "safety_factor" else (step < high))
    rule(
        ~ok,
        lambda r, c: (
            f"time_step.{topo.time_step_mode}: expected a value in ({low:g}, {high:g}"
            f"{']' if topo.time_step_mode == 'safety_factor' else ')'}, got {step[c]:g}"
        ),
    )
    if topo.termination:
        f, t = P[b["ke_fraction"].start], P[b["min_time"].start]
        rule(
            ~((f > 0) & (f < 1)),
            lambda r, c: f"termination.kinetic_energy_fraction: expected a value in (0, 1), got {f[c]:g}",
        )
        rule(~(t >= 0), lambda r, c: f"termination.min_time: expected a value >= 0, got {t[c]:g}")
    bad = np.zeros(V, dtype=bool)
    for mask, _ in rules:
        bad |= mask.any(axis=0)
    pcx, pcy = curve_points(topo, P)
    kmax, damp = spring_stiffness_bound(topo, P[b["k"]], pcx, pcy, P[b["rate"]] if "rate" in b else None)
    steps = choose_steps(
        topo, mass, kmax, damp, end, step, interval, time_curve_spacing(topo, pcx), P[b["wall_k"]]
    )
    assert steps.too_many is not None
    over = steps.too_many & ~bad  # a variant that breaks another rule has no meaningful step

    def too_small(c: int) -> str:
        n = int(steps.control_node[c])
        crit = ("0: stiffness / mass overflows" if steps.dt_crit[c] == 0 else f"{steps.dt_crit[c]:.3g}") + (
            f", node {topo.node_ids[n]}" if n >= 0 else ""
        )
        return (
            f"end_time {end[c]:g} (sampled every {interval:g}) needs more than {MAX_STEPS:.2g} time steps at the "
            f"critical step ({crit}): check the masses, stiffnesses and end_time"
        )

    rule(over, lambda r, c: too_small(c))
    return ParameterCheck(bad | over, rules)


def _material_rules(topo: Topology, P: np.ndarray, ranged: Callable[..., None]) -> None:
    """Each material parameter slot's rule (the material table's ``Slot.rule``), one check per
    (slot, rule) over every spring whose material has it."""
    b, mat = topo.blocks, topo.material
    groups: dict[tuple[str, str, str], list[int]] = {}
    for m in MATERIALS:
        for slot in m.slots:
            if slot.rule is not None:
                groups.setdefault((slot.block, slot.rule, slot.expect), []).append(m.code)
    for block, test, expect in sorted(groups, key=lambda g: SLOT_ORDER.index(g[0])):
        v, k = P[b[block]], P[b["k"]]
        ok = {"> 0": v > 0, ">= 0": v >= 0, "< 0": v < 0, "below k": (v >= 0) & (v < k)}[test]
        ranged(block, np.flatnonzero(np.isin(mat, groups[block, test, expect])), ~ok, expect)


def _rate_rules(topo: Topology, P: np.ndarray, rule: Callable[..., None]) -> None:
    """rate_elastic: its rates >= 0 and strictly increasing (an axis may set one)."""
    if topo.rate_offsets is None or not len(topo.rate_curves):
        return
    rates, ro = P[topo.blocks["rate"]], topo.rate_offsets
    for s in range(topo.n_springs):
        a, e = int(ro[s]), int(ro[s + 1])
        if e > a:
            sid, r = topo.spring_ids[s], rates[a:e]
            bad = np.concatenate([~(r[:1] >= 0), ~(np.diff(r, axis=0) > 0)])
            rule(
                bad,
                lambda k, c, sid=sid, r=r: (
                    f"springs.{sid}.material.curves.{k}.rate: expected a rate >= 0 and "
                    f"above the rate before it, got {r[k, c]:g}"
                ),
            )


def _option_rules(
    topo: Topology, P: np.ndarray, rule: Callable[..., None], ranged: Callable[..., None]
) -> None:
    """The spring options: failure elongations beyond the initial elongation."""
    b = topo.blocks
    e0, ft, fc = (P[b[name]] for name in ("e0", "fail_t", "fail_c"))
    every = np.arange(topo.n_springs)
    ranged("fail_t", every, ~(ft > 0), "a tension failure elongation > 0")
    ranged("fail_c", every, ~(fc < 0), "a compression failure elongation < 0")
    ids = topo.spring_ids
    rule(
        (ft > 0) & ~(e0 < ft),
        lambda r, c: (
            f"springs.{ids[r]}.failure.tension: expected an elongation above "
            f"initial_elongation ({e0[r, c]:g}), got {ft[r, c]:g}: the spring would be broken at t = 0"
        ),
    )
    rule(
        (fc < 0) & ~(e0 > fc),
        lambda r, c: (
            f"springs.{ids[r]}.failure.compression: expected an elongation below "
            f"initial_elongation ({e0[r, c]:g}), got {fc[r, c]:g}: the spring would be broken at t = 0"
        ),
    )


def _wall_side_rule(
    topo: Topology, P: np.ndarray, x0: np.ndarray, normal: np.ndarray, rule: Callable[..., None]
) -> None:
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
        return f"rigid_walls.{r}.point: " + behind_message(
            topo.node_ids[k], float(depth[r, k, c]), topo.wall_ids[r], length, bad.size - 1
        )

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
            rule(
                ~np.isfinite(pts),
                lambda r, col, cid=cid, pts=pts, axis=axis: (
                    f"curves.{cid}.{axis}.{r} is not "
                    f"finite ({pts[r, col]:g}): an axis value or a scale factor made it overflow"
                ),
            )
        rule(
            ~(np.diff(xs, axis=0) > 0),
            lambda r, col, cid=cid, xs=xs: (
                f"curves.{cid}.x must be strictly increasing "
                f"(x.{r} = {xs[r, col]:g} is followed by {xs[r + 1, col]:g})"
            ),
        )
    origin: dict[int, str] = {}  # curve -> material type of a spring that uses it
    signed: dict[int, str] = {}  # curve -> a material whose force has the sign of the elongation
    rising: set[int] = set()
    crush: set[int] = set()
    damper: set[int] = set()
    for s in range(topo.n_springs):
        row = spec(topo.material[s])  # the material table's curve roles and their rules
        if row.rate_curves and topo.rate_offsets is not None:  # rate_elastic: every curve an elastic one
            for c in topo.rate_curves[int(topo.rate_offsets[s]) : int(topo.rate_offsets[s + 1])]:
                origin[int(c)] = signed[int(c)] = row.name
        for role, c in zip(row.curves, (int(v) for v in topo.spring_curves[s]), strict=False):
            origin[c] = row.name
            if role.rule == "signed":  # a loading curve (an unloading one is increasing)
                signed[c] = row.name + (" loading" if len(row.curves) > 1 else "")
            else:
                {"increasing": rising, "compression_part": crush, "non_decreasing": damper}[
                    str(role.rule)
                ].add(c)
    for c, kind_name in sorted(origin.items()):
        a, e = int(off[c]), int(off[c + 1])
        at0 = _value_at_zero(cx[a:e], cy[a:e])
        scale = np.max(np.abs(cy[a:e]), axis=0)
        scale = np.where(scale > 0, scale, 1.0)
        why = (
            "a damper carries no force at rest; a preload belongs on a spring, with initial_elongation"
            if kind_name == "nonlinear_damper"
            else "a spring that carries force at t = 0 says so with "
            "initial_elongation, never with a shifted curve"
        )
        rule(
            np.abs(at0) > 1e-9 * scale,
            lambda r, col, cid=ids[c], at0=at0, kn=kind_name, why=why: (
                f"curves.{cid} "
                f"must pass through the origin (a {kn} curve; its force at 0 is {at0[col]:g}): {why}"
            ),
        )
    for c, kind_name in sorted(signed.items()):
        a, e = int(off[c]), int(off[c + 1])
        wrong = wrong_sign_points(cx[a:e], cy[a:e])

        def signed_text(
            r: int, col: int, cid: str = ids[c], a: int = a, wrong: np.ndarray = wrong, use: str = kind_name
        ) -> str:
            k = int(np.argmax(wrong[:, col]))
            return f"curves.{cid}: " + sign_message(cid, k, float(cx[a + k, col]), float(cy[a + k, col]), use)

        rule(np.any(wrong, axis=0), signed_text)
    for c in sorted(rising):
        a, e = int(off[c]), int(off[c + 1])
        rule(
            ~(np.diff(cy[a:e], axis=0) > 0),
            lambda r, col, cid=ids[c]: (
                f"curves.{cid}.y must be strictly increasing "
                "(the unloading curve of a general_nonlinear spring)"
            ),
        )
    for c in sorted(damper):
        a, e = int(off[c]), int(off[c + 1])
        rule(
            ~(np.diff(cy[a:e], axis=0) >= 0),
            lambda r, col, cid=ids[c]: (
                f"curves.{cid}.y must be non-decreasing "
                "(the force vs elongation rate curve of a nonlinear_damper)"
            ),
        )
    for c in sorted(crush):
        a = int(off[c])
        rule(
            ~(cx[a] < 0),
            lambda r, col, cid=ids[c], a=a: (
                f"curves.{cid} needs a compression part (x < 0): the "
                f"loading curve of a crush spring starts at x = {cx[a, col]:g}"
            ),
        )


def _value_at_zero(xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
    """Piecewise-linear value at 0 of curves with knots ``xs``, ``ys`` (n, V), extrapolated along the ends."""
    n, V = xs.shape
    k = np.clip(np.sum(xs <= 0.0, axis=0) - 1, 0, n - 2)
    cols = np.arange(V)
    x0, x1, y0, y1 = xs[k, cols], xs[k + 1, cols], ys[k, cols], ys[k + 1, cols]
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        return y0 + (y1 - y0) / (x1 - x0) * (0.0 - x0)
