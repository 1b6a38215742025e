"""The generic kernel's set-up and rare steps, called once per block or on rare steps (so a call's cost,
numba increfs every array argument, does not matter): which features the model has, the block's arrays,
and the lanes that fail. The step loop is :mod:`crashstudy.kernel.compiled`; its stages
:mod:`crashstudy.kernel.generic_springs` and :mod:`crashstudy.kernel.generic_nodes`; the outputs
:mod:`crashstudy.kernel.generic_outputs`.
"""

from __future__ import annotations

import functools
import inspect
from collections import namedtuple
from collections.abc import Callable
from typing import Any

import numpy as np
from numba.core import compiler
from numba.core.cpu import CPUTargetOptions
from numba.core.registry import cpu_target
from numba.extending import intrinsic

from crashstudy.kernel.step_laws import unstable, unstable_limit, wall_gives
from crashstudy.vocabulary.codes import (
    CRUSHED_TO_ZERO,
    INVALID,
    NSTATE,
    PM_DISPLACEMENT,
    UNSTABLE,
    UNSTABLE_WALLS,
)
from crashstudy.vocabulary.materials import KNOT_MATERIALS, STATE_MATERIALS

_FLAGS: dict[str, Any] = {
    "nopython": True,
    "nogil": True,
    "no_cpython_wrapper": True,
    "no_cfunc_wrapper": True,
}


def stage(py_func: Callable[..., Any], nrt: bool = False, inline: bool = False) -> Any:
    """The generic kernel's compiled functions (this module's and its stages'), callable from compiled code only
    (a call from Python raises): typed and lowered once per argument types with the flags of
    ``numba.njit(nogil=True, no_cpython_wrapper=True, no_cfunc_wrapper=True)``, then linked into the caller
    and called (numba's ``compile_internal`` path, as its own builtins: an ``intrinsic`` whose code is a
    call). Not a dispatcher: no dispatcher typing per call site, no disk-cache entry of its own (``_run``'s
    holds the whole kernel), and records read once (see ``compiled._run``): the cold compile -23 %
    (benchmarks/results/generic_compile.md). numba IR inlining (``inline="always"``) re-typed every copy
    (1.6x longer). ``nrt=False`` (the per-step stages): compiled without numba's reference counting, so a call does
    not incref / decref each of its ~20 array arguments; safe because no stage allocates or returns an array
    (without NRT numba refuses both at compile time: "Only accept returning of array passed into the function as
    argument", which ``np.empty``'s own implementation hits; tests/test_generic_stage.py), none keeps an array past
    its call (the caller's block arrays outlive it), and what they call (``laws``, ``step_laws``, other stages)
    takes and returns scalars or borrows the caller's arrays; only :func:`flags` and :func:`block_arrays`, which
    allocate, keep NRT (the 1179-spring grid, 1 variant: simulate 5.2-5.6 -> 4.2-4.4 s, docs/kernels.md).
    ``inline=True`` (:data:`hot_stage`, the per-spring stages called on every spring and step): the LLVM function
    gets ``alwaysinline`` before it is linked, so LLVM inlines it into ``_run``'s spring loop (the call passed every
    array as ~10 words; with numba's debug info on, the stage stays ``noinline``, numba's choice)."""
    done: dict[tuple[Any, ...], Any] = {}

    def typer(typingctx: Any, *args: Any) -> Any:
        if args not in done:
            flags: Any = compiler.Flags()
            CPUTargetOptions.parse_as_flags(flags, _FLAGS)
            flags.no_compile = True
            flags.nrt = nrt
            cres = compiler.compile_extra(
                typingctx, cpu_target.target_context, py_func, args, None, flags, {}
            )
            fn = cres.library._final_module.get_function(cres.fndesc.llvm_func_name)
            # LLVM inlines it into its caller (set before the module is first linked); not with debug info
            # (NUMBA_DEBUGINFO, NUMBA_ENABLE_PROFILING): numba makes the function noinline, LLVM rejects both
            if inline and b"noinline" not in list(fn.attributes):
                fn.add_function_attribute("alwaysinline")
            done[args] = cres
        cres = done[args]

        def codegen(context: Any, builder: Any, sig: Any, llargs: Any) -> Any:
            context.active_code_library.add_linking_library(cres.library)
            return context.call_internal(builder, cres.fndesc, sig, llargs)

        return cres.signature, codegen

    # the intrinsic takes py_func's arguments by name (numba reads them from the signature)
    params = list(inspect.signature(py_func).parameters.values())
    first = inspect.Parameter("typingctx", inspect.Parameter.POSITIONAL_OR_KEYWORD)
    typer.__signature__ = inspect.Signature([first, *params])  # type: ignore[attr-defined]
    typer.__name__ = typer.__qualname__ = py_func.__name__
    typer.__doc__ = py_func.__doc__
    return intrinsic(typer)


