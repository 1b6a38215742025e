"""Emitters of a generated kernel's pass B: the other springs, summaries, node updates, walls,
energy balance and termination; and the results of a lane.
"""

from __future__ import annotations

from typing import Any

from crashstudy.kernel.gen_shape import _lsum
from crashstudy.kernel.gen_springs import edot, pass_b_springs, time_curve
from crashstudy.vocabulary.codes import (
    GENERAL,
    PM_ACCELERATION,
    PM_DISPLACEMENT,
)


def pass_b(g: Any, ind: str) -> None:
    D, R, S, W, emit, ext, hist, live, loads, mat, static, term, walls = g.D, g.R, g.S, g.W, g.emit, g.ext, g.hist, g.live, g.loads, g.mat, g.static, g.term, g.walls  # fmt: skip
    emit(f"{ind}nbad = 0")
    emit(f"{ind}nhit = 0")
    emit(f"{ind}nstop = 0")
    emit(f"{ind}for w in range(B):")
    i2 = ind + "    "
    emit(f"{i2}af = 1.0 if fn <= {R['lim']} else 0.0")
    emit(f"{i2}afw = af * wt  # no absorbed work in step 0 (adds an exact 0)")
    emit(f"{i2}dtw = {R['dt']}")
    for k, (_, c) in enumerate(loads):  # load scales: time curves at t = n dt (0 outside the curve)
        if c < 0:
            emit(f"{i2}sc{k} = 1.0")
            continue
        time_curve(g, i2, f"sc{k}", c, "fn * dtw")
    if D > 1:
        emit(f"{i2}{R['crushed']} = -1.0")
    pass_b_springs(g, i2)
    # nodal forces in the reference scatter's order, then the central-difference update
    emit(f"{i2}ke = 0.0")
    if ext:
        emit(f"{i2}bal = 0.0")
    for wl in range(W):
        emit(f"{i2}wf{wl} = 0.0")
    for n in live:
        node(g, i2, n)
    if W:  # wall work in the reference's order (wall by wall, node by node), running variants only
        emit(f"{i2}wall_e = {R['wall_e']}")
        for wl in range(W):  # the penalty walls' stored energy first (as the reference)
            for n in walls[wl]:
                if not static[n]:
                    emit(f"{i2}wall_e = wall_e + pe{wl}_{n} if af > 0.0 else wall_e")
        for wl in range(W):
            for n in walls[wl]:
                if not static[n]:
                    emit(f"{i2}wall_e = wall_e + we{wl}_{n} if af > 0.0 else wall_e")
            emit(f"{i2}{R[f'pw{wl}']} = peak({R[f'pw{wl}']}, wf{wl} * af)")
            if "wall_force" in hist:
                emit(f"{i2}{R[f'wf{wl}']} = wf{wl}")
        emit(f"{i2}{R['wall_e']} = wall_e")
    emit(f"{i2}ke = ke if wt > 0.0 else {R['ke0']}")
    if ext:
        emit(f"{i2}work = work_increment({R['work']}, bal, dtw, afw)")
        emit(f"{i2}{R['work']} = work")
        emit(f"{i2}wmax = peak({R['wmax']}, abs(work))")
        emit(f"{i2}{R['wmax']} = wmax")
        emit(f"{i2}bal = abs((((ke + ie_tot) + {'(wall_e if n > 0 else 0.0)' if W else '0.0'}) - {R[g.E0]}) - work)")
        emit(f"{i2}thr = unstable_energy * ({R[g.ES]} + wmax) + {R['efl']}")
    else:
        emit(f"{i2}bal = abs((((ke + ie_tot) + {'(wall_e if n > 0 else 0.0)' if W else '0.0'}) - {R[g.E0]}) - 0.0)")
        emit(f"{i2}thr = {R['thr']}")
    emit(f"{i2}{R['err']} = peak({R['err']}, bal * af)")
    emit(f"{i2}{R['thr']} = thr")
    bad = "not (bal <= thr)"
    if D > 1:
        bad = f"({bad} or {R['crushed']} >= 0.0)"
    emit(f"{i2}nbad += (1 if af > 0.0 else 0) if {bad} else 0")
    emit(f"{i2}{R['ken']} = ke")
    emit(f"{i2}{R['ien']} = ie_tot")
    if term:  # early termination (docs/format.md): decided for running lanes after the failure check
        emit(f"{i2}edmin = np.inf")
        for s in range(S):
            emit(f"{i2}edmin = least(edmin, {R[f'ed{s}'] if mat[s] == GENERAL else edot(g, s)})")
        emit(f"{i2}fsum = {_lsum([f'abs(F{s})' for s in range(S)])}")
        emit(f"{i2}psum = {_lsum([R[f'pf{s}'] for s in range(S)])}")
        emit(f"{i2}kef = {R['kef']}")
        emit(f"{i2}small_f = fsum <= kef * psum")
        emit(f"{i2}small_ke = ke <= kef * ({R[g.ES]} + {R['wmax'] if ext else '0.0'})")
        emit(f"{i2}opening = " + ("False" if ext else "edmin >= 0.0"))
        emit(f"{i2}stop = (wt > 0.0) & (kef > 0.0) & (not (fn * dtw < {R['tmin']})) & small_f & (small_ke | opening)")
        emit(f"{i2}{R['stop']} = 1.0 if stop else 0.0")
        emit(f"{i2}nstop += 1 if stop else 0")



