"""Emitters of a generated kernel's spring stage: geometry, knot crossings, and pass A (the
``general_nonlinear`` springs). Every formula is a call of a law of :mod:`crashstudy.kernel.laws`.
"""

from __future__ import annotations

from typing import Any

from crashstudy.kernel.gen_shape import _lsum
from crashstudy.vocabulary import codes
from crashstudy.vocabulary.materials import DAMPER_MATERIALS


def sg_text(g: Any, s: int) -> str:
    """A 1-D spring's orientation as source: a literal when the same in every variant."""
    return {1: "1.0", -1: "-1.0", 0: g.R[f"sg{s}"]}[g.sign[s]]


def geometry(g: Any, ind: str, springs: list[int], pass_a: bool) -> None:
    """Elongation ``e{s}`` (and in 2-D the unit direction ``ax{s}_{d}``) of ``springs``, as the
    reference computes them; 2-D also updates the previous direction and the collapse flag."""
    D, R, emit, si, sj, static = g.D, g.R, g.emit, g.si, g.sj, g.static  # fmt: skip
    if D == 1:
        for n in sorted({m for s in springs for m in (si[s], sj[s])}):
            if not static[n]:
                emit(f"{ind}d{n} = {R[f'x{n}_0']} - {R[f'x0{n}_0']}")
        for s in springs:
            dj, di = ("0.0" if static[n] else f"d{n}" for n in (sj[s], si[s]))
            emit(f"{ind}e{s} = elongation_1d({sg_text(g, s)}, {dj}, {di})")  # 1.0 * y == y exactly
            if s in g.pre:
                emit(f"{ind}e{s} = {R[f'e0{s}']} + e{s}")
        return
    for s in springs:
        i, j = si[s], sj[s]
        for d in range(D):
            xj = R[f"xs{j}_{d}"] if static[j] else R[f"x{j}_{d}"]
            xi = R[f"xs{i}_{d}"] if static[i] else R[f"x{i}_{d}"]
            emit(f"{ind}u{d} = {xj} - {xi}")
        emit(f"{ind}ln = np.sqrt({_lsum([f'u{d} * u{d}' for d in range(D)])})")
        emit(f"{ind}turn = {_lsum([f'u{d} * ' + R[f'ap{s}_{d}'] for d in range(D)])}")
        for d in range(D):
            emit(f"{ind}{R[f'ap{s}_{d}']} = u{d}")
        emit(f"{ind}gone = collapsed(ln, {R[f'l0{s}']}, turn)")
        if not pass_a:  # the first collapsed spring in spring order (pass A's ones come first: see below)
            intact = f" and {R[f'br{s}']} == 0.0" if s in g.fragile else ""  # a broken spring may collapse
            emit(f"{ind}{R['crushed']} = {float(s)!r} if (gone and {R['crushed']} < 0.0{intact}) else {R['crushed']}")
        else:
            emit(f"{ind}gone{s} = gone")
        emit(f"{ind}dn = 1.0 if gone else ln")
        for d in range(D):
            emit(f"{ind}ax{s}_{d} = u{d} / dn")
        emit(f"{ind}e{s} = elongation_2d(ln, {R[f'l0{s}']})")
        if s in g.pre:
            emit(f"{ind}e{s} = {R[f'e0{s}']} + e{s}")



def knot_search(g: Any, ind: str, s: int, lo: str, hi: str, shift: str, ep: str, out: tuple[str, str, str]) -> None:
    """Candidate |force| of the flagged knots of spring s's curve on the path (lo, hi) (abscissa of
    the curve), with the abscissa and force of the knot that gave it: ``out`` (kc, kx, ky), as
    kernel.compiled's knot loop (``knot_peak``, the first knot starting from 0)."""
    co, emit, knots, mat = g.co, g.emit, g.knots, g.mat  # fmt: skip
    kc, kx, ky = out
    for idx, k in enumerate(knots[s]):
        yk = f"crush_knot_force({co(f'kyv{k}')})" if mat[s] == codes.CRUSH else co(f"kyv{k}")
        c0, xs0, ys0 = ("0.0", f"({ep} - {shift})", "0.0") if idx == 0 else (kc, kx, ky)
        emit(f"{ind}{kc}, {kx}, {ky} = knot_step({c0}, {xs0}, {ys0}, {lo}, {hi}, {co(f'cx{k}')}, {yk})")



