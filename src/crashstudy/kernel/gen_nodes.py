"""Emitters of a generated kernel's pass B: the other springs, summaries, node updates, walls,
energy balance and termination; and the results of a lane.
"""

from __future__ import annotations

from typing import Any

from crashstudy.kernel.gen_loops import stores
from crashstudy.kernel.gen_rows import One
from crashstudy.kernel.gen_shape import Layout, _lsum
from crashstudy.kernel.gen_springs import edot, pass_b_springs, time_curve
from crashstudy.vocabulary.codes import GENERAL, PM_CODES

PM_NAMES = {
    code: f"PM_{name.upper()}" for name, code in PM_CODES.items()
}  # as the generated module imports them


def pass_b(g: Layout, ind: str) -> None:
    g.emit(f"{ind}nbad = 0")
    g.emit(f"{ind}nhit = 0")
    g.emit(f"{ind}nstop = 0")
    g.emit(f"{ind}for w in range(B):")
    i2 = ind + "    "
    g.emit(f"{i2}af = 1.0 if fn <= {g.R['lim']} else 0.0")
    g.emit(f"{i2}afw = af * wt  # no absorbed work in step 0 (adds an exact 0)")
    g.emit(f"{i2}dtw = {g.R['dt']}")
    for k, (_, c) in enumerate(g.loads):  # load scales: time curves at t = n dt (0 outside the curve)
        if c < 0:
            g.emit(f"{i2}sc{k} = 1.0")
            continue
        time_curve(g, i2, f"sc{k}", c, "fn * dtw")
    if g.D > 1:
        g.emit(f"{i2}{g.R['crushed']} = -1.0")
    pass_b_springs(g, i2)
    # nodal forces in the reference scatter's order, then the central-difference update
    g.emit(f"{i2}ke = 0.0")
    if g.ext:
        g.emit(f"{i2}bal = 0.0")
    for wl in range(g.W):
        g.emit(f"{i2}wf{wl} = 0.0")
    for n in g.live:
        node(g, i2, n)
    if g.W:  # wall work in the reference's order (wall by wall, node by node), running variants only
        g.emit(f"{i2}wall_e = {g.R['wall_e']}")
        for wl in range(g.W):  # the penalty walls' stored energy first (as the reference)
            for n in g.walls[wl]:
                if not g.static[n]:
                    g.emit(f"{i2}wall_e = wall_e + pe{wl}_{n} if af > 0.0 else wall_e")
        for wl in range(g.W):
            for n in g.walls[wl]:
                if not g.static[n]:
                    g.emit(f"{i2}wall_e = wall_e + we{wl}_{n} if af > 0.0 else wall_e")
            g.emit(f"{i2}{g.R['pw', wl]} = peak({g.R['pw', wl]}, wf{wl} * af)")
            if "wall_force" in g.hist:
                g.emit(f"{i2}{g.R['wf', wl]} = wf{wl}")
        g.emit(f"{i2}{g.R['wall_e']} = wall_e")
    g.emit(f"{i2}ke = ke if wt > 0.0 else {g.R['ke0']}")
    wall = "(wall_e if n > 0 else 0.0)" if g.W else "0.0"  # t = 0: before any impact
    if g.ext:
        g.emit(f"{i2}work = work_increment({g.R['work']}, bal, dtw, afw)")
        g.emit(f"{i2}{g.R['work']} = work")
        g.emit(f"{i2}wmax = peak({g.R['wmax']}, abs(work))")
        g.emit(f"{i2}{g.R['wmax']} = wmax")
        g.emit(f"{i2}bal = energy_balance(ke, ie_tot, {wall}, {g.R[g.E0]}, work)")
        g.emit(f"{i2}thr = unstable_limit({g.R[g.ES]}, wmax, {g.R['efl']})")
    else:
        g.emit(f"{i2}bal = energy_balance(ke, ie_tot, {wall}, {g.R[g.E0]}, 0.0)")
        g.emit(f"{i2}thr = {g.R['thr']}")
    g.emit(f"{i2}{g.R['err']} = peak({g.R['err']}, bal * af)")
    g.emit(f"{i2}{g.R['thr']} = thr")
    bad = f"(unstable(bal, thr) or wall_gives({wall}, thr))" if g.W else "unstable(bal, thr)"
    if g.D > 1:
        bad = f"({bad} or {g.R['crushed']} >= 0.0)"
    g.emit(f"{i2}nbad += (1 if af > 0.0 else 0) if {bad} else 0")
    g.emit(f"{i2}{g.R['ken']} = ke")
    g.emit(f"{i2}{g.R['ien']} = ie_tot")
    if g.term:  # early termination (docs/format.md): decided for running lanes after the failure check
        g.emit(f"{i2}edmin = np.inf")
        for s in range(g.S):
            g.emit(f"{i2}edmin = least(edmin, {g.R['ed', s] if g.mat[s] == GENERAL else edot(g, s)})")
        g.emit(f"{i2}fsum = {_lsum([f'abs(F{s})' for s in range(g.S)])}")
        g.emit(f"{i2}psum = {_lsum([g.R['pf', s] for s in range(g.S)])}")
        g.emit(f"{i2}kef = {g.R['kef']}")
        g.emit(f"{i2}opening = " + ("False" if g.ext else "edmin >= 0.0"))
        test = f"stop_test(kef, fsum, psum, ke, {g.R[g.ES]}, {g.R['wmax'] if g.ext else '0.0'}, opening)"
        g.emit(f"{i2}stop = (wt > 0.0) & (kef > 0.0) & (not (fn * dtw < {g.R['tmin']})) & {test}")
        g.emit(f"{i2}{g.R['stop']} = 1.0 if stop else 0.0")
        g.emit(f"{i2}nstop += 1 if stop else 0")