def _chain(g: Any, n: int, d: int, force: Any, axis: Any) -> str:
    """Nodal force on dof (n, d) in the reference scatter's order: f[i] += F ax, f[j] -= F ax."""
    D, R, S, si, sign, sj, term = g.D, g.R, g.S, g.si, g.sign, g.sj, g.term  # fmt: skip
    out = "0.0"
    for s in range(S):
        for side, op in ((si[s], "+"), (sj[s], "-")):
            if side != n:
                continue
            term = force(s)
            if D > 1:
                out = f"({out} {op} {term} * {axis(s, d)})"
            elif sign[s] == 0:
                out = f"({out} {op} {term} * {R[f'sg{s}']})"
            else:  # a - b == a + (-b): the sign folds into the operator exactly
                out = f"({out} {op if sign[s] == 1 else ('-' if op == '+' else '+')} {term})"
    return out



def emit_results(g: Any, ind: str) -> None:
    """Write lane w's summaries to its variant's columns (the lane's variant has ended)."""
    N, R, S, W, emit, ext, movable, static = g.N, g.R, g.S, g.W, g.emit, g.ext, g.movable, g.static  # fmt: skip
    emit(f"{ind}q = vi[w]")
    wm = R["wmax"] if ext else "0.0"
    emit(f"{ind}energy_error[q] = {R['err']} / max({R[g.ES]} + {wm}, 1e-300)")
    emit(f"{ind}if status[q] == OK:")
    emit(f"{ind}    t_end[q] = int({R['lim']}) * {R['dt']}")
    emit(f"{ind}elif n_fail[w] > 0:")
    emit(f"{ind}    t_end[q] = (n_fail[w] - 1) * {R['dt']}")
    for s in range(S):
        emit(f"{ind}absorbed[{s}, q] = {R[f'ie{s}']}")
        emit(f"{ind}peak_force[{s}, q] = {R[f'pf{s}']}")
        emit(f"{ind}max_crush[{s}, q] = {R[f'mc{s}']}")
        emit(f"{ind}max_elongation[{s}, q] = {R[f'me{s}']}")
    for n in range(N):
        emit(f"{ind}peak_acc[{n}, q] = " + ("0.0" if static[n] or not movable[n] else f"np.sqrt({R[f'pa{n}']})"))
    for wl in range(W):
        emit(f"{ind}peak_wall[{wl}, q] = {R[f'pw{wl}']}")
        emit(f"{ind}w_impulse[{wl}, q] = {R[f'wi{wl}']}")



