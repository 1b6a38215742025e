"""Emitters of a generated kernel's spring stage: geometry, knot crossings, and pass A (the
``general_nonlinear`` springs). Every formula is a call of a law of :mod:`crashstudy.kernel.laws`.
"""

from __future__ import annotations

from crashstudy.kernel.gen_shape import Layout, _lsum
from crashstudy.vocabulary import codes
from crashstudy.vocabulary.materials import DAMPER_MATERIALS


def sg_text(g: Layout, s: int) -> str:
    """A 1-D spring's orientation as source: a literal when the same in every variant."""
    return {1: "1.0", -1: "-1.0", 0: g.R["sg", s]}[g.sign[s]]


def geometry(g: Layout, ind: str, springs: list[int], pass_a: bool) -> None:
    """Elongation ``e{s}`` (and in 2-D the unit direction ``ax{s}_{d}``) of ``springs``, as the
    reference computes them; 2-D also updates the previous direction and the collapse flag."""
    if g.D == 1:
        for n in sorted({m for s in springs for m in (g.si[s], g.sj[s])}):
            if not g.static[n]:
                g.emit(f"{ind}d{n} = {g.R['x', n, 0]} - {g.R['x0', n, 0]}")
        for s in springs:
            dj, di = ("0.0" if g.static[n] else f"d{n}" for n in (g.sj[s], g.si[s]))
            g.emit(f"{ind}e{s} = elongation_1d({sg_text(g, s)}, {dj}, {di})")  # 1.0 * y == y exactly
            if s in g.pre:
                g.emit(f"{ind}e{s} = {g.R['e0', s]} + e{s}")
        return
    for s in springs:
        i, j = g.si[s], g.sj[s]
        for d in range(g.D):
            xj = g.R["xs", j, d] if g.static[j] else g.R["x", j, d]
            xi = g.R["xs", i, d] if g.static[i] else g.R["x", i, d]
            g.emit(f"{ind}u{d} = {xj} - {xi}")
        ap = [g.R["ap", s, d] for d in range(2)]
        g.emit(f"{ind}ax{s}_0, ax{s}_1, ln, gone = axis_2d(u0, u1, {ap[0]}, {ap[1]}, {g.R['l0', s]})")
        for d in range(2):
            g.emit(f"{ind}{ap[d]} = u{d}")
        if not pass_a:  # the first collapsed spring in spring order (pass A's ones come first: see below)
            intact = f" and {g.R['br', s]} == 0.0" if s in g.fragile else ""  # a broken spring may collapse
            g.emit(
                f"{ind}{g.R['crushed']} = {float(s)!r} if (gone and {g.R['crushed']} < 0.0{intact}) else {g.R['crushed']}"
            )
        else:
            g.emit(f"{ind}gone{s} = gone")
        g.emit(f"{ind}e{s} = elongation_2d(ln, {g.R['l0', s]})")
        if s in g.pre:
            g.emit(f"{ind}e{s} = {g.R['e0', s]} + e{s}")


def knot_search(
    g: Layout, ind: str, s: int, lo: str, hi: str, shift: str, ep: str, out: tuple[str, str, str]
) -> None:
    """Candidate |force| of the flagged knots of spring s's curve on the path (lo, hi) (abscissa of
    the curve), with the abscissa and force of the knot that gave it: ``out`` (kc, kx, ky), as
    kernel.compiled's knot loop (``knot_peak``, the first knot starting from 0)."""
    kc, kx, ky = out
    for idx, k in enumerate(g.knots[s]):
        yk = f"crush_knot_force({g.co('kyv', k)})" if g.mat[s] == codes.CRUSH else g.co("kyv", k)
        c0, xs0, ys0 = ("0.0", f"({ep} - {shift})", "0.0") if idx == 0 else (kc, kx, ky)
        g.emit(f"{ind}{kc}, {kx}, {ky} = knot_step({c0}, {xs0}, {ys0}, {lo}, {hi}, {g.co('cx', k)}, {yk})")


def knot_post(g: Layout, ind: str, s: int, kc: str, kx: str, ky: str, sh: str) -> None:
    """The crossing of spring s's winning knot: peak-force candidate, crossing fraction ``th{s}`` and
    (knot force - force interpolated in time) x axis ``dfax{s}_{d}`` (see kernel.compiled)."""
    fp = g.R["fp", s]
    g.emit(f"{ind}th, dF = knot_crossing({kc}, {kx}, {ky}, {g.R['ep', s]}, e{s}, {sh}, {fp}, F{s})")
    if s in g.fragile:  # a spring that breaks in this step: the step's ends only
        g.emit(f"{ind}kcb = 0.0 if {g.R['br', s]} > 0.0 else {kc}")
        kc = "kcb"
    g.emit(f"{ind}hit{s} = ({kc} > 0.0) & (wt > 0.0)")
    g.emit(f"{ind}{g.R['kth', s]} = th")
    g.emit(f"{ind}{g.R['kh', s]} = 1.0 if hit{s} else 0.0")
    g.emit(f"{ind}nhit += 1 if hit{s} else 0")
    for d in range(g.D):
        axis = f"ax{s}_{d}" if g.D > 1 else sg_text(g, s)
        g.emit(f"{ind}{g.R['kdf', s, d]} = dF * {axis}")
    g.emit(f"{ind}{g.R['pf', s]} = peak({g.R['pf', s]}, {kc} * afw)")