def knot_post(g: Any, ind: str, s: int, kc: str, kx: str, ky: str, sh: str) -> None:
    """The crossing of spring s's winning knot: peak-force candidate, crossing fraction ``th{s}`` and
    (knot force - force interpolated in time) x axis ``dfax{s}_{d}`` (see kernel.compiled)."""
    D, R, emit = g.D, g.R, g.emit  # fmt: skip
    fp = R[f"fp{s}"]
    emit(f"{ind}th, dF = knot_crossing({kc}, {kx}, {ky}, {R[f'ep{s}']}, e{s}, {sh}, {fp}, F{s})")
    if s in g.fragile:  # a spring that breaks in this step: the step's ends only
        emit(f"{ind}kcb = 0.0 if {R[f'br{s}']} > 0.0 else {kc}")
        kc = "kcb"
    emit(f"{ind}hit{s} = ({kc} > 0.0) & (wt > 0.0)")
    emit(f"{ind}{R[f'kth{s}']} = th")
    emit(f"{ind}{R[f'kh{s}']} = 1.0 if hit{s} else 0.0")
    emit(f"{ind}nhit += 1 if hit{s} else 0")
    for d in range(D):
        axis = f"ax{s}_{d}" if D > 1 else sg_text(g, s)
        emit(f"{ind}{R[f'kdf{s}_{d}']} = dF * {axis}")
    emit(f"{ind}{R[f'pf{s}']} = peak({R[f'pf{s}']}, {kc} * afw)")



def time_curve(g: Any, ind: str, name: str, c: int, t: str) -> None:
    """``name`` = time curve c at time ``t`` (0 outside its first..last knot, with a margin: laws.time_window),
    branch-free."""
    co, emit, off, ramp = g.co, g.emit, g.off, g.ramp  # fmt: skip
    cx0, cxl = co(f"cx{off[c]}"), co(f"cx{off[c + 1] - 1}")
    emit(f"{ind}tt = {t}")
    emit(f"{ind}{name} = {ramp(c, 'tt')} if time_window(tt, {cx0}, {cxl}) else 0.0")



def vp(g: Any, n: int, d: int) -> str:
    R, static = g.R, g.static  # fmt: skip
    # a dof driven by a displacement curve: v^{n-1/2}, the slope of its segment (see the reference)
    disp = any((p, dd, kind) == (n, d, codes.PM_DISPLACEMENT) for p, dd, kind, _ in g.pm)
    return "0.0" if static[n] else f"end_rate({R[f'v{n}_{d}']}, {'0.0' if disp else R[f'a{n}_{d}']}, dtw)"



def edot(g: Any, s: int) -> str:
    """Elongation rate of spring s from v^{n-1/2} + dt/2 a^{n-1} (dampers; termination's opening test)."""
    D, si, sj = g.D, g.si, g.sj  # fmt: skip
    if D == 1:
        return f"({sg_text(g, s)} * ({vp(g, sj[s], 0)} - {vp(g, si[s], 0)}))"
    return _lsum([f"ax{s}_{d} * ({vp(g, sj[s], d)} - {vp(g, si[s], d)})" for d in range(D)])