#: a stage LLVM inlines into its caller (the per-spring stages of the step, see :func:`stage`)
hot_stage = functools.partial(stage, inline=True)


#: rows of the per-spring options array of a block: preloaded (initial_elongation), breakable (failure)
PRELOADED, BREAKABLE = 0, 1
#: the arrays of a block, one record for the stages of the step (inputs copied per lane, state, scratch,
#: summaries; see :func:`block_arrays` for each one's meaning and shape)
Block = namedtuple(  # type: ignore[misc]
    "Block",
    "m_b im_b x0_b sg_b l0_b kp_b cx_b cy_b ds_b ky_b s0_b yt_b yc_b g_arg g_argt g_argc g_L g_Ut "
    "g_Uc g_rev dt_b x v vnew f fext fext_prev acc acc_prev k_sh k_c k_x k_y k_any k_hit k_th k_dfax "
    "jump_prev pm_acc axis_prev state forces elong f_prev e_prev ie pf mc pacc pwall e_tmp ed_tmp "
    "F_tmp ax_tmp edot_min crushed work wall_e wmax ke0 ke ie_tot err bal wforce act actf n_fail nst "
    "next_rec st_ok me broken options ftmp e_init",
)


@functools.partial(stage, nrt=True)
def flags(T, P, H):  # pragma: no cover - compiled
    """What the model contains: (has_state, has_gravity, no_ext, any_hist, has_term, movable, knotted, any_knot,
    pm_disp: (N, D) the dofs driven by a displacement curve, whose rate is v^{n-1/2} (see the reference))."""
    material, gravity, rec_mask, ke_fraction, free = T.material, P.gravity, H.rec, P.ke_fraction, T.free
    pm_node, curve_a, off, knot_check, pm_kind, pm_dir = (
        T.pm_node,
        T.curve_a,
        T.curve_off,
        T.knot_check,
        T.pm_kind,
        T.pm_dir,
    )
    N, D, _ = P.x0.shape
    S = T.spring_i.shape[0]
    NL = T.load_node.shape[0]
    NP = pm_node.shape[0]
    has_state = False
    for s in range(S):
        if material[s] in STATE_MATERIALS:
            has_state = True
    has_gravity = False
    for d in range(D):
        for q in range(gravity.shape[1]):
            if gravity[d, q] != 0.0:
                has_gravity = True
    no_ext = NL == 0 and NP == 0 and not has_gravity
    any_hist = False
    for h in range(rec_mask.shape[0]):
        any_hist = any_hist or rec_mask[h]
    has_term = False
    for q in range(ke_fraction.shape[0]):
        if ke_fraction[q] > 0.0:
            has_term = True
    movable = np.zeros(N, dtype=np.bool_)
    for n_ in range(N):
        for d in range(D):
            if free[n_, d] > 0.0:
                movable[n_] = True
    for k in range(NP):
        movable[pm_node[k]] = True
    # springs whose curve has a knot that can be a local maximum of |force| (Batch.knot_check)
    knotted = np.zeros(S, dtype=np.bool_)
    any_knot = False
    for s in range(S):
        ca = curve_a[s]
        if material[s] in KNOT_MATERIALS and ca >= 0:
            for k in range(off[ca] + 1, off[ca + 1] - 1):
                if knot_check[k]:
                    knotted[s] = True
                    any_knot = True
    pm_disp = np.zeros((N, D), dtype=np.bool_)
    for k in range(NP):
        if pm_kind[k] == PM_DISPLACEMENT:
            pm_disp[pm_node[k], pm_dir[k]] = True
    return has_state, has_gravity, no_ext, any_hist, has_term, movable, knotted, any_knot, pm_disp