def time_curve(g: Layout, ind: str, name: str, c: int, t: str) -> None:
    """``name`` = time curve c at time ``t`` (0 outside its first..last knot, with a margin: laws.time_window),
    branch-free."""
    cx0, cxl = g.co("cx", g.off[c]), g.co("cx", g.off[c + 1] - 1)
    g.emit(f"{ind}tt = {t}")
    g.emit(f"{ind}{name} = {g.ramp(c, 'tt')} if time_window(tt, {cx0}, {cxl}) else 0.0")


def vp(g: Layout, n: int, d: int) -> str:
    # a dof driven by a displacement curve: v^{n-1/2}, the slope of its segment (see the reference)
    disp = any((p, dd, kind) == (n, d, codes.PM_DISPLACEMENT) for p, dd, kind, _ in g.pm)
    return "0.0" if g.static[n] else f"end_rate({g.R['v', n, d]}, {'0.0' if disp else g.R['a', n, d]}, dtw)"


def edot(g: Layout, s: int) -> str:
    """Elongation rate of spring s from v^{n-1/2} + dt/2 a^{n-1} (dampers; termination's opening test)."""
    if g.D == 1:
        return f"({sg_text(g, s)} * ({vp(g, g.sj[s], 0)} - {vp(g, g.si[s], 0)}))"
    return _lsum([f"ax{s}_{d} * ({vp(g, g.sj[s], d)} - {vp(g, g.si[s], d)})" for d in range(g.D)])


def pass_a(g: Layout, ind: str) -> None:
    g.emit(f"{ind}nrev = 0")
    g.emit(f"{ind}for w in range(B):")
    i2 = ind + "    "
    g.emit(f"{i2}dtw = {g.R['dt']}")
    geometry(g, i2, g.general, True)
    if g.term:
        for s in g.general:
            g.emit(f"{i2}{g.R['ed', s]} = {edot(g, s)}")
    for s in g.general:
        st = [g.R["st", s, k] for k in range(8)]
        g.emit(f"{i2}e = e{s}")
        if g.D > 1:
            for d in range(g.D):
                g.emit(f"{i2}{g.R['ax', s, d]} = ax{s}_{d}")
            g.emit(f"{i2}{g.R['rev', s]} = 2.0 if gone{s} else 0.0  # collapsed: kept for pass B")
        g.emit(f"{i2}mode = {st[0]}")
        g.emit(f"{i2}et = {st[1]}")
        g.emit(f"{i2}ft = {st[2]}")
        g.emit(f"{i2}ec = {st[3]}")
        g.emit(f"{i2}fc = {st[4]}")
        g.emit(f"{i2}ytw = {g.R['yt', s]}")
        g.emit(f"{i2}ycw = {g.R['yc', s]}")
        if s in g.knotted:  # on the loading curve, in its own (shifted) abscissa; state before the step
            ep = g.R["ep", s]
            g.emit(f"{i2}lo_, hi_, sh = general_window({ep}, e, mode, et, ec, {st[5]})")
            knot_search(g, i2, s, "lo_", "hi_", "sh", ep, (g.R["gkc", s], g.R["gkx", s], g.R["gky", s]))
            g.emit(f"{i2}{g.R['gksh', s]} = sh")
        g.emit(f"{i2}L = {g.ramp(g.ca[s], f'(e - {st[5]})')}")
        g.emit(f"{i2}Ut = {g.ramp(g.cb[s], '(e - et)')}")
        g.emit(f"{i2}Uc = {g.ramp(g.cb[s], '(e - ec)')}")
        g.emit(
            f"{i2}{g.R['F', s]}, {st[0]}, {st[1]}, {st[2]}, {st[3]}, {st[4]}, {st[6]}, {st[7]}, rev = general_law("
            f"e, mode, et, ft, ec, fc, {st[6]}, {st[7]}, L, Ut, Uc, ytw, ycw)"
        )
        g.emit(f"{i2}{g.R['E', s]} = e")
        g.emit(
            f"{i2}{g.R['rev', s]} = {g.R['rev', s]} + 1.0 if rev else {g.R['rev', s]}"
            if g.D > 1
            else f"{i2}{g.R['rev', s]} = 1.0 if rev else 0.0"
        )
        g.emit(f"{i2}nrev += 1 if rev else 0")
    g.emit(f"{ind}if nrev > 0:")
    for s in g.general:
        g.emit(f"{ind}    for w in range(B):")
        g.emit(f"{ind}        if {g.R['rev', s]} == 1.0 or {g.R['rev', s]} == 3.0:")
        rows = ", ".join(g.R["st", s, k] for k in range(8))
        # the curve numbers as int64, not literals: numba compiles a law called with a literal int once per
        # value, so every new curve number in a model cost a compile of the reversal laws (~4 CPU s)
        g.emit(
            f"{ind}            {g.R['F', s]}, {rows} = general_reverse_call({g.R['E', s]}, "
            + ", ".join(g.R["st", s, k] for k in (0, 1, 2, 3, 4, 6, 7))
            + f", {g.R['yt', s]}, {g.R['yc', s]}, np.int64({g.ca[s]}), np.int64({g.cb[s]}), vi[w], cx, cy, cds, cs0, cs1, off)"
        )