def pass_a(g: Any, ind: str) -> None:
    D, R, ca, cb, emit, general, knotted, ramp, term = g.D, g.R, g.ca, g.cb, g.emit, g.general, g.knotted, g.ramp, g.term  # fmt: skip
    emit(f"{ind}nrev = 0")
    emit(f"{ind}for w in range(B):")
    i2 = ind + "    "
    emit(f"{i2}dtw = {R['dt']}")
    geometry(g, i2, general, True)
    if term:
        for s in general:
            emit(f"{i2}{R[f'ed{s}']} = {edot(g, s)}")
    for s in general:
        st = [R[f"st{s}_{k}"] for k in range(8)]
        emit(f"{i2}e = e{s}")
        if D > 1:
            for d in range(D):
                emit(f"{i2}{R[f'ax{s}_{d}']} = ax{s}_{d}")
            emit(f"{i2}{R[f'rev{s}']} = 2.0 if gone{s} else 0.0  # collapsed: kept for pass B")
        emit(f"{i2}mode = {st[0]}")
        emit(f"{i2}et = {st[1]}")
        emit(f"{i2}ft = {st[2]}")
        emit(f"{i2}ec = {st[3]}")
        emit(f"{i2}fc = {st[4]}")
        emit(f"{i2}ytw = {R[f'yt{s}']}")
        emit(f"{i2}ycw = {R[f'yc{s}']}")
        if s in knotted:  # on the loading curve, in its own (shifted) abscissa; state before the step
            ep = R[f"ep{s}"]
            emit(f"{i2}lo_, hi_, sh = general_window({ep}, e, mode, et, ec, {st[5]})")
            knot_search(g, i2, s, "lo_", "hi_", "sh", ep, (R[f"gkc{s}"], R[f"gkx{s}"], R[f"gky{s}"]))
            emit(f"{i2}{R[f'gksh{s}']} = sh")
        emit(f"{i2}L = {ramp(ca[s], f'(e - {st[5]})')}")
        emit(f"{i2}Ut = {ramp(cb[s], '(e - et)')}")
        emit(f"{i2}Uc = {ramp(cb[s], '(e - ec)')}")
        emit(f"{i2}{R[f'F{s}']}, {st[0]}, {st[1]}, {st[2]}, {st[3]}, {st[4]}, {st[6]}, {st[7]}, rev = general_law("
             f"e, mode, et, ft, ec, fc, {st[6]}, {st[7]}, L, Ut, Uc, ytw, ycw)")
        emit(f"{i2}{R[f'E{s}']} = e")
        emit(f"{i2}{R[f'rev{s}']} = {R[f'rev{s}']} + 1.0 if rev else {R[f'rev{s}']}"
             if D > 1 else f"{i2}{R[f'rev{s}']} = 1.0 if rev else 0.0")  # fmt: skip
        emit(f"{i2}nrev += 1 if rev else 0")
    emit(f"{ind}if nrev > 0:")
    for s in general:
        emit(f"{ind}    for w in range(B):")
        emit(f"{ind}        if {R[f'rev{s}']} == 1.0 or {R[f'rev{s}']} == 3.0:")
        rows = ", ".join(R[f"st{s}_{k}"] for k in range(8))
        emit(f"{ind}            {R[f'F{s}']}, {rows} = general_reverse_call({R[f'E{s}']}, "
             + ", ".join(R[f"st{s}_{k}"] for k in (0, 1, 2, 3, 4, 6, 7))
             + f", {R[f'yt{s}']}, {R[f'yc{s}']}, {ca[s]}, {cb[s]}, vi[w], cx, cy, cds, cs0, cs1, off)")



def failure(g: Any, ind: str, s: int) -> None:
    """A breakable spring (docs/format.md, failure): past a failure elongation it breaks at the crossing
    time interpolated in the step (``spring_fail_time``) and its force is 0 from then on; ``em{s}``, ``ai{s}``
    are the elongation and activity its extremes take (the failure elongation; 0 once broken)."""
    if s not in g.fragile:
        return
    R, emit = g.R, g.emit
    br = R[f"br{s}"]
    emit(f"{ind}was = {br} > 0.0")
    emit(f"{ind}snaps, lim_, tb = broken_at(e{s}, {R[f'ep{s}']}, {R[f'ft{s}']}, {R[f'fc{s}']}, n, dtw)")
    emit(f"{ind}snaps = snaps and af > 0.0 and (not was) and n > 0")
    emit(f"{ind}ai{s} = 0.0 if was else af")
    emit(f"{ind}em{s} = lim_ if snaps else e{s}")
    emit(f"{ind}if snaps:")
    emit(f"{ind}    spring_fail_time[{s}, vi[w]] = tb")
    emit(f"{ind}    {br} = 1.0")
    emit(f"{ind}F{s} = 0.0 if {br} > 0.0 else F{s}")



