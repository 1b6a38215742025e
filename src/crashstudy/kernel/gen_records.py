"""Emitters of a generated kernel's lane records at the end of a step: the lanes that fail, the histories
of the lanes that sample, the lanes that end (termination, final energies) and the compaction of the
block when an eighth of its lanes have ended.
"""

from __future__ import annotations

from crashstudy.kernel.gen_nodes import _chain
from crashstudy.kernel.gen_rows import One
from crashstudy.kernel.gen_shape import Layout
from crashstudy.vocabulary.codes import UNSTABLE_WALLS


def failures(g: Layout, i3: str) -> None:
    """The lanes whose energy balance broke or whose walls gave energy (or, in 2-D, whose spring collapsed)
    stop here (rare)."""
    g.emit(f"{i3}if nbad > 0:")
    g.emit(f"{i3}    for w in range(B):")
    g.emit(f"{i3}        if not fn <= {g.R['lim']}:")
    g.emit(f"{i3}            continue")
    wall_now = f"({g.R['wall_e']} if n > 0 else 0.0)" if g.W else "0.0"  # t = 0: before any impact
    work = g.R["work"] if g.ext else "0.0"
    bal = f"energy_balance({g.R['ken']}, {g.R['ien']}, {wall_now}, {g.R[g.E0]}, {work})"
    g.emit(f"{i3}        if unstable({bal}, {g.R['thr']}):")
    g.emit(f"{i3}            status[vi[w]] = UNSTABLE")
    if g.W:  # walls that gave energy while the balance held (docs/solver.md, "Instability tests")
        g.emit(f"{i3}        elif wall_gives({wall_now}, {g.R['thr']}):")
        g.emit(f"{i3}            status[vi[w]] = UNSTABLE")
        g.emit(f"{i3}            fail_item[vi[w]] = {UNSTABLE_WALLS}")
    if g.D > 1:
        g.emit(f"{i3}        elif {g.R['crushed']} >= 0.0:")
        g.emit(f"{i3}            status[vi[w]] = CRUSHED_TO_ZERO")
        g.emit(f"{i3}            fail_item[vi[w]] = int({g.R['crushed']})")
    g.emit(f"{i3}        else:")
    g.emit(f"{i3}            continue")
    g.emit(f"{i3}        fail_time[vi[w]] = n * {g.R['dt']}")
    g.emit(f"{i3}        n_fail[w] = n")
    g.emit(f"{i3}        {g.R['lim']} = -1.0")
    g.emit(f"{i3}    alive = -1")
    g.emit(f"{i3}    for w in range(B):")
    g.emit(f"{i3}        alive = max(alive, int({g.R['lim']}))")
    g.emit(f"{i3}    n_end = _next_end(Z, B, fn - 1.0)")
    g.emit(f"{i3}    ended = True")


def records(g: Layout, i3: str) -> None:
    """The histories of the lanes that sample at this step (the body of the kernel's ``_records``: it
    returns ``next_min``, the next step a running lane samples)."""
    if g.hist:
        g.emit(f"{i3}next_min = nmax + 1")
        g.emit(f"{i3}for w in range(B):")
        g.emit(f"{i3}    q = vi[w]")
        g.emit(f"{i3}    if fn > {g.R['lim']}:")
        g.emit(f"{i3}        continue")
        g.emit(f"{i3}    if n == next_rec[w]:")
        g.emit(f"{i3}        r = n // out_every[q]")
        g.emit(f"{i3}        next_rec[w] = n + out_every[q]")
        g.emit(f"{i3}        if r < n_out:")
        i5 = i3 + "            "
        R = g.R
        # the moving nodes' position, displacement and velocity: one loop over [n, d, xh, x0, vh, v]
        move = [
            [n, d, *(R.row((f, n, d)) * R.stride for f in ("xh", "x0", "vh", "v"))]
            for n in range(g.N)
            for d in range(g.D)
            if not g.static[n]
        ]
        kept = [h for h in ("position", "displacement", "velocity") if h in g.hist]
        if move and kept:
            t = g.table(move)
            g.emit(f"{i5}for i in range({len(move)}):")
            g.emit(f"{i5}    n_, d_ = {t}[i, 0], {t}[i, 1]")
            for name, arr, val in (
                ("position", "h_pos", f"Z[{t}[i, 2] + w]"),
                ("displacement", "h_disp", f"Z[{t}[i, 2] + w] - Z[{t}[i, 3] + w]"),
                # v^{n+1/2} is the lane's v row now (it ran: vn * 1.0 + vo * 0.0)
                (
                    "velocity",
                    "h_vel",
                    f"(0.5 * (Z[{t}[i, 4] + w] + Z[{t}[i, 5] + w]) if n > 0 else Z[{t}[i, 4] + w])",
                ),
            ):
                if name in g.hist:
                    g.emit(f"{i5}    {arr}[r, n_, d_, q] = {val}")
        for n in range(g.N):
            for d in range(g.D):
                if g.static[n]:
                    for name, arr, val in (
                        ("position", "h_pos", f"x0[{n}, {d}, q]"),
                        ("displacement", "h_disp", "0.0"),
                        ("velocity", "h_vel", "0.0"),
                        ("acceleration", "h_acc", "0.0"),
                    ):
                        if name in g.hist:
                            g.emit(f"{i5}{arr}[r, {n}, {d}, q] = {val}")
                    continue
                if "acceleration" not in g.hist:
                    continue
                chain = _chain(g, n, d, lambda s: R["fp", s], lambda s, d: R["axh", s, d])
                fext = f"{R['m', n]} * {R['g', d]}" if g.grav else "0.0"
                fext = R["fx", n, d] if n in g.loaded else fext  # this step's external force
                acc = f"({chain} + {fext}) * {R['im', n, d]}"
                for k, (p, dd, _, _) in enumerate(g.pm):  # a prescribed dof: its kinematic acceleration
                    if (p, dd) == (n, d):
                        acc = R["pma", k]
                acc = R["wa", n, d] if ("wa", n, d) in R else acc  # a wall node: with the contact force
                g.emit(f"{i5}h_acc[r, {n}, {d}, q] = {acc}")
        springs: tuple[tuple[str, str, One], ...] = (
            ("spring_force", "h_force", "fp"),
            ("spring_elongation", "h_elong", "ep"),
        )
        for name, arr, row in springs:
            if name in g.hist and g.S:
                t = g.table([[s, R.row((row, s)) * R.stride] for s in range(g.S)])
                g.emit(f"{i5}for i in range({g.S}):")
                g.emit(f"{i5}    {arr}[r, {t}[i, 0], q] = Z[{t}[i, 1] + w]")
        if "kinetic_energy" in g.hist:
            g.emit(f"{i5}h_energy[r, 0, q] = {g.R['ken']}")
            g.emit(f"{i5}h_energy[r, 1, q] = {g.R['ien']}")
            g.emit(f"{i5}h_energy[r, 2, q] = {g.R['work'] if g.ext else '0.0'}")
            g.emit(f"{i5}h_energy[r, 3, q] = {(g.R['wall_e'] + ' if n > 0 else 0.0') if g.W else '0.0'}")
        for wl in range(g.W if "wall_force" in g.hist else 0):
            g.emit(f"{i5}h_wall[r, {wl}, q] = {g.R['wf', wl]}")
        g.emit(f"{i3}    if fn + 1.0 <= {g.R['lim']}:")
        g.emit(f"{i3}        next_min = min(next_min, next_rec[w])")