def failure(g: Layout, ind: str, s: int) -> None:
    """A breakable spring (docs/format.md, failure): past a failure elongation it breaks at the crossing
    time interpolated in the step (``spring_fail_time``) and its force is 0 from then on; ``em{s}``, ``ai{s}``
    are the elongation and activity its extremes take (the failure elongation; 0 once broken)."""
    if s not in g.fragile:
        return
    R, emit = g.R, g.emit
    br = R["br", s]
    emit(f"{ind}was = {br} > 0.0")
    emit(f"{ind}snaps, lim_, tb = broken_at(e{s}, {R['ep', s]}, {R['ft', s]}, {R['fc', s]}, n, dtw)")
    emit(f"{ind}snaps = snaps and af > 0.0 and (not was) and n > 0")
    emit(f"{ind}ai{s} = 0.0 if was else af")
    emit(f"{ind}em{s} = lim_ if snaps else e{s}")
    emit(f"{ind}if snaps:")
    emit(f"{ind}    spring_fail_time[{s}, vi[w]] = tb")
    emit(f"{ind}    {br} = 1.0")
    emit(f"{ind}F{s} = 0.0 if {br} > 0.0 else F{s}")


def pass_k(g: Layout, ind: str) -> None:
    """|a| at this step's knot crossings (only run when a lane crossed one): a interpolated in time
    plus the kinked spring's correction, as kernel.compiled (rows kth, kdf, kh, ao, a)."""
    g.emit(f"{ind}if nhit > 0:")
    g.emit(f"{ind}    for w in range(B):")
    i2 = ind + "        "
    g.emit(f"{i2}af = 1.0 if fn <= {g.R['lim']} else 0.0")
    for s in g.knotted:
        g.emit(f"{i2}th = {g.R['kth', s]}")
        for side, p in enumerate((g.si[s], g.sj[s])):
            if g.static[p] or not g.movable[p]:
                continue
            g.emit(f"{i2}a2 = 0.0")
            for d in range(g.D):
                g.emit(
                    f"{i2}ai = knot_accel({g.R['ao', p, d]}, {g.R['a', p, d]}, th, {g.R['kdf', s, d]}, "
                    f"{g.R['im', p, d]}, {side})"
                )
                g.emit(f"{i2}a2 = a2 + ai * ai")
            g.emit(f"{i2}{g.R['pa', p]} = peak({g.R['pa', p]}, (a2 if {g.R['kh', s]} > 0.0 else 0.0) * af)")


