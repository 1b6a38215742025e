"""The NumPy twins of the per-step laws of :mod:`crashstudy.kernel.step_laws` (and of the 2-D axis,
``laws.axis_2d``), over arrays of variants:
the same operations in the same order, used by the reference kernel (:mod:`crashstudy.kernel.reference`)
and checked bit for bit against the compiled laws in tests/test_laws.py.
"""

from __future__ import annotations

import numpy as np

from crashstudy.vocabulary.codes import (
    PM_ACCELERATION,
    PM_DISPLACEMENT,
    TINY_LENGTH,
    UNSTABLE_ENERGY,
    WALL_PASSIVITY,
)


def axis_2d_np(
    u0: np.ndarray, u1: np.ndarray, p0: np.ndarray, p1: np.ndarray, l0: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Unit direction, length and collapse flag of a 2-D spring (the twin of ``laws.axis_2d``; the
    reference's D-generic sums, ``reference.run_reference``, are the same operations for D = 2)."""
    ln = np.sqrt((0.0 + u0 * u0) + u1 * u1)
    gone = (ln <= TINY_LENGTH * l0) | (((0.0 + u0 * p0) + u1 * p1) <= 0.0)
    dn = np.where(gone, 1.0, ln)
    return u0 / dn, u1 / dn, ln, gone


def half_step_np(vo: np.ndarray, a: np.ndarray, dtn: np.ndarray | float) -> np.ndarray:
    """v^{n+1/2} (the twin of ``step_laws.half_step``)."""
    return vo + dtn * a


def advance_np(
    x: np.ndarray, vo: np.ndarray, vn: np.ndarray, dt: np.ndarray, af: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """x^{n+1} and the velocity kept (the twin of ``step_laws.advance``)."""
    return x + (dt * af) * vn, vn * af + vo * (1.0 - af)


def kinetic_np(ke: np.ndarray, m: np.ndarray, vo: np.ndarray, vn: np.ndarray) -> np.ndarray:
    """One dof's kinetic energy added to ``ke`` (the twin of ``step_laws.kinetic``)."""
    return ke + 0.5 * m * vo * vn


def spring_extremes_np(
    pf: np.ndarray,
    mc: np.ndarray,
    me: np.ndarray,
    F: np.ndarray,
    af: np.ndarray,
    em: np.ndarray,
    ai: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Peak |force|, crush and elongation (the twin of ``step_laws.spring_extremes``; ``laws.peak``'s
    running maximum: ``np.maximum(0.0, -0.0)`` is -0.0)."""

    def peak(p: np.ndarray, x: np.ndarray) -> np.ndarray:
        return np.where(x > p, x, p)

    return peak(pf, np.abs(F) * af), peak(mc, -em * ai), peak(me, em * ai)


def prescribed_time_np(kind: int, t: np.ndarray, dt: np.ndarray) -> np.ndarray:
    """The time a prescribed motion's curve is read for the step from t (the twin of ``step_laws.prescribed_time``)."""
    return t + dt if kind == PM_DISPLACEMENT else t if kind == PM_ACCELERATION else t + 0.5 * dt


def prescribed_velocity_np(
    kind: int,
    x0: np.ndarray,
    scale: np.ndarray,
    tc: np.ndarray,
    x: np.ndarray,
    v: np.ndarray,
    dt: np.ndarray,
    dtn: np.ndarray,
) -> np.ndarray:
    """v^{n+1/2} of a driven dof (the twin of ``step_laws.prescribed_velocity``)."""
    if kind == PM_DISPLACEMENT:
        return (x0 + scale * tc - x) / dt
    if kind == PM_ACCELERATION:
        return v + dtn * scale * tc
    return scale * tc


def prescribed_step_np(
    last: np.ndarray | bool, vn: np.ndarray, vo: np.ndarray, pa: np.ndarray, dtn: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """(v^{n+1/2}, a^n); the last step continues with ``pa`` (the twin of ``step_laws.prescribed_step``)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(last, vo + dtn * pa, vn), np.where(last, pa, (vn - vo) / dtn)


def stop_test_np(
    kef: np.ndarray,
    fsum: np.ndarray,
    psum: np.ndarray,
    ke: np.ndarray,
    scale: np.ndarray,
    wmax: np.ndarray,
    opening: np.ndarray,
) -> np.ndarray:
    """Early termination's force and energy test (the twin of ``step_laws.stop_test``)."""
    small_f = fsum <= kef * psum
    small_ke = ke <= kef * (scale + wmax)
    return small_f & (small_ke | opening)


def energy_balance_np(
    ke: np.ndarray, ie: np.ndarray, wall: np.ndarray, e_init: np.ndarray, work: np.ndarray
) -> np.ndarray:
    """|KE + IE + E_wall - E^0 - W_ext| per variant (the twin of ``step_laws.energy_balance``)."""
    return np.abs(ke + ie + wall - e_init - work)


def unstable_limit_np(scale: np.ndarray, wmax: np.ndarray, floor: np.ndarray) -> np.ndarray:
    """The largest balance error of a stable run (the twin of ``step_laws.unstable_limit``)."""
    return UNSTABLE_ENERGY * (scale + wmax) + floor


def unstable_np(bal: np.ndarray, limit: np.ndarray) -> np.ndarray:
    """Balance error above the limit or not a number (the twin of ``step_laws.unstable``)."""
    return ~np.isfinite(bal) | (bal > limit)


def wall_gives_np(wall: np.ndarray, limit: np.ndarray) -> np.ndarray:
    """The walls have given energy (the twin of ``step_laws.wall_gives``)."""
    return wall < -WALL_PASSIVITY * limit


def wall_hold_np(dvn: np.ndarray, an: np.ndarray, dtn: np.ndarray) -> np.ndarray:
    """NumPy twin of :func:`crashstudy.kernel.step_laws.wall_hold`."""
    h = np.where(-an > 0.0, -an, 0.0)
    c = dvn / dtn
    return np.where(c < h, c, h)


def wall_penalty_np(k: np.ndarray, gap: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """NumPy twin of :func:`crashstudy.kernel.step_laws.wall_penalty`."""
    pen = np.where(-gap > 0.0, -gap, 0.0)
    fp = k * pen
    return fp, 0.5 * fp * pen


def wall_plane_np(
    vn: np.ndarray,
    gap: np.ndarray,
    dist: np.ndarray,
    v: np.ndarray,
    x: np.ndarray,
    p: np.ndarray,
    nr: np.ndarray,
    dt: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One dof's share of the normal velocity and the plane distances (the twin of ``step_laws.wall_plane``)."""
    return vn + v * nr, gap + (x - p) * nr, dist + ((x + dt * v) - p) * nr


def wall_dof_np(
    dvn: np.ndarray,
    c: np.ndarray,
    nr: np.ndarray,
    free: np.ndarray,
    v: np.ndarray,
    a: np.ndarray,
    vo: np.ndarray,
    jp: np.ndarray,
    we: np.ndarray,
) -> tuple[np.ndarray, ...]:
    """One dof at a rigid wall: (v, a, wall work, jump) (the twin of ``step_laws.wall_dof``)."""
    jmp = dvn * nr * free
    return v + jmp, a + c * nr * free, we + vo * (jmp + jp), jmp


def wall_work_np(m: np.ndarray, we: np.ndarray) -> np.ndarray:
    """The twin of ``step_laws.wall_work``."""
    return -0.5 * m * we