def pass_k(g: Any, ind: str) -> None:
    """|a| at this step's knot crossings (only run when a lane crossed one): a interpolated in time
    plus the kinked spring's correction, as kernel.compiled (rows kth, kdf, kh, ao, a)."""
    D, R, emit, knotted, movable, si, sj, static = g.D, g.R, g.emit, g.knotted, g.movable, g.si, g.sj, g.static  # fmt: skip
    emit(f"{ind}if nhit > 0:")
    emit(f"{ind}    for w in range(B):")
    i2 = ind + "        "
    emit(f"{i2}af = 1.0 if fn <= {R['lim']} else 0.0")
    for s in knotted:
        emit(f"{i2}th = {R[f'kth{s}']}")
        for side, p in enumerate((si[s], sj[s])):
            if static[p] or not movable[p]:
                continue
            emit(f"{i2}a2 = 0.0")
            for d in range(D):
                emit(f"{i2}ai = knot_accel({R[f'ao{p}_{d}']}, {R[f'a{p}_{d}']}, th, {R[f'kdf{s}_{d}']}, "
                     f"{R[f'im{p}_{d}']}, {side})")
                emit(f"{i2}a2 = a2 + ai * ai")
            emit(f"{i2}{R[f'pa{p}']} = peak({R[f'pa{p}']}, (a2 if {R[f'kh{s}']} > 0.0 else 0.0) * af)")