def pass_b_springs(g: Layout, i2: str) -> None:
    """Pass B's springs (every material but ``general_nonlinear``, whose force pass A left in rows) and
    the summaries of every spring; the reference walks the springs in order, and 2-D's "first
    collapsed spring" needs that order. The material dispatch is one line per law."""
    for s in range(g.S):
        if g.mat[s] == codes.GENERAL:
            g.emit(f"{i2}F{s} = {g.R['F', s]}")
            g.emit(f"{i2}e{s} = {g.R['E', s]}")
            if g.D > 1:
                for d in range(g.D):
                    g.emit(f"{i2}ax{s}_{d} = {g.R['ax', s, d]}")
                intact = f" and {g.R['br', s]} == 0.0" if s in g.fragile else ""
                g.emit(
                    f"{i2}{g.R['crushed']} = {float(s)!r} if ({g.R['rev', s]} >= 2.0 and {g.R['crushed']} < 0.0{intact})"
                    f" else {g.R['crushed']}"
                )
            failure(g, i2, s)
            if s in g.knotted:
                knot_post(g, i2, s, g.R["gkc", s], g.R["gkx", s], g.R["gky", s], g.R["gksh", s])
            continue
        geometry(g, i2, [s], False)
        k = g.mat[s]
        if k == codes.LINEAR:
            g.emit(f"{i2}F{s} = linear_force({g.R['kp', s]}, e{s})")
        elif k == codes.DAMPER:
            g.emit(f"{i2}F{s} = damper_force({g.R['kp', s]}, {edot(g, s)})")
        elif k == codes.NONLINEAR:
            g.emit(f"{i2}F{s} = nonlinear_force({g.ramp(g.ca[s], f'e{s}')})")
            if s in g.knotted:  # the whole path
                g.emit(f"{i2}lo_, hi_, sh = nonlinear_window({g.R['ep', s]}, e{s})")
                knot_search(g, i2, s, "lo_", "hi_", "sh", g.R["ep", s], ("kc", "kx", "ky"))
        elif k == codes.CRUSH:
            emin, fstar = g.R["st", s, 0], g.R["st", s, 1]
            g.emit(f"{i2}emin = {emin}")
            g.emit(
                f"{i2}F{s}, {emin}, {fstar} = crush_law(e{s}, emin, {fstar}, {g.ramp(g.ca[s], f'e{s}')}, {g.R['kp', s]})"
            )
            if s in g.knotted:  # (e, e_min before the step): crushing further
                g.emit(f"{i2}lo_, hi_, sh = crush_window(e{s}, emin)")
                knot_search(g, i2, s, "lo_", "hi_", "sh", g.R["ep", s], ("kc", "kx", "ky"))
        elif k == codes.ELASTOPLASTIC:
            st0, st1 = g.R["st", s, 0], g.R["st", s, 1]
            g.emit(
                f"{i2}F{s}, {st0}, {st1} = elastoplastic_law(e{s}, {st0}, {st1}, {g.R['kp', s]}, {g.R['kt', s]}, "
                f"{g.R['fy', s]})"
            )
        elif k == codes.NONLINEAR_DAMPER:
            g.emit(f"{i2}rd = {edot(g, s)}")
            g.emit(f"{i2}F{s} = {g.ramp(g.ca[s], 'rd')}")
        elif k == codes.RATE_ELASTIC:  # the first curve, then each neighbouring pair folded in by the rate
            rc = g.rc[s]
            g.emit(f"{i2}rd = abs({edot(g, s)})")
            g.emit(f"{i2}F{s} = {g.ramp(rc[0], f'e{s}')}")
            for q in range(len(rc) - 1):
                g.emit(
                    f"{i2}F{s} = rate_segment(F{s}, rd, {g.R['rt', s, q]}, {g.R['rt', s, q + 1]}, "
                    f"{g.ramp(rc[q], f'e{s}')}, {g.ramp(rc[q + 1], f'e{s}')})"
                )
        else:  # pragma: no cover - the compiler knows no other material
            raise ValueError(f"material code {k}")
        failure(g, i2, s)
        if s in g.knotted:  # after a failure check: a spring that breaks in this step takes no knot
            knot_post(g, i2, s, "kc", "kx", "ky", "sh")
    # summaries in spring order (the reference kernel's order of operations)
    g.emit(f"{i2}ie_tot = 0.0")
    for s in range(g.S):
        ie = g.R["ie", s]
        step = f"energy_increment({ie}, F{s}, {g.R['fp', s]}, e{s}, {g.R['ep', s]}, afw)"
        if s in g.pre and g.mat[s] not in DAMPER_MATERIALS:  # a preload's first half step
            half = f"energy_first_half({ie}, F{s}, {g.R['fp', s]}, e{s}, {g.R['ep', s]}, {g.R['dt']}, {g.R['r0', s]}, afw)"
            step = f"{half} if (n1 and {g.R['e0', s]} != 0.0) else {step}"
        g.emit(f"{i2}{ie} = {step}")
        g.emit(f"{i2}ie_tot = ie_tot + {ie}")
        em, ai = (f"em{s}", f"ai{s}") if s in g.fragile else (f"e{s}", "af")  # extremes while intact
        ext = f"{g.R['pf', s]}, {g.R['mc', s]}, {g.R['me', s]}"
        g.emit(f"{i2}{ext} = spring_extremes({ext}, F{s}, af, {em}, {ai})")
        g.emit(f"{i2}{g.R['fp', s]} = F{s}")
        g.emit(f"{i2}{g.R['ep', s]} = e{s}")
        if g.hist and g.D > 1:
            for d in range(g.D):
                g.emit(f"{i2}{g.R['axh', s, d]} = ax{s}_{d}")
