"""The per-step laws of both fast kernels that are not spring forces: the central-difference node
update, the spring summaries, energies and the energy balance, prescribed motion, the stop test and the
walls. Small pure compiled scalar functions, as :mod:`crashstudy.kernel.laws` (whose module docstring
says how they are compiled and called); their NumPy twins are in :mod:`crashstudy.kernel.reference`
and :mod:`crashstudy.kernel.step_twins`.
"""

from __future__ import annotations

from crashstudy.kernel.cache import cached_njit
from crashstudy.kernel.laws import peak
from crashstudy.vocabulary.codes import PM_ACCELERATION, PM_DISPLACEMENT, UNSTABLE_ENERGY, WALL_PASSIVITY

_jit = cached_njit(nogil=True, error_model="numpy")


# ---- the central-difference node update (docs/solver.md) -------------------------------------


@_jit
def half_step(vo, a, dtn):  # pragma: no cover - compiled
    """v^{n+1/2} = v^{n-1/2} + dtn a^n (``dtn`` = dt, or dt/2 in step 0)."""
    return vo + dtn * a


@_jit
def advance(x, vo, vn, dt, af):  # pragma: no cover - compiled
    """x^{n+1} = x^n + dt v^{n+1/2} and the velocity kept, for a running variant (``af`` 1.0); a stopped
    one (``af`` 0.0, ``vn`` finite) keeps x and v."""
    return x + (dt * af) * vn, vn * af + vo * (1.0 - af)


@_jit
def kinetic(ke, m, vo, vn):  # pragma: no cover - compiled
    """Kinetic energy at t^n of one dof, m v^{n-1/2} v^{n+1/2} / 2, added to ``ke``."""
    return ke + 0.5 * m * vo * vn


# ---- a spring's summaries --------------------------------------------------------------------


@_jit
def spring_extremes(pf, mc, me, F, af, em, ai):  # pragma: no cover - compiled
    """Peak |force|, largest crush and largest elongation of a spring; ``af`` 1.0 while the variant runs,
    ``em``/``ai`` the elongation and activity the extremes take (a breakable spring: up to its break)."""
    return peak(pf, abs(F) * af), peak(mc, -em * ai), peak(me, em * ai)


# ---- energies, prescribed motion, stop test, walls -------------------------------------------


@_jit
def energy_increment(ie, F, fp, e, ep, af):  # pragma: no cover - compiled
    """Work done on a spring (trapezoid), ``af`` 1.0 while the variant runs (0.0 adds an exact 0)."""
    return ie + (0.5 * (F + fp) * (e - ep)) * af


@_jit
def energy_first_half(ie, F, fp, e, ep, dt, rate0, af):  # pragma: no cover - compiled
    """The first step of a preloaded spring: F^0 acts on the mean of the rates at 0 and 1/2 for dt/2."""
    return ie + ((0.5 * F + 0.25 * fp) * (e - ep) + 0.25 * dt * fp * rate0) * af


@_jit
def ext_power(bal, fx, v, fxp, vb):  # pragma: no cover - compiled
    """External power of one dof (trapezoid with the previous step's force ``fxp``), added to ``bal``."""
    return bal + 0.5 * (fx * v + fxp * vb)


@_jit
def work_increment(work, bal, dt, af):  # pragma: no cover - compiled
    return work + (bal * dt) * af


@_jit
def prescribed_time(kind, t, dt):  # pragma: no cover - compiled
    """When the step from ``t`` reads a prescribed motion's curve: a displacement at the step's end
    ``t + dt``, an acceleration at ``t``, a velocity at the half step ``t + dt/2`` (docs/solver.md)."""
    if kind == PM_DISPLACEMENT:
        return t + dt
    if kind == PM_ACCELERATION:
        return t
    return t + 0.5 * dt


@_jit
def prescribed_velocity(kind, x0, scale, tc, x, vo, dt, dtn):  # pragma: no cover - compiled
    """``v^{n+1/2}`` of a driven dof from its curve's value ``tc`` (times ``scale``): the velocity that
    lands it on ``x0 + scale tc``, the velocity ``vo`` plus ``dtn`` times the acceleration, or the velocity."""
    if kind == PM_DISPLACEMENT:
        return ((x0 + scale * tc) - x) / dt
    if kind == PM_ACCELERATION:
        return vo + dtn * scale * tc
    return scale * tc


@_jit
def prescribed_step(last, vn, vo, pa, dtn):  # pragma: no cover - compiled
    """(``v^{n+1/2}``, ``a^n``) of a driven dof; the last step (whose update would read the curve past
    end_time) continues with the previous acceleration ``pa``."""
    if last:
        return vo + dtn * pa, pa
    return vn, (vn - vo) / dtn


