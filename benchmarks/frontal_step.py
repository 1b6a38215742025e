"""One time step of a block of the frontal loop: a fused, branch-free pass over its variants that does
every spring, every node update and every summary. Part of the hand-specialised reference loop for
``studies/models/frontal-9mass.yaml`` (benchmarks only; frontal_specialised.py describes it)."""

from __future__ import annotations

from frontal_constants import (
    C_BOX,
    C_CELL,
    C_CELL_INV,
    C_CELL_U,
    C_ENG,
    C_MOUNT,
    C_MOUNT_INV,
    C_MOUNT_U,
    C_RAD,
    C_RAIL,
    C_REAR,
    KU_BOX,
    KU_CELL,
    KU_ENG,
    KU_MOUNT,
    KU_RAD,
    KU_RAIL,
    KU_REAR,
    R_AH,
    R_CS,
    R_DT,
    R_EH,
    R_EP,
    R_ERR,
    R_FH,
    R_FP,
    R_GS,
    R_IE,
    R_IEEND,
    R_IEH,
    R_IM,
    R_IX,
    R_KE0,
    R_KEEND,
    R_KEH,
    R_KF,
    R_M,
    R_MC,
    R_NST,
    R_PA,
    R_PF,
    R_U,
    R_UH,
    R_V,
    R_VH,
    R_YS,
    ROW,
    YC_CELL,
    YC_MOUNT,
    YT_CELL,
    YT_MOUNT,
    _jit,
)
from frontal_laws import _crush, _general, _max, _node, _ramp3, _ramp4, _ramp5, _summary


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