def _chain(g: Layout, n: int, d: int, force: Any, axis: Any) -> str:
    """Nodal force on dof (n, d) in the reference scatter's order: f[i] += F ax, f[j] -= F ax."""
    out = "0.0"
    for s in range(g.S):
        for side, op in ((g.si[s], "+"), (g.sj[s], "-")):
            if side != n:
                continue
            term = force(s)
            if g.D > 1:
                out = f"({out} {op} {term} * {axis(s, d)})"
            elif g.sign[s] == 0:
                out = f"({out} {op} {term} * {g.R['sg', s]})"
            else:  # a - b == a + (-b): the sign folds into the operator exactly
                out = f"({out} {op if g.sign[s] == 1 else ('-' if op == '+' else '+')} {term})"
    return out


def emit_results(g: Layout, ind: str) -> None:
    """Write lane w's summaries to its variant's columns (the lane's variant has ended)."""
    g.emit(f"{ind}q = vi[w]")
    wm = g.R["wmax"] if g.ext else "0.0"
    g.emit(f"{ind}energy_error[q] = {g.R['err']} / max({g.R[g.ES]} + {wm}, 1e-300)")
    g.emit(f"{ind}if status[q] == OK:")
    g.emit(f"{ind}    t_end[q] = int({g.R['lim']}) * {g.R['dt']}")
    g.emit(f"{ind}elif n_fail[w] > 0:")
    g.emit(f"{ind}    t_end[q] = (n_fail[w] - 1) * {g.R['dt']}")
    summaries: tuple[tuple[str, One], ...] = (
        ("absorbed", "ie"),
        ("peak_force", "pf"),
        ("max_crush", "mc"),
        ("max_elongation", "me"),
    )
    for arr, row in summaries:
        stores(g, ind, arr, [(s, (row, s)) for s in range(g.S)])
    still = [n for n in range(g.N) if g.static[n] or not g.movable[n]]
    for n in still:
        g.emit(f"{ind}peak_acc[{n}, q] = 0.0")
    stores(g, ind, "peak_acc", [(n, ("pa", n)) for n in range(g.N) if n not in still], "np.sqrt({})")
    stores(g, ind, "peak_wall", [(wl, ("pw", wl)) for wl in range(g.W)])
    stores(g, ind, "w_impulse", [(wl, ("wi", wl)) for wl in range(g.W)])