def node(g: Any, i2: str, n: int) -> None:
    """Node n's forces (the reference scatter's order), a^n, v^{n+1/2}, prescribed motion, external
    work, walls, kinetic energy, x^{n+1} and peak |a|."""
    D, R, W, emit, grav, keep_a, loaded, loads, movable, pm, walls = g.D, g.R, g.W, g.emit, g.grav, g.keep_a, g.loaded, g.loads, g.movable, g.pm, g.walls  # fmt: skip
    held = [wl for wl in range(W) if n in walls[wl]]
    for wl in held:  # penalty walls: force k pen of x^n, stored energy (0 for a rigid wall)
        gap = _lsum([f"({R[f'x{n}_{d}']} - {R[f'wp{wl}_{d}']}) * {R[f'wn{wl}_{d}']}" for d in range(D)])
        emit(f"{i2}fp{wl}, ep = wall_penalty({R[f'wk{wl}']}, {gap})")
        emit(f"{i2}wf{wl} = wf{wl} + fp{wl}")
        emit(f"{i2}pe{wl}_{n} = ep - {R[f'pen{wl}_{n}']}")
        emit(f"{i2}{R[f'pen{wl}_{n}']} = ep")
    for d in range(D):
        chain = _chain(g, n, d, lambda s: f"F{s}", lambda s, d: f"ax{s}_{d}")
        for wl in held:
            chain = f"({chain} + fp{wl} * {R[f'wn{wl}_{d}']})"
        fext = f"{R[f'm{n}']} * {R[f'g{d}']}" if grav else "0.0"
        if n in loaded:  # gravity, then the loads on this node in load order
            for k, (p, _) in enumerate(loads):
                if p == n:
                    fext = f"({fext} + {R[f'lf{k}_{d}']} * sc{k})"
            emit(f"{i2}fx_{d} = {fext}")
            fext = f"fx_{d}"
        emit(f"{i2}fs = {chain}")
        emit(f"{i2}a = (fs + {fext}) * {R[f'im{n}_{d}']}")
        emit(f"{i2}vo_{d} = {R[f'v{n}_{d}']}")
        emit(f"{i2}vn_{d} = vo_{d} + (h * dtw) * a")
        for k, (p, dd, kind, c) in enumerate(pm):  # prescribed motion of this dof, in order
            if (p, dd) != (n, d):
                continue
            sc = R[f"pms{k}"]
            if kind == PM_DISPLACEMENT:
                time_curve(g, i2, "tc", c, "fn * dtw + dtw")
                emit(f"{i2}vn_{d} = (({R[f'x0{n}_{d}']} + {sc} * tc) - {R[f'x{n}_{d}']}) / dtw")
            elif kind == PM_ACCELERATION:
                time_curve(g, i2, "tc", c, "fn * dtw")
                emit(f"{i2}vn_{d} = vo_{d} + (h * dtw) * {sc} * tc")
            else:
                time_curve(g, i2, "tc", c, "fn * dtw + 0.5 * dtw")
                emit(f"{i2}vn_{d} = {sc} * tc")
            pa = R[f"pma{k}"]
            emit(f"{i2}last = fn == {R['nst']}  # the last step continues with the previous acceleration")
            emit(f"{i2}{pa} = {pa} if last else (vn_{d} - vo_{d}) / (h * dtw)")
            emit(f"{i2}vn_{d} = vo_{d} + (h * dtw) * {pa} if last else vn_{d}")
            emit(f"{i2}a = {pa}")
            emit(f"{i2}fx_{d} = fx_{d} + ({R[f'm{n}']} * a - (fs + fx_{d}))")
        emit(f"{i2}a_{d} = a")
        if n in g.record:  # kept for the per-step record (crash criteria), written after the failure check
            emit(f"{i2}{R[f'am{n}_{d}']} = a")
        if n in loaded:  # external work: trapezoid with the previous step's force (R fx)
            emit(f"{i2}vb = 0.5 * ({R[f'v0{n}_{d}']} + vo_{d}) if n1 else vo_{d}")
            emit(f"{i2}bal = ext_power(bal, fx_{d}, vo_{d}, {R[f'fx{n}_{d}']}, vb)")
            emit(f"{i2}{R[f'fx{n}_{d}']} = fx_{d}")
        elif grav:  # external work of gravity: trapezoid, f_ext^0 over the first half step
            emit(f"{i2}vb = 0.5 * ({R[f'v0{n}_{d}']} + vo_{d}) if n1 else vo_{d}")
            emit(f"{i2}bal = ext_power(bal, ({fext}), vo_{d}, ({fext}) * wt, vb)")
        if n in keep_a:  # a^{n-1}: dampers' velocity estimate, knot crossings (R ao)
            emit(f"{i2}{R[f'ao{n}_{d}']} = {R[f'a{n}_{d}']}")
            emit(f"{i2}{R[f'a{n}_{d}']} = a")
    for wl in held:  # rigid walls, in wall order
        wall(g, i2, n, wl)
    for d in range(D if held else 0):  # a^n with the walls' contact forces (held: 0)
        if n in keep_a:
            emit(f"{i2}{R[f'a{n}_{d}']} = a_{d}")
        if n in g.record:
            emit(f"{i2}{R[f'am{n}_{d}']} = a_{d}")
        if "acceleration" in g.hist:
            emit(f"{i2}{R[f'wa{n}_{d}']} = a_{d}")
    for d in range(D):
        x, v = R[f"x{n}_{d}"], R[f"v{n}_{d}"]
        emit(f"{i2}ke = ke + 0.5 * {R[f'm{n}']} * vo_{d} * vn_{d}")
        emit(f"{i2}{x} = {x} + (dtw * af) * vn_{d}")
        emit(f"{i2}{v} = vn_{d} * af + vo_{d} * (1.0 - af)")
    if movable[n]:
        a2 = _lsum([f"a_{d} * a_{d}" for d in range(D)])
        emit(f"{i2}{R[f'pa{n}']} = peak({R[f'pa{n}']}, {a2} * af)")