@_jit
def stop_test(kef, fsum, psum, ke, scale, wmax, opening):  # pragma: no cover - compiled
    """Early termination (docs/format.md, ``termination``): the sum of |spring force| has fallen to
    ``kef`` (kinetic_energy_fraction) of the sum of the peaks, and the kinetic energy to ``kef`` of the
    energy scale (KE0 + |IE0| + max |W_ext|) or every spring is opening (``opening``)."""
    return (fsum <= kef * psum) & ((ke <= kef * (scale + wmax)) | opening)


@_jit
def energy_balance(ke, ie, wall, e_init, work):  # pragma: no cover - compiled
    """The energy balance error of one variant, ``|KE + IE + E_wall - E^0 - W_ext|`` (docs/solver.md)."""
    return abs((((ke + ie) + wall) - e_init) - work)


@_jit
def unstable_limit(scale, wmax, floor):  # pragma: no cover - compiled
    """The largest energy balance error of a stable run: ``UNSTABLE_ENERGY`` times the energy scale
    (KE0 + |IE0|) plus the largest |external work| so far, plus the variant's round-off floor."""
    return UNSTABLE_ENERGY * (scale + wmax) + floor


@_jit
def unstable(bal, limit):  # pragma: no cover - compiled
    """The run is unstable: its energy balance error is above the limit, or not a number."""
    return not (bal <= limit)


@_jit
def wall_gives(wall, limit):  # pragma: no cover - compiled
    """The walls have given energy: the energy they have taken is below -``WALL_PASSIVITY`` x ``limit``
    (``unstable_limit``'s). Only an unstable step can do it: it throws a node through the wall, whose jump
    lands it on the plane, so the balance still closes (docs/solver.md, "Instability tests")."""
    return wall < -WALL_PASSIVITY * limit


@_jit
def wall_plane(vn, gap, dist, v, x, p, nr, dt):  # pragma: no cover - compiled
    """One dof's share of a node's normal velocity ``vn``, its distance ``gap`` from a wall's plane at x^n
    and ``dist`` at x^n + dt v^{n+1/2} (``p`` the plane's point, ``nr`` its normal), added dof by dof."""
    return vn + v * nr, gap + (x - p) * nr, dist + ((x + dt * v) - p) * nr


@_jit
def wall_dof(dvn, c, nr, free, v, a, vo, jp, we):  # pragma: no cover - compiled
    """One dof of a node at a rigid wall: the velocity jump ``dvn`` along the normal joins v^{n+1/2}, the
    held acceleration ``c`` joins a^n (``free`` 0 on a fixed dof), and the wall work of this step's and the
    previous step's jumps ``jp`` at v^{n-1/2} (``vo``) joins ``we``; returns (v, a, we, this jump)."""
    jmp = dvn * nr * free
    return v + jmp, a + c * nr * free, we + vo * (jmp + jp), jmp


@_jit
def wall_work(m, we):  # pragma: no cover - compiled
    """Energy a rigid wall takes from a node of mass ``m`` (impulses of both steps at v^{n-1/2})."""
    return -0.5 * m * we


@_jit
def wall_jump(vn, gap, dist, dt, k):  # pragma: no cover - compiled
    """Normal velocity change that lands a node crossing a rigid wall (``k`` = 0) exactly on the plane."""
    return (-gap / dt - vn) if ((dist < 0.0) & (vn < 0.0) & (k == 0.0)) else 0.0


@_jit
def wall_penalty(k, gap):  # pragma: no cover - compiled
    """Penalty wall of contact stiffness ``k`` (0: rigid, an exact 0): (force k pen along the normal,
    stored energy k pen^2 / 2) for the penetration ``pen = max(0, -gap)``."""
    pen = -gap if -gap > 0.0 else 0.0
    fp = k * pen
    return fp, 0.5 * fp * pen


@_jit
def wall_hold(dvn, an, dtn):  # pragma: no cover - compiled
    """The normal acceleration a rigid wall cancels in this step (per unit mass, >= 0): the part of its
    velocity jump ``dvn`` that the node's own forces (normal acceleration ``an``) pushed into the wall
    over the velocity update ``dtn``; the rest of the jump is the impact (docs/solver.md, "Rigid walls")."""
    h = -an if -an > 0.0 else 0.0
    c = dvn / dtn
    return c if c < h else h


@_jit
def wall_impulse(m, dvn, c, dtn):  # pragma: no cover - compiled
    """Impact impulse of one node in one step: the momentum its jump removes beyond the held part ``c dtn``."""
    d = dvn - c * dtn
    return m * (d if d > 0.0 else 0.0)


@_jit
def wall_force(m, c):  # pragma: no cover - compiled
    """Contact force of a held node: the reaction ``m c`` to the forces pushing it into the wall."""
    return m * c