def ends(g: Layout, i3: str, results: str) -> None:
    """Termination, final energies, and lane compaction: lanes whose variant ended leave the block once
    they are an eighth of it (their results are written by the call ``results``, the running lanes move
    down)."""
    if g.term:  # lanes that met the termination test (and did not fail) end at this step
        g.emit(f"{i3}if nstop > 0:")
        g.emit(f"{i3}    for w in range(B):")
        g.emit(f"{i3}        if {g.R['stop']} > 0.0 and fn <= {g.R['lim']}:")
        g.emit(f"{i3}            {g.R['lim']} = fn")
        g.emit(f"{i3}            n_end = fn")
        g.emit(f"{i3}    alive = -1")
        g.emit(f"{i3}    for w in range(B):")
        g.emit(f"{i3}        alive = max(alive, int({g.R['lim']}))")
    g.emit(f"{i3}if fn == n_end:")
    g.emit(f"{i3}    for w in range(B):")
    g.emit(f"{i3}        if fn == {g.R['lim']}:")
    g.emit(f"{i3}            final_energy[0, vi[w]] = {g.R['ken']}")
    g.emit(f"{i3}            final_energy[1, vi[w]] = {g.R['ien']}")
    g.emit(f"{i3}            final_energy[2, vi[w]] = {g.R['work'] if g.ext else '0.0'}")
    g.emit(f"{i3}            final_energy[3, vi[w]] = {g.R['wall_e'] if g.W else '0.0'}")
    g.emit(f"{i3}    n_end = _next_end(Z, B, fn)")
    g.emit(f"{i3}    ended = True")
    # lanes whose variant ended leave the block once they are an eighth of it: their results are
    # written now and the running lanes move down, so later steps run over fewer lanes
    g.emit(f"{i3}if ended:")
    g.emit(f"{i3}    ended = False")
    g.emit(f"{i3}    gone = 0")
    g.emit(f"{i3}    for w in range(B):")
    g.emit(f"{i3}        gone += 1 if fn + 1.0 > {g.R['lim']} else 0")
    g.emit(f"{i3}    if gone >= max(8, B // 8) and gone < B:")
    g.emit(f"{i3}        k = 0")
    g.emit(f"{i3}        for w in range(B):")
    g.emit(f"{i3}            if fn + 1.0 > {g.R['lim']}:")
    g.emit(f"{i3}                {results}")
    g.emit(f"{i3}                continue")
    g.emit(f"{i3}            if k != w:")
    g.emit(f"{i3}                for r in range(NROWS):")
    g.emit(f"{i3}                    Z[r * ROW + k] = Z[r * ROW + w]")
    g.emit(f"{i3}                vi[k] = vi[w]")
    g.emit(f"{i3}                next_rec[k] = next_rec[w]")
    g.emit(f"{i3}                n_fail[k] = n_fail[w]")
    g.emit(f"{i3}            k += 1")
    g.emit(f"{i3}        B = k")
    g.emit(f"{i3}        n_end = _next_end(Z, B, fn)")
    if g.hist:
        g.emit(f"{i3}        next_min = nmax + 1")
        g.emit(f"{i3}        for w in range(B):")
        g.emit(f"{i3}            next_min = min(next_min, next_rec[w])")