def wall(g: Any, i2: str, n: int, wl: int) -> None:
    """Rigid wall wl on node n: land on the plane, no velocity into it."""
    D, R, emit, free = g.D, g.R, g.emit, g.free  # fmt: skip
    nr = [R[f"wn{wl}_{d}"] for d in range(D)]
    pt = [R[f"wp{wl}_{d}"] for d in range(D)]
    xw = [R[f"x{n}_{d}"] for d in range(D)]
    emit(f"{i2}wv = {_lsum([f'vn_{d} * {nr[d]}' for d in range(D)])}")
    emit(f"{i2}gap = {_lsum([f'({xw[d]} - {pt[d]}) * {nr[d]}' for d in range(D)])}")
    emit(f"{i2}dist = {_lsum([f'(({xw[d]} + dtw * vn_{d}) - {pt[d]}) * {nr[d]}' for d in range(D)])}")
    emit(f"{i2}dvn = wall_jump(wv, gap, dist, dtw, {R[f'wk{wl}']})")
    emit(f"{i2}c = wall_hold(dvn, {_lsum([f'a_{d} * {nr[d]}' for d in range(D)])}, h * dtw)")
    emit(f"{i2}we = 0.0")
    for d in range(D):
        jp = R[f"jp{wl}_{n}_{d}"]
        emit(f"{i2}jmp = dvn * {nr[d]} * {float(free[n][d])!r}")
        emit(f"{i2}vn_{d} = vn_{d} + jmp")
        emit(f"{i2}a_{d} = a_{d} + c * {nr[d]} * {float(free[n][d])!r}")
        emit(f"{i2}we = we + vo_{d} * (jmp + {jp})")
        emit(f"{i2}{jp} = jmp")
    emit(f"{i2}we{wl}_{n} = -0.5 * {R[f'm{n}']} * we")
    emit(f"{i2}wf{wl} = wf{wl} + wall_force({R[f'm{n}']}, c)")
    emit(f"{i2}{R[f'wi{wl}']} = {R[f'wi{wl}']} + wall_impulse({R[f'm{n}']}, dvn, c, h * dtw) * af")
