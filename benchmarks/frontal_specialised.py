"""Hand-specialised reference loop for ``studies/models/frontal-9mass.yaml`` (benchmarks only).

What the hardware gives for this one model: the topology is hard-coded (which nodes each spring
joins, which material it has), the curves' shapes are compile-time constants (the crush springs' curve
scale and x_scale and the flange's stiffness come per variant: a study's curve axes), and one fused loop over the
variants of a block (innermost, contiguous, ``BLOCK`` columns) does every spring, every node update
and every summary of a time step, with branch-free curves and material laws (selects, ``min``/``max``)
so that LLVM can put several variants in one SIMD instruction. It computes the same physics as the
generic kernel (central difference, docs/format.md and docs/solver.md; summaries as
:mod:`crashstudy.kernel.compiled`) and takes the same per-variant steps, so element-steps are equal;
``check_against_generic`` compares peak forces.

Nodes (1-D, all springs drawn left to right so ``e = u_j - u_i``):
0 barrier (fixed), 1 bumper, 2 radiator, 3 engine, 4 engine_mount, 5 front_wheel, 6 transmission,
7 aft_frame, 8 survival_room.
Springs: 0 crash-box (0-1, crush), 1 front-rail (1-5, crush), 2 rear-rail (5-7, crush),
3 occupant-cell (7-8, general_nonlinear), 4 radiator-support (1-2, crush), 5 engine-stackup (2-3,
crush), 6 engine-mount (3-4, general_nonlinear), 7 gearbox-flange (3-6, linear).

The two general_nonlinear springs have monotone loading curves and straight unloading lines through
the origin, so the curve inverses of rules 3-4 are ramp sums too (no search, no branch).
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import numba as nb
import numpy as np

from crashstudy.kernel.output import KernelOutput, allocate
from crashstudy.schema.yamlio import load_yaml

ROOT = Path(__file__).resolve().parents[1]
MODEL = ROOT / "studies" / "models" / "frontal-9mass.yaml"
BLOCK = 256  # variants per block (the generic kernel's BLOCK)
ROW = BLOCK + 8  # row stride of the work array: 33 cache lines, not a power of two (rows 2 KiB apart
# would all fall into the same two L1 sets and alias 4 KiB apart)
N_NODES, N_SPRINGS = 9, 8
SPRING_NODES = ((0, 1), (1, 5), (5, 7), (7, 8), (1, 2), (2, 3), (3, 4), (3, 6))
SPRING_IDS = (
    "crash-box",
    "front-rail",
    "rear-rail",
    "occupant-cell",
    "radiator-support",
    "engine-stackup",
    "engine-mount",
    "gearbox-flange",
)
NODE_IDS = (
    "barrier",
    "bumper",
    "radiator",
    "engine",
    "engine_mount",
    "front_wheel",
    "transmission",
    "aft_frame",
    "survival_room",
)


def _ramp(x: list[float], y: list[float]) -> tuple[float, ...]:
    """Ramp-sum coefficients (y0, s0, x0, x1, ds1, x2, ds2, ...) of a piecewise-linear curve, as
    :func:`crashstudy.arrays.batch.build_batch` computes them (same floating-point operations)."""
    xa = np.asarray(x, dtype=np.float64)
    ya = np.asarray(y, dtype=np.float64)
    slope = np.diff(ya) / np.diff(xa)
    ds = np.diff(slope)
    out = [float(ya[0]), float(slope[0]), float(xa[0])]
    for k in range(1, len(xa) - 1):
        out += [float(xa[k]), float(ds[k - 1])]
    return tuple(out)


def _model_constants() -> dict[str, Any]:
    m = load_yaml(str(MODEL)).data  # YAML 1.2 numbers (1.0e6 is a number)
    c = m["curves"]
    sp = m["springs"]
    assert tuple(m["nodes"]) == NODE_IDS and tuple(sp) == SPRING_IDS, (
        "frontal-9mass.yaml changed: update this file"
    )
    for sid, (i, j) in zip(SPRING_IDS, SPRING_NODES, strict=True):
        assert sp[sid]["nodes"] == [NODE_IDS[i], NODE_IDS[j]], sid
    out = {name: _ramp(v["x"], v["y"]) for name, v in c.items()}
    for name in ("cell-unloading", "mount-unloading"):  # straight lines through the origin
        xs, ys = c[name]["x"], c[name]["y"]
        slopes = np.diff(ys) / np.diff(xs)
        assert np.allclose(slopes, slopes[0]) and 0.0 in xs and ys[xs.index(0.0)] == 0.0, name
        out[name + "-slope"] = float(slopes[0])
    for name in ("cell-loading", "mount-loading"):  # monotone: the inverse is a ramp sum too
        xs, ys = c[name]["x"], c[name]["y"]
        assert np.all(np.diff(ys) > 0), name
        out[name + "-inverse"] = _ramp(ys, xs)
    out["ku"] = tuple(
        float(sp[s]["material"]["unloading_stiffness"])
        for s in ("crash-box", "front-rail", "rear-rail", "radiator-support", "engine-stackup")
    )
    cell, mount = sp["occupant-cell"]["material"], sp["engine-mount"]["material"]
    out["cell-yield"] = (float(cell["tension_yield"]), float(cell["compression_yield"]))
    out["mount-yield"] = (float(mount["tension_yield"]), float(mount["compression_yield"]))
    out["k-flange"] = float(sp["gearbox-flange"]["material"]["stiffness"])
    return out


K = _model_constants()
# module-level constants: numba freezes them into the compiled code
C_BOX, C_RAIL, C_REAR, C_RAD, C_ENG = (
    K["crash-box-loading"],
    K["rail-loading"],
    K["rear-rail-loading"],
    K["radiator-support-loading"],
    K["engine-stackup-loading"],
)
C_CELL, C_CELL_INV, C_CELL_U = K["cell-loading"], K["cell-loading-inverse"], K["cell-unloading"]
C_MOUNT, C_MOUNT_INV, C_MOUNT_U = K["mount-loading"], K["mount-loading-inverse"], K["mount-unloading"]
KU_BOX, KU_RAIL, KU_REAR, KU_RAD, KU_ENG = K["ku"]
KU_CELL, KU_MOUNT = K["cell-unloading-slope"], K["mount-unloading-slope"]
YT_CELL, YC_CELL = K["cell-yield"]
YT_MOUNT, YC_MOUNT = K["mount-yield"]
K_FLANGE = K["k-flange"]

_jit = nb.njit(inline="always", error_model="numpy")

# Rows of the one block work array Z (rows x BLOCK columns). One array with a compile-time row
# stride lets LLVM prove that the rows never overlap, so the fused variant loop vectorises without
# runtime alias checks (separately allocated arrays would each need one).
R_U, R_V, R_M, R_IM = 0, 9, 18, 27  # displacement, velocity, mass, 1/mass: 9 rows each
R_DT, R_NST, R_KE0, R_ERR, R_KEEND, R_IEEND = 36, 37, 38, 39, 40, 41
R_FP, R_EP, R_IE, R_PF, R_MC = (
    42,
    50,
    58,
    66,
    74,
)  # per spring: previous F, previous e, work, peak |F|, max crush
R_PA = 82  # per node: peak a^2
R_CS = 91  # crush state (e_min, F*): 2 rows per spring index
R_GS = 107  # general_nonlinear state: 8 rows per slot (slot 0: occupant-cell, slot 1: engine-mount)
R_FH, R_EH, R_UH, R_AH, R_VH, R_KEH, R_IEH = 123, 131, 139, 148, 157, 166, 167  # recorded values
R_YS, R_IX, R_KF = (
    168,
    173,
    178,
)  # per variant: the crush springs' curve scale and 1 / x_scale, the flange's k
N_ROWS = 179
CRUSH_SPRINGS = (0, 1, 2, 4, 5)  # crash-box, front-rail, rear-rail, radiator-support, engine-stackup


@_jit
def _max(a, b):  # pragma: no cover - compiled
    """``max(a, b)`` as a select (numba's builtin ``max`` is a call that blocks vectorisation)."""
    return b if b > a else a


@_jit
def _min(a, b):  # pragma: no cover - compiled
    """``_min(a, b)`` as a select."""
    return b if b < a else a


@_jit
def _ramp3(e, c):  # pragma: no cover - compiled
    """Ramp sum with 3 interior knots, coefficients (y0, s0, x0, x1, ds1, ...) as build_batch's."""
    y = c[0] + c[1] * (e - c[2])
    y = y + c[4] * _max(0.0, e - c[3])
    y = y + c[6] * _max(0.0, e - c[5])
    return y + c[8] * _max(0.0, e - c[7])


@_jit
def _ramp4(e, c):  # pragma: no cover - compiled
    """Ramp sum with 4 interior knots."""
    return _ramp3(e, c) + c[10] * _max(0.0, e - c[9])


@_jit
def _ramp5(e, c):  # pragma: no cover - compiled
    """Ramp sum with 5 interior knots."""
    return _ramp4(e, c) + c[12] * _max(0.0, e - c[11])


@_jit
def _line(e, c):  # pragma: no cover - compiled
    """A straight curve (its one interior knot has a zero slope change, which adds exactly 0)."""
    return c[0] + c[1] * (e - c[2])


@_jit
def _crush(e, emin, fstar, ramp, c, ku, ys, ixs):  # pragma: no cover - compiled
    """Crush law (docs/format.md), branch-free: returns (F, e_min, F*) after this step; the loading curve
    is ``ys * curve(e * ixs)`` (a study's curve scale and 1 / x_scale)."""
    on = e <= emin
    f_load = _min(0.0, ys * ramp(e * ixs, c))
    f_unl = _min(0.0, fstar + ku * (e - emin))
    return (f_load if on else f_unl), (e if on else emin), (f_load if on else fstar)


@_jit
def _general(
    e, mode, et, ft, ec, fc, shift, yld_t, yld_c, ramp, cl, ramp_inv, cinv, cu, ku, yt, yc
):  # pragma: no cover - compiled
    """general_nonlinear rules 1-4 (docs/format.md) for a monotone loading curve and a straight unloading
    line: every branch is evaluated and the result selected. State: mode, e*_t, F*_t, e*_c, F*_c,
    shift, yielded_t, yielded_c (as the generic kernel's); returns (F, new state...)."""
    L = ramp(e - shift, cl)
    thr_t = ft if yld_t > 0.0 else yt
    thr_c = fc if yld_c > 0.0 else yc
    m0 = mode == 0.0
    mp = mode > 0.0
    mn = mode < 0.0
    to_t = m0 & (L >= yt)
    to_c = m0 & (L <= yc)
    load_p = mp & (e >= et)
    load_n = mn & (e <= ec)
    fu_p = ft + _line(e - et, cu)
    fu_n = fc + _line(e - ec, cu)
    rev_c = mp & (e < et) & (fu_p <= thr_c)
    rev_t = mn & (e > ec) & (fu_n >= thr_t)
    f_unl = fu_p if mp else fu_n
    F = L if (m0 | load_p | load_n) else f_unl
    et = e if load_p else et
    ft = L if load_p else ft
    ec = e if load_n else ec
    fc = L if load_n else fc
    # rule 4: the loading curve shifted through the current point (computed always, used on reversal)
    thr = thr_c if mp else thr_t
    base_e = et if mp else ec
    base_f = ft if mp else fc
    rev = rev_c | rev_t
    shift_new = base_e + (thr - base_f) / ku - ramp_inv(thr, cinv)
    shift = shift_new if rev else shift
    Ls = ramp(e - shift, cl)
    F = Ls if rev else F
    ec = e if rev_c else ec
    fc = Ls if rev_c else fc
    et = e if rev_t else et
    ft = Ls if rev_t else ft
    et = e if to_t else et
    ft = L if to_t else ft
    ec = e if to_c else ec
    fc = L if to_c else fc
    up = to_t | rev_t
    down = (to_c | rev_c) & (not up)
    mode_dn = -1.0 if down else mode
    mode = 1.0 if up else mode_dn
    yld_t = 1.0 if up else yld_t
    yld_c = 1.0 if down else yld_c
    return F, mode, et, ft, ec, fc, shift, yld_t, yld_c


@_jit
def _summary(F, e, ie, fp, ep, pf, mc, af, wt):  # pragma: no cover - compiled
    """Absorbed work (trapezoid), peak |F| and max crush of one spring after this step."""
    ie = ie + (0.5 * (F + fp) * (e - ep)) * (af * wt)
    return ie, _max(pf, abs(F) * af), _max(mc, -e * af)


@_jit
def _node(f, im, m, vo, u, pa, h, dtw, af):  # pragma: no cover - compiled
    """Central-difference update of one node: (a, v_old, v_new, m v_old v_new / 2, peak a^2, u, v)."""
    a = f * im
    vn = vo + (h * dtw) * a
    return (
        a,
        vo,
        vn,
        0.5 * m * vo * vn,
        _max(pa, (a * a) * af),
        u + (dtw * af) * vn,
        vn * af + vo * (1.0 - af),
    )


@_jit
def _step(Z, B, n, rec):  # pragma: no cover - compiled
    """Time step ``n`` of a block: one fused, branch-free pass over its ``B`` variants. ``rec`` (a
    constant at each call site) also keeps the values a history sample needs in rows R_FH..R_IEH."""
    h = 1.0 if n > 0 else 0.5
    wt = 1.0 if n > 0 else 0.0  # the trapezoid of absorbed work starts at step 1
    fn = float(n)
    for w in range(B):
        af = 1.0 if fn <= Z[(R_NST) * ROW + w] else 0.0
        if rec:
            for n_ in range(9):
                Z[(R_UH + n_) * ROW + w] = Z[(R_U + n_) * ROW + w]
        e0 = Z[(R_U + 1) * ROW + w]
        e1 = Z[(R_U + 5) * ROW + w] - Z[(R_U + 1) * ROW + w]
        e2 = Z[(R_U + 7) * ROW + w] - Z[(R_U + 5) * ROW + w]
        e3 = Z[(R_U + 8) * ROW + w] - Z[(R_U + 7) * ROW + w]
        e4 = Z[(R_U + 2) * ROW + w] - Z[(R_U + 1) * ROW + w]
        e5 = Z[(R_U + 3) * ROW + w] - Z[(R_U + 2) * ROW + w]
        e6 = Z[(R_U + 4) * ROW + w] - Z[(R_U + 3) * ROW + w]
        e7 = Z[(R_U + 6) * ROW + w] - Z[(R_U + 3) * ROW + w]
        F0, Z[(R_CS + 0) * ROW + w], Z[(R_CS + 1) * ROW + w] = _crush(
            e0,
            Z[(R_CS + 0) * ROW + w],
            Z[(R_CS + 1) * ROW + w],
            _ramp4,
            C_BOX,
            KU_BOX,
            Z[(R_YS + 0) * ROW + w],
            Z[(R_IX + 0) * ROW + w],
        )
        F1, Z[(R_CS + 2) * ROW + w], Z[(R_CS + 3) * ROW + w] = _crush(
            e1,
            Z[(R_CS + 2) * ROW + w],
            Z[(R_CS + 3) * ROW + w],
            _ramp4,
            C_RAIL,
            KU_RAIL,
            Z[(R_YS + 1) * ROW + w],
            Z[(R_IX + 1) * ROW + w],
        )
        F2, Z[(R_CS + 4) * ROW + w], Z[(R_CS + 5) * ROW + w] = _crush(
            e2,
            Z[(R_CS + 4) * ROW + w],
            Z[(R_CS + 5) * ROW + w],
            _ramp3,
            C_REAR,
            KU_REAR,
            Z[(R_YS + 2) * ROW + w],
            Z[(R_IX + 2) * ROW + w],
        )
        F4, Z[(R_CS + 8) * ROW + w], Z[(R_CS + 9) * ROW + w] = _crush(
            e4,
            Z[(R_CS + 8) * ROW + w],
            Z[(R_CS + 9) * ROW + w],
            _ramp3,
            C_RAD,
            KU_RAD,
            Z[(R_YS + 3) * ROW + w],
            Z[(R_IX + 3) * ROW + w],
        )
        F5, Z[(R_CS + 10) * ROW + w], Z[(R_CS + 11) * ROW + w] = _crush(
            e5,
            Z[(R_CS + 10) * ROW + w],
            Z[(R_CS + 11) * ROW + w],
            _ramp3,
            C_ENG,
            KU_ENG,
            Z[(R_YS + 4) * ROW + w],
            Z[(R_IX + 4) * ROW + w],
        )
        g = R_GS
        (
            F3,
            Z[(g) * ROW + w],
            Z[(g + 1) * ROW + w],
            Z[(g + 2) * ROW + w],
            Z[(g + 3) * ROW + w],
            Z[(g + 4) * ROW + w],
            Z[(g + 5) * ROW + w],
            Z[(g + 6) * ROW + w],
            Z[(g + 7) * ROW + w],
        ) = _general(
            e3,
            Z[(g) * ROW + w],
            Z[(g + 1) * ROW + w],
            Z[(g + 2) * ROW + w],
            Z[(g + 3) * ROW + w],
            Z[(g + 4) * ROW + w],
            Z[(g + 5) * ROW + w],
            Z[(g + 6) * ROW + w],
            Z[(g + 7) * ROW + w],
            _ramp4,
            C_CELL,
            _ramp4,
            C_CELL_INV,
            C_CELL_U,
            KU_CELL,
            YT_CELL,
            YC_CELL,
        )
        g = R_GS + 8
        (
            F6,
            Z[(g) * ROW + w],
            Z[(g + 1) * ROW + w],
            Z[(g + 2) * ROW + w],
            Z[(g + 3) * ROW + w],
            Z[(g + 4) * ROW + w],
            Z[(g + 5) * ROW + w],
            Z[(g + 6) * ROW + w],
            Z[(g + 7) * ROW + w],
        ) = _general(
            e6,
            Z[(g) * ROW + w],
            Z[(g + 1) * ROW + w],
            Z[(g + 2) * ROW + w],
            Z[(g + 3) * ROW + w],
            Z[(g + 4) * ROW + w],
            Z[(g + 5) * ROW + w],
            Z[(g + 6) * ROW + w],
            Z[(g + 7) * ROW + w],
            _ramp5,
            C_MOUNT,
            _ramp5,
            C_MOUNT_INV,
            C_MOUNT_U,
            KU_MOUNT,
            YT_MOUNT,
            YC_MOUNT,
        )
        F7 = Z[R_KF * ROW + w] * e7
        # summaries in spring order (the generic kernel's order of operations)
        ie0, Z[(R_PF + 0) * ROW + w], Z[(R_MC + 0) * ROW + w] = _summary(
            F0,
            e0,
            Z[(R_IE + 0) * ROW + w],
            Z[(R_FP + 0) * ROW + w],
            Z[(R_EP + 0) * ROW + w],
            Z[(R_PF + 0) * ROW + w],
            Z[(R_MC + 0) * ROW + w],
            af,
            wt,
        )
        Z[(R_IE + 0) * ROW + w], Z[(R_FP + 0) * ROW + w], Z[(R_EP + 0) * ROW + w] = ie0, F0, e0
        ie1, Z[(R_PF + 1) * ROW + w], Z[(R_MC + 1) * ROW + w] = _summary(
            F1,
            e1,
            Z[(R_IE + 1) * ROW + w],
            Z[(R_FP + 1) * ROW + w],
            Z[(R_EP + 1) * ROW + w],
            Z[(R_PF + 1) * ROW + w],
            Z[(R_MC + 1) * ROW + w],
            af,
            wt,
        )
        Z[(R_IE + 1) * ROW + w], Z[(R_FP + 1) * ROW + w], Z[(R_EP + 1) * ROW + w] = ie1, F1, e1
        ie2, Z[(R_PF + 2) * ROW + w], Z[(R_MC + 2) * ROW + w] = _summary(
            F2,
            e2,
            Z[(R_IE + 2) * ROW + w],
            Z[(R_FP + 2) * ROW + w],
            Z[(R_EP + 2) * ROW + w],
            Z[(R_PF + 2) * ROW + w],
            Z[(R_MC + 2) * ROW + w],
            af,
            wt,
        )
        Z[(R_IE + 2) * ROW + w], Z[(R_FP + 2) * ROW + w], Z[(R_EP + 2) * ROW + w] = ie2, F2, e2
        ie3, Z[(R_PF + 3) * ROW + w], Z[(R_MC + 3) * ROW + w] = _summary(
            F3,
            e3,
            Z[(R_IE + 3) * ROW + w],
            Z[(R_FP + 3) * ROW + w],
            Z[(R_EP + 3) * ROW + w],
            Z[(R_PF + 3) * ROW + w],
            Z[(R_MC + 3) * ROW + w],
            af,
            wt,
        )
        Z[(R_IE + 3) * ROW + w], Z[(R_FP + 3) * ROW + w], Z[(R_EP + 3) * ROW + w] = ie3, F3, e3
        ie4, Z[(R_PF + 4) * ROW + w], Z[(R_MC + 4) * ROW + w] = _summary(
            F4,
            e4,
            Z[(R_IE + 4) * ROW + w],
            Z[(R_FP + 4) * ROW + w],
            Z[(R_EP + 4) * ROW + w],
            Z[(R_PF + 4) * ROW + w],
            Z[(R_MC + 4) * ROW + w],
            af,
            wt,
        )
        Z[(R_IE + 4) * ROW + w], Z[(R_FP + 4) * ROW + w], Z[(R_EP + 4) * ROW + w] = ie4, F4, e4
        ie5, Z[(R_PF + 5) * ROW + w], Z[(R_MC + 5) * ROW + w] = _summary(
            F5,
            e5,
            Z[(R_IE + 5) * ROW + w],
            Z[(R_FP + 5) * ROW + w],
            Z[(R_EP + 5) * ROW + w],
            Z[(R_PF + 5) * ROW + w],
            Z[(R_MC + 5) * ROW + w],
            af,
            wt,
        )
        Z[(R_IE + 5) * ROW + w], Z[(R_FP + 5) * ROW + w], Z[(R_EP + 5) * ROW + w] = ie5, F5, e5
        ie6, Z[(R_PF + 6) * ROW + w], Z[(R_MC + 6) * ROW + w] = _summary(
            F6,
            e6,
            Z[(R_IE + 6) * ROW + w],
            Z[(R_FP + 6) * ROW + w],
            Z[(R_EP + 6) * ROW + w],
            Z[(R_PF + 6) * ROW + w],
            Z[(R_MC + 6) * ROW + w],
            af,
            wt,
        )
        Z[(R_IE + 6) * ROW + w], Z[(R_FP + 6) * ROW + w], Z[(R_EP + 6) * ROW + w] = ie6, F6, e6
        ie7, Z[(R_PF + 7) * ROW + w], Z[(R_MC + 7) * ROW + w] = _summary(
            F7,
            e7,
            Z[(R_IE + 7) * ROW + w],
            Z[(R_FP + 7) * ROW + w],
            Z[(R_EP + 7) * ROW + w],
            Z[(R_PF + 7) * ROW + w],
            Z[(R_MC + 7) * ROW + w],
            af,
            wt,
        )
        Z[(R_IE + 7) * ROW + w], Z[(R_FP + 7) * ROW + w], Z[(R_EP + 7) * ROW + w] = ie7, F7, e7
        ie_tot = (((((((0.0 + ie0) + ie1) + ie2) + ie3) + ie4) + ie5) + ie6) + ie7
        if rec:
            Z[(R_FH + 0) * ROW + w], Z[(R_EH + 0) * ROW + w] = F0, e0
            Z[(R_FH + 1) * ROW + w], Z[(R_EH + 1) * ROW + w] = F1, e1
            Z[(R_FH + 2) * ROW + w], Z[(R_EH + 2) * ROW + w] = F2, e2
            Z[(R_FH + 3) * ROW + w], Z[(R_EH + 3) * ROW + w] = F3, e3
            Z[(R_FH + 4) * ROW + w], Z[(R_EH + 4) * ROW + w] = F4, e4
            Z[(R_FH + 5) * ROW + w], Z[(R_EH + 5) * ROW + w] = F5, e5
            Z[(R_FH + 6) * ROW + w], Z[(R_EH + 6) * ROW + w] = F6, e6
            Z[(R_FH + 7) * ROW + w], Z[(R_EH + 7) * ROW + w] = F7, e7
        # nodal forces, accumulated in the generic scatter's order
        f1 = ((0.0 - F0) + F1) + F4
        f2 = (0.0 - F4) + F5
        f3 = ((0.0 - F5) + F6) + F7
        f4 = 0.0 - F6
        f5 = (0.0 - F1) + F2
        f6 = 0.0 - F7
        f7 = (0.0 - F2) + F3
        f8 = 0.0 - F3
        dtw = Z[(R_DT) * ROW + w]
        a1, vo1, vn1, k1, Z[(R_PA + 1) * ROW + w], Z[(R_U + 1) * ROW + w], Z[(R_V + 1) * ROW + w] = _node(
            f1,
            Z[(R_IM + 1) * ROW + w],
            Z[(R_M + 1) * ROW + w],
            Z[(R_V + 1) * ROW + w],
            Z[(R_U + 1) * ROW + w],
            Z[(R_PA + 1) * ROW + w],
            h,
            dtw,
            af,
        )
        a2, vo2, vn2, k2, Z[(R_PA + 2) * ROW + w], Z[(R_U + 2) * ROW + w], Z[(R_V + 2) * ROW + w] = _node(
            f2,
            Z[(R_IM + 2) * ROW + w],
            Z[(R_M + 2) * ROW + w],
            Z[(R_V + 2) * ROW + w],
            Z[(R_U + 2) * ROW + w],
            Z[(R_PA + 2) * ROW + w],
            h,
            dtw,
            af,
        )
        a3, vo3, vn3, k3, Z[(R_PA + 3) * ROW + w], Z[(R_U + 3) * ROW + w], Z[(R_V + 3) * ROW + w] = _node(
            f3,
            Z[(R_IM + 3) * ROW + w],
            Z[(R_M + 3) * ROW + w],
            Z[(R_V + 3) * ROW + w],
            Z[(R_U + 3) * ROW + w],
            Z[(R_PA + 3) * ROW + w],
            h,
            dtw,
            af,
        )
        a4, vo4, vn4, k4, Z[(R_PA + 4) * ROW + w], Z[(R_U + 4) * ROW + w], Z[(R_V + 4) * ROW + w] = _node(
            f4,
            Z[(R_IM + 4) * ROW + w],
            Z[(R_M + 4) * ROW + w],
            Z[(R_V + 4) * ROW + w],
            Z[(R_U + 4) * ROW + w],
            Z[(R_PA + 4) * ROW + w],
            h,
            dtw,
            af,
        )
        a5, vo5, vn5, k5, Z[(R_PA + 5) * ROW + w], Z[(R_U + 5) * ROW + w], Z[(R_V + 5) * ROW + w] = _node(
            f5,
            Z[(R_IM + 5) * ROW + w],
            Z[(R_M + 5) * ROW + w],
            Z[(R_V + 5) * ROW + w],
            Z[(R_U + 5) * ROW + w],
            Z[(R_PA + 5) * ROW + w],
            h,
            dtw,
            af,
        )
        a6, vo6, vn6, k6, Z[(R_PA + 6) * ROW + w], Z[(R_U + 6) * ROW + w], Z[(R_V + 6) * ROW + w] = _node(
            f6,
            Z[(R_IM + 6) * ROW + w],
            Z[(R_M + 6) * ROW + w],
            Z[(R_V + 6) * ROW + w],
            Z[(R_U + 6) * ROW + w],
            Z[(R_PA + 6) * ROW + w],
            h,
            dtw,
            af,
        )
        a7, vo7, vn7, k7, Z[(R_PA + 7) * ROW + w], Z[(R_U + 7) * ROW + w], Z[(R_V + 7) * ROW + w] = _node(
            f7,
            Z[(R_IM + 7) * ROW + w],
            Z[(R_M + 7) * ROW + w],
            Z[(R_V + 7) * ROW + w],
            Z[(R_U + 7) * ROW + w],
            Z[(R_PA + 7) * ROW + w],
            h,
            dtw,
            af,
        )
        a8, vo8, vn8, k8, Z[(R_PA + 8) * ROW + w], Z[(R_U + 8) * ROW + w], Z[(R_V + 8) * ROW + w] = _node(
            f8,
            Z[(R_IM + 8) * ROW + w],
            Z[(R_M + 8) * ROW + w],
            Z[(R_V + 8) * ROW + w],
            Z[(R_U + 8) * ROW + w],
            Z[(R_PA + 8) * ROW + w],
            h,
            dtw,
            af,
        )
        ke = (((((((0.0 + k1) + k2) + k3) + k4) + k5) + k6) + k7) + k8
        if rec:
            Z[(R_AH + 1) * ROW + w] = a1
            Z[(R_VH + 1) * ROW + w] = 0.5 * (vo1 + vn1) if n > 0 else vo1
            Z[(R_AH + 2) * ROW + w] = a2
            Z[(R_VH + 2) * ROW + w] = 0.5 * (vo2 + vn2) if n > 0 else vo2
            Z[(R_AH + 3) * ROW + w] = a3
            Z[(R_VH + 3) * ROW + w] = 0.5 * (vo3 + vn3) if n > 0 else vo3
            Z[(R_AH + 4) * ROW + w] = a4
            Z[(R_VH + 4) * ROW + w] = 0.5 * (vo4 + vn4) if n > 0 else vo4
            Z[(R_AH + 5) * ROW + w] = a5
            Z[(R_VH + 5) * ROW + w] = 0.5 * (vo5 + vn5) if n > 0 else vo5
            Z[(R_AH + 6) * ROW + w] = a6
            Z[(R_VH + 6) * ROW + w] = 0.5 * (vo6 + vn6) if n > 0 else vo6
            Z[(R_AH + 7) * ROW + w] = a7
            Z[(R_VH + 7) * ROW + w] = 0.5 * (vo7 + vn7) if n > 0 else vo7
            Z[(R_AH + 8) * ROW + w] = a8
            Z[(R_VH + 8) * ROW + w] = 0.5 * (vo8 + vn8) if n > 0 else vo8
        ke0 = Z[(R_KE0) * ROW + w]
        ke = ke if n > 0 else ke0
        Z[(R_ERR) * ROW + w] = _max(Z[(R_ERR) * ROW + w], abs(ke + ie_tot - ke0) * af)
        last = fn == Z[(R_NST) * ROW + w]
        Z[(R_KEEND) * ROW + w] = ke if last else Z[(R_KEEND) * ROW + w]
        Z[(R_IEEND) * ROW + w] = ie_tot if last else Z[(R_IEEND) * ROW + w]
        if rec:
            Z[(R_KEH) * ROW + w] = ke
            Z[(R_IEH) * ROW + w] = ie_tot


@nb.njit(nogil=True, error_model="numpy", cache=True)
def _run_blocks(
    b_lo,
    b_hi,
    starts,
    record,
    mass,
    inv_mass,
    x0,
    v0,
    dt,
    n_steps,
    out_every,
    n_out,
    ys,
    ixs,
    kf,
    h_pos,
    h_disp,
    h_vel,
    h_acc,
    h_force,
    h_elong,
    h_energy,
    peak_force,
    max_crush,
    absorbed,
    peak_acc,
    energy_error,
    final_energy,
    t_end,
):  # pragma: no cover
    N = 9
    S = 8
    for bi in range(b_lo, b_hi):
        lo = starts[bi]
        B = starts[bi + 1] - lo
        Z = np.zeros(N_ROWS * ROW)  # row r of the block: Z[r * ROW : r * ROW + BLOCK]
        next_rec = np.zeros(B, dtype=np.int64)
        for n_ in range(N):
            for w in range(B):
                Z[(R_M + n_) * ROW + w] = mass[n_, lo + w]
                Z[(R_IM + n_) * ROW + w] = inv_mass[n_, 0, lo + w]
                Z[(R_V + n_) * ROW + w] = v0[n_, 0, lo + w]
        for k in range(5):
            for w in range(B):
                Z[(R_YS + k) * ROW + w] = ys[k, lo + w]
                Z[(R_IX + k) * ROW + w] = ixs[k, lo + w]
        nmax = 0
        for w in range(B):
            Z[R_KF * ROW + w] = kf[lo + w]
            Z[R_DT * ROW + w] = dt[lo + w]
            Z[R_NST * ROW + w] = n_steps[lo + w]
            nmax = max(nmax, n_steps[lo + w])
        for n_ in range(N):
            for w in range(B):
                Z[R_KE0 * ROW + w] += (
                    0.5 * Z[(R_M + n_) * ROW + w] * Z[(R_V + n_) * ROW + w] * Z[(R_V + n_) * ROW + w]
                )
        for n in range(nmax + 1):
            rec_now = False
            if record:
                for w in range(B):
                    rec_now = rec_now or (n == next_rec[w] and n <= n_steps[lo + w])
            if not rec_now:
                _step(Z, B, n, False)
                continue
            _step(Z, B, n, True)
            for w in range(B):
                q = lo + w
                if n != next_rec[w] or n > n_steps[q]:
                    continue
                r = n // out_every[q]
                next_rec[w] = n + out_every[q]
                if r >= n_out:
                    continue
                for n_ in range(N):
                    h_pos[r, n_, 0, q] = x0[n_, 0, q] + Z[(R_UH + n_) * ROW + w]
                    h_disp[r, n_, 0, q] = Z[(R_UH + n_) * ROW + w]
                    h_vel[r, n_, 0, q] = Z[(R_VH + n_) * ROW + w]
                    h_acc[r, n_, 0, q] = Z[(R_AH + n_) * ROW + w]
                for s in range(S):
                    h_force[r, s, q] = Z[(R_FH + s) * ROW + w]
                    h_elong[r, s, q] = Z[(R_EH + s) * ROW + w]
                h_energy[r, 0, q] = Z[R_KEH * ROW + w]
                h_energy[r, 1, q] = Z[R_IEH * ROW + w]
                h_energy[r, 2, q] = 0.0
                h_energy[r, 3, q] = 0.0
        for w in range(B):
            q = lo + w
            energy_error[q] = Z[R_ERR * ROW + w] / _max(Z[R_KE0 * ROW + w], 1e-300)
            t_end[q] = n_steps[q] * Z[R_DT * ROW + w]
            final_energy[0, q] = Z[R_KEEND * ROW + w]
            final_energy[1, q] = Z[R_IEEND * ROW + w]
            for s in range(S):
                peak_force[s, q] = Z[(R_PF + s) * ROW + w]
                max_crush[s, q] = Z[(R_MC + s) * ROW + w]
                absorbed[s, q] = Z[(R_IE + s) * ROW + w]
            for n_ in range(N):
                peak_acc[n_, q] = np.sqrt(Z[(R_PA + n_) * ROW + w])


_THREADS = [os.cpu_count() or 1]


def set_threads(n: int) -> None:
    """Threads the specialised loop uses (blocks spread over a thread pool, as the generic kernel)."""
    _THREADS[0] = max(1, int(n))


def run_specialised(b: Any, histories: tuple[str, ...], n_out: int, block: int = BLOCK) -> KernelOutput:
    """Run the frontal model's variants of batch ``b`` (a :class:`crashstudy.arrays.batch.Batch` built from
    frontal-9mass.yaml) with the specialised loop; histories all or none."""
    N, D, V = b.x0.shape
    assert (N, D, len(b.spring_i)) == (N_NODES, 1, N_SPRINGS), "not the frontal model"
    assert np.array_equal(np.stack([b.spring_i, b.spring_j], axis=1), np.array(SPRING_NODES)), (
        "not the frontal model"
    )
    assert np.all(b.sign == 1.0) and np.all(b.invalid == 0)
    record = len(histories) > 0
    out = allocate(N_SPRINGS, N_NODES, 1, 0, V, histories, n_out)
    h_energy = np.full((n_out, 4, V), np.nan) if record else np.empty((1, 4, 1))

    def buf(name: str, nd: int) -> np.ndarray:
        return out.histories[name] if name in out.histories else np.empty((1,) * nd)

    starts = np.unique(np.minimum(np.arange(0, V + block, block), V)).astype(np.int64)
    curves = b.curve_a[list(CRUSH_SPRINGS)]
    others = [c for c in range(b.cfac.shape[1]) if c not in set(curves.tolist())]
    assert np.all(b.cfac[:2, others] == 1.0), "the loop scales the crush springs' curves only"
    ys, ixs = np.ascontiguousarray(b.cfac[0, curves]), np.ascontiguousarray(1.0 / b.cfac[1, curves])
    args = (
        starts,
        record,
        b.mass,
        b.inv_mass,
        b.x0,
        b.v0,
        b.dt,
        b.n_steps,
        b.out_every,
        n_out,
        ys,
        ixs,
        np.ascontiguousarray(b.kpar[7]),
        buf("position", 4),
        buf("displacement", 4),
        buf("velocity", 4),
        buf("acceleration", 4),
        buf("spring_force", 3),
        buf("spring_elongation", 3),
        h_energy,
        out.peak_force,
        out.max_crush,
        out.absorbed_energy,
        out.peak_acceleration,
        out.energy_error,
        out.final_energy,
        out.t_end,
    )
    nblocks = len(starts) - 1
    threads = min(_THREADS[0], nblocks)
    if threads <= 1:
        _run_blocks(0, nblocks, *args)
    else:
        with ThreadPoolExecutor(threads) as pool:
            list(pool.map(lambda bi: _run_blocks(bi, bi + 1, *args), range(nblocks)))
    for k, name in enumerate(("kinetic_energy", "internal_energy", "external_work", "wall_energy")):
        if name in out.histories:
            out.histories[name][:] = h_energy[:, k, :]
    return out