@functools.partial(stage, nrt=True)
def block_arrays(lo, B, has_state, any_knot, T, P, Out):  # pragma: no cover - compiled
    """The block's copies of its variants' inputs and its state, zeroed or set to the initial state;
    invalid variants are marked; preloaded springs (``initial_elongation``) start from the batch's state and
    IE0, and ``e_init`` holds KE0 + IE0 (row 0) and the error's scale KE0 + |IE0| (row 1). Returns the
    arrays (a :data:`Block`) and the largest step count."""
    si, sj, pm_node = T.spring_i, T.spring_j, T.pm_node
    mass, inv_mass, x0, v0, length0, sign, kpar = P.mass, P.inv_mass, P.x0, P.v0, P.length0, P.sign, P.kpar
    yield_t, yield_c, cx, cy, cds, cs0, knot_y = P.yield_t, P.yield_c, P.cx, P.cy, P.cds, P.cs0, P.knot_y
    dt, n_steps, invalid, fail_item, fail_time = P.dt, P.n_steps, P.invalid, Out.fail_item, Out.fail_time
    ie0_, e0, fail_t, fail_c, state0 = P.ie0, P.e0, P.fail_t, P.fail_c, P.state0
    # (T, P and Out read here only: a record read in a loop is reloaded whole each time, see compiled._run)
    N, D, _ = x0.shape
    S = si.shape[0]
    K = cx.shape[0]
    C = cs0.shape[0]
    W = T.wall_nodes.shape[0]
    NP = pm_node.shape[0]
    # block-local copies of the per-variant inputs (contiguous, cache-resident)
    m_b = np.empty((N, B))
    im_b = np.empty((N, D, B))
    x0_b = np.empty((N, D, B))
    sg_b = np.empty((S, B))
    l0_b = np.empty((S, B))
    kp_b = np.empty((S, B))
    cx_b = np.empty((K, B))
    cy_b = np.empty((K, B))
    ds_b = np.empty((K, B))
    ky_b = np.empty((K, B))
    s0_b = np.empty((C, B))
    yt_b = np.empty((S, B))
    yc_b = np.empty((S, B))
    g_arg = np.empty(B)
    g_argt = np.empty(B)
    g_argc = np.empty(B)
    g_L = np.empty(B)
    g_Ut = np.empty(B)
    g_Uc = np.empty(B)
    g_rev = np.zeros(B, dtype=np.bool_)
    dt_b = np.empty(B)
    for w in range(B):
        dt_b[w] = dt[lo + w]
    for n_ in range(N):
        for w in range(B):
            m_b[n_, w] = mass[n_, lo + w]
        for d in range(D):
            for w in range(B):
                im_b[n_, d, w] = inv_mass[n_, d, lo + w]
                x0_b[n_, d, w] = x0[n_, d, lo + w]
    for s in range(S):
        for w in range(B):
            sg_b[s, w] = sign[s, lo + w]
            yt_b[s, w] = yield_t[s, lo + w]
            yc_b[s, w] = yield_c[s, lo + w]
            l0_b[s, w] = length0[s, lo + w]
            kp_b[s, w] = kpar[s, lo + w]
    for k in range(K):
        for w in range(B):
            cx_b[k, w] = cx[k, lo + w]
            cy_b[k, w] = cy[k, lo + w]
            ds_b[k, w] = cds[k, lo + w]
            ky_b[k, w] = knot_y[k, lo + w]
    for c in range(C):
        for w in range(B):
            s0_b[c, w] = cs0[c, lo + w]
    # state
    x = np.empty((N, D, B))
    v = np.empty((N, D, B))
    vnew = np.empty((N, D, B))
    f = np.empty((N, D, B))
    fext = np.zeros((N, D, B))
    fext_prev = np.zeros((N, D, B))
    acc = np.zeros((N, D, B))  # a^{n-1} at the start of step n (dampers' velocity estimate)
    acc_prev = np.zeros((N, D, B) if any_knot else (0, D, B))  # a^{n-1} during step n (knot crossings)
    k_sh = np.empty(B)  # knot test: shift of the curve's abscissa (general_nonlinear)
    k_c = np.empty(B)  # candidate |force|, and the abscissa and force of the knot that gave it
    k_x = np.empty(B)
    k_y = np.empty(B)
    k_any = np.zeros(S, dtype=np.bool_)  # some lane of the block passed over a knot of spring s this step
    k_hit = np.zeros((S if any_knot else 0, B), dtype=np.bool_)  # this lane did
    k_th = np.zeros((S if any_knot else 0, B))  # crossing fraction of the step at that knot
    k_dfax = np.zeros((S if any_knot else 0, D, B))  # (knot force - interpolated force) * axis
    jump_prev = np.zeros((W, N, D, B))
    pm_acc = np.zeros((NP, B))  # kinematic acceleration of each prescribed dof
    axis_prev = np.zeros((S if D > 1 else 0, D, B))  # 2-D: previous spring direction (un-normalised)
    if D > 1:
        for s in range(S):
            for d in range(D):
                for w in range(B):
                    axis_prev[s, d, w] = x0_b[sj[s], d, w] - x0_b[si[s], d, w]
    state = np.zeros((S if has_state else 0, NSTATE, B))
    forces = np.zeros((S, B))
    elong = np.zeros((S, B))
    f_prev = np.zeros((S, B))
    e_prev = np.zeros((S, B))
    ie = np.zeros((S, B))
    pf = np.zeros((S, B))
    mc = np.zeros((S, B))
    pacc = np.zeros((N, B))
    pwall = np.zeros((W, B))
    e_tmp = np.empty(B)
    ed_tmp = np.empty(B)
    F_tmp = np.empty(B)
    ax_tmp = np.empty((D, B))
    edot_min = np.empty(B)
    crushed = np.empty(B, dtype=np.int64)
    work = np.zeros(B)
    wall_e = np.zeros(B)
    wmax = np.zeros(B)
    ke0 = np.zeros(B)
    ke = np.zeros(B)
    ie_tot = np.zeros(B)
    err = np.zeros(B)
    bal = np.zeros(B)
    wforce = np.zeros((W, B))
    act = np.empty(B, dtype=np.bool_)
    actf = np.empty(B)  # 1.0 while the variant runs, else 0.0 (arithmetic masks vectorise)
    n_fail = np.full(B, -1, dtype=np.int64)
    nst = np.empty(B, dtype=np.int64)
    next_rec = np.zeros(B, dtype=np.int64)
    st_ok = np.zeros(B, dtype=np.int64)
    nmax = -1
    for w in range(B):
        q = lo + w
        nst[w] = n_steps[q]
        if invalid[q] > 0:
            st_ok[w] = INVALID
            fail_item[q] = invalid[q]
            fail_time[q] = 0.0
        elif nst[w] > nmax:
            nmax = nst[w]
    for n_ in range(N):
        for d in range(D):
            for w in range(B):
                x[n_, d, w] = x0_b[n_, d, w]
                v[n_, d, w] = v0[n_, d, lo + w]
                ke0[w] += 0.5 * m_b[n_, w] * v[n_, d, w] * v[n_, d, w]
    # spring options: max elongation, broken springs, (preloaded, breakable) per spring, the
    # elongation / activity the extremes of a breakable spring take in this step, KE0 + IE0
    me = np.zeros((S, B))
    broken = np.zeros((S, B), dtype=np.bool_)
    options = np.zeros((2, S), dtype=np.bool_)  # rows PRELOADED, BREAKABLE
    ftmp = np.empty((2, B))
    e_init = np.zeros(
        (2, B)
    )  # KE0 + IE0 (the energy at t = 0), KE0 + |IE0| (the error's and stop tests' scale)
    for s in range(S):
        for w in range(B):
            q = lo + w
            ie[s, w] = ie0_[s, q]
            options[PRELOADED, s] = options[PRELOADED, s] or e0[s, q] != 0.0
            options[BREAKABLE, s] = options[BREAKABLE, s] or fail_t[s, q] < np.inf or fail_c[s, q] > -np.inf
    if has_state and state0.shape[0] > 0:
        for s in range(S):
            for k in range(NSTATE):
                for w in range(B):
                    state[s, k, w] = state0[s, k, lo + w]
    for w in range(B):
        ie0 = 0.0
        for s in range(S):
            ie0 = ie0 + ie0_[s, lo + w]
        e_init[0, w] = ke0[w] + ie0
        e_init[1, w] = ke0[w] + abs(ie0)

    return Block(
        m_b,
        im_b,
        x0_b,
        sg_b,
        l0_b,
        kp_b,
        cx_b,
        cy_b,
        ds_b,
        ky_b,
        s0_b,
        yt_b,
        yc_b,
        g_arg,
        g_argt,
        g_argc,
        g_L,
        g_Ut,
        g_Uc,
        g_rev,
        dt_b,
        x,
        v,
        vnew,
        f,
        fext,
        fext_prev,
        acc,
        acc_prev,
        k_sh,
        k_c,
        k_x,
        k_y,
        k_any,
        k_hit,
        k_th,
        k_dfax,
        jump_prev,
        pm_acc,
        axis_prev,
        state,
        forces,
        elong,
        f_prev,
        e_prev,
        ie,
        pf,
        mc,
        pacc,
        pwall,
        e_tmp,
        ed_tmp,
        F_tmp,
        ax_tmp,
        edot_min,
        crushed,
        work,
        wall_e,
        wmax,
        ke0,
        ke,
        ie_tot,
        err,
        bal,
        wforce,
        act,
        actf,
        n_fail,
        nst,
        next_rec,
        st_ok,
        me,
        broken,
        options,
        ftmp,
        e_init,
    ), nmax