def pass_b_springs(g: Any, i2: str) -> None:
    """Pass B's springs (every material but ``general_nonlinear``, whose force pass A left in rows) and
    the summaries of every spring; the reference walks the springs in order, and 2-D's "first
    collapsed spring" needs that order. The material dispatch is one line per law."""
    D, R, S, ca, emit, hist, knotted, mat, ramp = g.D, g.R, g.S, g.ca, g.emit, g.hist, g.knotted, g.mat, g.ramp  # fmt: skip
    for s in range(S):
        if mat[s] == codes.GENERAL:
            emit(f"{i2}F{s} = {R[f'F{s}']}")
            emit(f"{i2}e{s} = {R[f'E{s}']}")
            if D > 1:
                for d in range(D):
                    emit(f"{i2}ax{s}_{d} = {R[f'ax{s}_{d}']}")
                intact = f" and {R[f'br{s}']} == 0.0" if s in g.fragile else ""
                emit(f"{i2}{R['crushed']} = {float(s)!r} if ({R[f'rev{s}']} >= 2.0 and {R['crushed']} < 0.0{intact})"
                     f" else {R['crushed']}")  # fmt: skip
            failure(g, i2, s)
            if s in knotted:
                knot_post(g, i2, s, R[f"gkc{s}"], R[f"gkx{s}"], R[f"gky{s}"], R[f"gksh{s}"])
            continue
        geometry(g, i2, [s], False)
        k = mat[s]
        if k == codes.LINEAR:
            emit(f"{i2}F{s} = linear_force({R[f'kp{s}']}, e{s})")
        elif k == codes.DAMPER:
            emit(f"{i2}F{s} = damper_force({R[f'kp{s}']}, {edot(g, s)})")
        elif k == codes.NONLINEAR:
            emit(f"{i2}F{s} = nonlinear_force({ramp(ca[s], f'e{s}')})")
            if s in knotted:  # the whole path
                emit(f"{i2}lo_, hi_, sh = nonlinear_window({R[f'ep{s}']}, e{s})")
                knot_search(g, i2, s, "lo_", "hi_", "sh", R[f"ep{s}"], ("kc", "kx", "ky"))
        elif k == codes.CRUSH:
            emin, fstar = R[f"st{s}_0"], R[f"st{s}_1"]
            emit(f"{i2}emin = {emin}")
            emit(f"{i2}F{s}, {emin}, {fstar} = crush_law(e{s}, emin, {fstar}, {ramp(ca[s], f'e{s}')}, {R[f'kp{s}']})")
            if s in knotted:  # (e, e_min before the step): crushing further
                emit(f"{i2}lo_, hi_, sh = crush_window(e{s}, emin)")
                knot_search(g, i2, s, "lo_", "hi_", "sh", R[f"ep{s}"], ("kc", "kx", "ky"))
        elif k == codes.ELASTOPLASTIC:
            st0, st1 = R[f"st{s}_0"], R[f"st{s}_1"]
            emit(f"{i2}F{s}, {st0}, {st1} = elastoplastic_law(e{s}, {st0}, {st1}, {R[f'kp{s}']}, {R[f'kt{s}']}, "
                 f"{R[f'fy{s}']})")
        elif k == codes.NONLINEAR_DAMPER:
            emit(f"{i2}rd = {edot(g, s)}")
            emit(f"{i2}F{s} = {ramp(ca[s], 'rd')}")
        elif k == codes.RATE_ELASTIC:  # the first curve, then each neighbouring pair folded in by the rate
            rc = g.rc[s]
            emit(f"{i2}rd = abs({edot(g, s)})")
            emit(f"{i2}F{s} = {ramp(rc[0], f'e{s}')}")
            for q in range(len(rc) - 1):
                emit(f"{i2}F{s} = rate_segment(F{s}, rd, {R[f'rt{s}_{q}']}, {R[f'rt{s}_{q + 1}']}, "
                     f"{ramp(rc[q], f'e{s}')}, {ramp(rc[q + 1], f'e{s}')})")
        else:  # pragma: no cover - the compiler knows no other material
            raise ValueError(f"material code {k}")
        failure(g, i2, s)
        if s in knotted:  # after a failure check: a spring that breaks in this step takes no knot
            knot_post(g, i2, s, "kc", "kx", "ky", "sh")
    # summaries in spring order (the reference kernel's order of operations)
    emit(f"{i2}ie_tot = 0.0")
    for s in range(S):
        ie = R[f"ie{s}"]
        step = f"energy_increment({ie}, F{s}, {R[f'fp{s}']}, e{s}, {R[f'ep{s}']}, afw)"
        if s in g.pre and mat[s] not in DAMPER_MATERIALS:  # a preload's first half step
            half = f"energy_first_half({ie}, F{s}, {R[f'fp{s}']}, e{s}, {R[f'ep{s}']}, {R['dt']}, {R[f'r0{s}']}, afw)"
            step = f"{half} if (n1 and {R[f'e0{s}']} != 0.0) else {step}"
        emit(f"{i2}{ie} = {step}")
        emit(f"{i2}ie_tot = ie_tot + {ie}")
        emit(f"{i2}{R[f'pf{s}']} = peak({R[f'pf{s}']}, abs(F{s}) * af)")
        em, ai = (f"em{s}", f"ai{s}") if s in g.fragile else (f"e{s}", "af")  # extremes while intact
        emit(f"{i2}{R[f'mc{s}']} = peak({R[f'mc{s}']}, -{em} * {ai})")
        emit(f"{i2}{R[f'me{s}']} = peak({R[f'me{s}']}, {em} * {ai})")
        emit(f"{i2}{R[f'fp{s}']} = F{s}")
        emit(f"{i2}{R[f'ep{s}']} = e{s}")
        if hist and D > 1:
            for d in range(D):
                emit(f"{i2}{R[f'axh{s}_{d}']} = ax{s}_{d}")