def node(g: Layout, i2: str, n: int) -> None:
    """Node n's forces (the reference scatter's order), a^n, v^{n+1/2}, prescribed motion, external
    work, walls, kinetic energy, x^{n+1} and peak |a|."""
    held = [wl for wl in range(g.W) if n in g.walls[wl]]
    for wl in held:  # penalty walls: force k pen of x^n, stored energy (0 for a rigid wall)
        gap = _lsum([f"({g.R['x', n, d]} - {g.R['wp', wl, d]}) * {g.R['wn', wl, d]}" for d in range(g.D)])
        g.emit(f"{i2}fp{wl}, ep = wall_penalty({g.R['wk', wl]}, {gap})")
        g.emit(f"{i2}wf{wl} = wf{wl} + fp{wl}")
        g.emit(f"{i2}pe{wl}_{n} = ep - {g.R['pen', wl, n]}")
        g.emit(f"{i2}{g.R['pen', wl, n]} = ep")
    for d in range(g.D):
        chain = _chain(g, n, d, lambda s: f"F{s}", lambda s, d: f"ax{s}_{d}")
        for wl in held:
            chain = f"({chain} + fp{wl} * {g.R['wn', wl, d]})"
        fext = f"{g.R['m', n]} * {g.R['g', d]}" if g.grav else "0.0"
        if n in g.loaded:  # gravity, then the loads on this node in load order
            for k, (p, _) in enumerate(g.loads):
                if p == n:
                    fext = f"({fext} + {g.R['lf', k, d]} * sc{k})"
            g.emit(f"{i2}fx_{d} = {fext}")
            fext = f"fx_{d}"
        g.emit(f"{i2}fs = {chain}")
        g.emit(f"{i2}a = (fs + {fext}) * {g.R['im', n, d]}")
        g.emit(f"{i2}vo_{d} = {g.R['v', n, d]}")
        g.emit(f"{i2}vn_{d} = half_step(vo_{d}, a, h * dtw)")
        for k, (p, dd, kind, c) in enumerate(g.pm):  # prescribed motion of this dof, in order
            if (p, dd) != (n, d):
                continue
            sc = g.R["pms", k]
            kn = PM_NAMES[kind]
            time_curve(g, i2, "tc", c, f"prescribed_time({kn}, fn * dtw, dtw)")
            x0, x = g.R["x0", n, d], g.R["x", n, d]
            g.emit(f"{i2}vn_{d} = prescribed_velocity({kn}, {x0}, {sc}, tc, {x}, vo_{d}, dtw, h * dtw)")
            pa = g.R["pma", k]
            g.emit(f"{i2}vn_{d}, a = prescribed_step(fn == {g.R['nst']}, vn_{d}, vo_{d}, {pa}, h * dtw)")
            g.emit(f"{i2}{pa} = a")
            g.emit(f"{i2}fx_{d} = fx_{d} + ({g.R['m', n]} * a - (fs + fx_{d}))")
        g.emit(f"{i2}a_{d} = a")
        if n in g.record:  # kept for the per-step record (crash criteria), written after the failure check
            g.emit(f"{i2}{g.R['am', n, d]} = a")
        if n in g.loaded:  # external work: trapezoid with the previous step's force (R fx)
            g.emit(f"{i2}vb = 0.5 * ({g.R['v0', n, d]} + vo_{d}) if n1 else vo_{d}")
            g.emit(f"{i2}bal = ext_power(bal, fx_{d}, vo_{d}, {g.R['fx', n, d]}, vb)")
            g.emit(f"{i2}{g.R['fx', n, d]} = fx_{d}")
        elif g.grav:  # external work of gravity: trapezoid, f_ext^0 over the first half step
            g.emit(f"{i2}vb = 0.5 * ({g.R['v0', n, d]} + vo_{d}) if n1 else vo_{d}")
            g.emit(f"{i2}bal = ext_power(bal, ({fext}), vo_{d}, ({fext}) * wt, vb)")
        if n in g.keep_a:  # a^{n-1}: dampers' velocity estimate, knot crossings (R ao)
            g.emit(f"{i2}{g.R['ao', n, d]} = {g.R['a', n, d]}")
            g.emit(f"{i2}{g.R['a', n, d]} = a")
    for wl in held:  # rigid walls, in wall order
        wall(g, i2, n, wl)
    for d in range(g.D if held else 0):  # a^n with the walls' contact forces (held: 0)
        if n in g.keep_a:
            g.emit(f"{i2}{g.R['a', n, d]} = a_{d}")
        if n in g.record:
            g.emit(f"{i2}{g.R['am', n, d]} = a_{d}")
        if "acceleration" in g.hist:
            g.emit(f"{i2}{g.R['wa', n, d]} = a_{d}")
    for d in range(g.D):
        x, v = g.R["x", n, d], g.R["v", n, d]
        g.emit(f"{i2}ke = kinetic(ke, {g.R['m', n]}, vo_{d}, vn_{d})")
        g.emit(f"{i2}{x}, {v} = advance({x}, vo_{d}, vn_{d}, dtw, af)")
    if g.movable[n]:
        a2 = _lsum([f"a_{d} * a_{d}" for d in range(g.D)])
        g.emit(f"{i2}{g.R['pa', n]} = peak({g.R['pa', n]}, {a2} * af)")


def wall(g: Layout, i2: str, n: int, wl: int) -> None:
    """Rigid wall wl on node n: land on the plane, no velocity into it."""
    nr = [g.R["wn", wl, d] for d in range(g.D)]
    pt = [g.R["wp", wl, d] for d in range(g.D)]
    xw = [g.R["x", n, d] for d in range(g.D)]
    g.emit(f"{i2}wv, gap, dist = 0.0, 0.0, 0.0")
    for d in range(g.D):
        g.emit(f"{i2}wv, gap, dist = wall_plane(wv, gap, dist, vn_{d}, {xw[d]}, {pt[d]}, {nr[d]}, dtw)")
    g.emit(f"{i2}dvn = wall_jump(wv, gap, dist, dtw, {g.R['wk', wl]})")
    g.emit(f"{i2}c = wall_hold(dvn, {_lsum([f'a_{d} * {nr[d]}' for d in range(g.D)])}, h * dtw)")
    g.emit(f"{i2}we = 0.0")
    for d in range(g.D):
        jp = g.R["jp", wl, n, d]
        free = float(g.free[n][d])
        g.emit(
            f"{i2}vn_{d}, a_{d}, we, {jp} = wall_dof(dvn, c, {nr[d]}, {free!r}, vn_{d}, a_{d}, vo_{d}, {jp}, we)"
        )
    g.emit(f"{i2}we{wl}_{n} = wall_work({g.R['m', n]}, we)")
    g.emit(f"{i2}wf{wl} = wf{wl} + wall_force({g.R['m', n]}, c)")
    g.emit(f"{i2}{g.R['wi', wl]} = {g.R['wi', wl]} + wall_impulse({g.R['m', n]}, dvn, c, h * dtw) * af")