@stage
def fail_lanes(n, lo, B, D, e_floor, Out, K):  # pragma: no cover - compiled
    """A step where some lane failed (rare): unstable (energy balance, or walls that gave energy) or, in 2-D,
    a spring crushed to zero length; those lanes stop."""
    act, actf, bal, e_scale, wmax, crushed, st_ok = (
        K.act,
        K.actf,
        K.bal,
        K.e_init[1],
        K.wmax,
        K.crushed,
        K.st_ok,
    )
    n_fail, dt_b, wall_e, fail_item, fail_time = K.n_fail, K.dt_b, K.wall_e, Out.fail_item, Out.fail_time
    for w in range(B):
        if not act[w]:
            continue
        lim = unstable_limit(e_scale[w], wmax[w], e_floor[lo + w])
        if unstable(bal[w], lim):
            st_ok[w] = UNSTABLE
        elif wall_gives(wall_e[w] if n > 0 else 0.0, lim):  # the balance held: fail_item names the walls
            st_ok[w] = UNSTABLE
            fail_item[lo + w] = UNSTABLE_WALLS
        elif D > 1 and crushed[w] >= 0:
            st_ok[w] = CRUSHED_TO_ZERO
            fail_item[lo + w] = crushed[w]
        else:
            continue
        fail_time[lo + w] = n * dt_b[w]
        n_fail[w] = n
        act[w] = False
        actf[w] = 0.0
