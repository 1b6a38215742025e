"""Hand-specialised loop for ``studies/models/helicopter-subfloor.yaml`` (benchmarks only).

The model: ground (fixed) -- underfloor -- transmission -- cabin -- troop_compartment, 2-D, gravity, both
springs ``general_nonlinear`` with a loading and an unloading curve and yield forces. What a hand-coder
would write for this one model: the topology and the curves' shapes are compile-time constants (ramp
sums with literal knots), one variant at a time with its whole state in registers (nine numbers per
spring, two nodes of two dofs), and the variants spread over threads. Everything a study varies comes
in per variant: masses, initial velocities, gravity, each curve's force scale ``ys`` and abscissa scale
``xs`` (``F = ys * curve(e / xs)``), the yield forces, the step and the step count (taken from
crashstudy's batch, so element-steps are equal).

The material law itself is crashstudy's :func:`crashstudy.kernel.laws.general_law` (rules 1-3, a few
selects) and, for the rare rule-4 reversal, ``general_reverse_call`` on the batch's curve arrays: the loop
specialises the structure around the law, not the law. It computes the peak |force| per spring over the
steps (no knot-peak search between steps: docs/solver.md "Peaks"), which :func:`check` compares with
crashstudy's (the springs whose curve has a knot peak are reported apart by ``benchmarks/matrix.py``).
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numba as nb
import numpy as np

from chain_specialised import _pos, _ramp_src  # benchmarks/: the ramp-sum source of the chain loop
from crashstudy.kernel.laws import general_law, general_reverse_call
from crashstudy.schema.yamlio import load_yaml

ROOT = Path(__file__).resolve().parents[1]
MODEL = ROOT / "studies" / "models" / "helicopter-subfloor.yaml"
NODE_IDS = ("ground", "transmission", "troop_compartment")
SPRING_IDS = ("underfloor", "cabin")
CURVE_IDS = ("underfloor-loading", "underfloor-unloading", "cabin-loading", "cabin-unloading")


def _curves() -> dict[str, Any]:
    m = load_yaml(str(MODEL)).data
    assert tuple(m["nodes"]) == NODE_IDS and tuple(m["springs"]) == SPRING_IDS, (
        "helicopter-subfloor.yaml changed"
    )
    ns: dict[str, Any] = {"pos": _pos}
    for k, cid in enumerate(CURVE_IDS):  # ramp sums with literal knots, as the chain loop writes them
        x, y = np.asarray(m["curves"][cid]["x"], float), np.asarray(m["curves"][cid]["y"], float)
        source = f"def c{k}(e):\n    return {_ramp_src('e', x, y)}\n"
        exec(compile(source, "<helicopter_specialised>", "exec"), ns)  # noqa: S102 - our own source
    return {f"c{k}": nb.njit(inline="always", error_model="numpy")(ns[f"c{k}"]) for k in range(4)}


_C = _curves()
c0, c1, c2, c3 = _C["c0"], _C["c1"], _C["c2"], _C["c3"]


@nb.njit(nogil=True, error_model="numpy", cache=False)
def _run_range(
    lo, hi, m1, m2, v0, g, x0, l0, ys, ixs, yt, yc, dt, n_steps, cx, cy, cds, cs0, cs1, off, ca, cb, pf
):  # pragma: no cover  # noqa: E501
    for v in range(lo, hi):
        im1, im2 = 1.0 / m1[v], 1.0 / m2[v]
        gx, gy = g[0, v], g[1, v]
        # displacements and velocities of transmission (1) and troop compartment (2)
        u1x = u1y = u2x = u2y = 0.0
        v1x, v1y, v2x, v2y = v0[1, 0, v], v0[1, 1, v], v0[2, 0, v], v0[2, 1, v]
        X0x, X0y = x0[0, 0, v], x0[0, 1, v]
        X1x, X1y = x0[1, 0, v], x0[1, 1, v]
        X2x, X2y = x0[2, 0, v], x0[2, 1, v]
        L0a, L0b = l0[0, v], l0[1, v]
        ysa, ixa, ysau, ixau = ys[0, v], ixs[0, v], ys[1, v], ixs[1, v]
        ysb, ixb, ysbu, ixbu = ys[2, v], ixs[2, v], ys[3, v], ixs[3, v]
        yta, yca, ytb, ycb = yt[0, v], yc[0, v], yt[1, v], yc[1, v]
        # general_nonlinear state: mode, e_t*, F_t*, e_c*, F_c*, shift, yielded_t, yielded_c
        ma = eta = fta = eca = fca = sha = yla = ylca = 0.0
        mb = etb = ftb = ecb = fcb = shb = ylb = ylcb = 0.0
        pfa = pfb = 0.0
        h = dt[v]
        for n in range(n_steps[v] + 1):
            # underfloor: ground -> transmission
            dx, dy = (X1x + u1x) - X0x, (X1y + u1y) - X0y
            La = np.sqrt(dx * dx + dy * dy)
            ea = La - L0a
            Fa, ma, eta, fta, eca, fca, yla, ylca, rev = general_law(
                ea,
                ma,
                eta,
                fta,
                eca,
                fca,
                yla,
                ylca,
                ysa * c0((ea - sha) * ixa),
                ysau * c1((ea - eta) * ixau),
                ysau * c1((ea - eca) * ixau),
                yta,
                yca,
            )
            if rev:
                Fa, ma, eta, fta, eca, fca, sha, yla, ylca = general_reverse_call(
                    ea,
                    ma,
                    eta,
                    fta,
                    eca,
                    fca,
                    yla,
                    ylca,
                    yta,
                    yca,
                    ca[0],
                    cb[0],
                    v,
                    cx,
                    cy,
                    cds,
                    cs0,
                    cs1,
                    off,
                )
            nax, nay = dx / La, dy / La
            # cabin: transmission -> troop compartment
            dx, dy = (X2x + u2x) - (X1x + u1x), (X2y + u2y) - (X1y + u1y)
            Lb = np.sqrt(dx * dx + dy * dy)
            eb = Lb - L0b
            Fb, mb, etb, ftb, ecb, fcb, ylb, ylcb, rev = general_law(
                eb,
                mb,
                etb,
                ftb,
                ecb,
                fcb,
                ylb,
                ylcb,
                ysb * c2((eb - shb) * ixb),
                ysbu * c3((eb - etb) * ixbu),
                ysbu * c3((eb - ecb) * ixbu),
                ytb,
                ycb,
            )
            if rev:
                Fb, mb, etb, ftb, ecb, fcb, shb, ylb, ylcb = general_reverse_call(
                    eb,
                    mb,
                    etb,
                    ftb,
                    ecb,
                    fcb,
                    ylb,
                    ylcb,
                    ytb,
                    ycb,
                    ca[1],
                    cb[1],
                    v,
                    cx,
                    cy,
                    cds,
                    cs0,
                    cs1,
                    off,
                )
            nbx, nby = dx / Lb, dy / Lb
            pfa = max(pfa, abs(Fa))
            pfb = max(pfb, abs(Fb))
            # nodal forces (tension pulls the ends together), gravity, central difference
            a1x = (-Fa * nax + Fb * nbx) * im1 + gx
            a1y = (-Fa * nay + Fb * nby) * im1 + gy
            a2x = (-Fb * nbx) * im2 + gx
            a2y = (-Fb * nby) * im2 + gy
            hs = 0.5 * h if n == 0 else h
            v1x += hs * a1x
            v1y += hs * a1y
            v2x += hs * a2x
            v2y += hs * a2y
            u1x += h * v1x
            u1y += h * v1y
            u2x += h * v2x
            u2y += h * v2y
        pf[0, v] = pfa
        pf[1, v] = pfb


def run_specialised(b: Any, threads: int = 2) -> SimpleNamespace:
    """Peak |force| per spring (S, V) of every variant of batch ``b`` (a crashstudy Batch of the helicopter model)."""
    N, D, V = b.x0.shape
    assert (N, D, tuple(b.spring_i), tuple(b.spring_j)) == (3, 2, (0, 1), (1, 2)), "not the helicopter model"
    assert np.all(b.free[0] == 0.0) and np.all(b.free[1:] == 1.0) and len(b.wall_nodes) == 0
    assert np.all(b.fail_t == np.inf) and np.all(b.fail_c == -np.inf) and b.state0.shape[0] == 0, "no options"
    curves = np.array([b.curve_a[0], b.curve_b[0], b.curve_a[1], b.curve_b[1]])
    ys = np.ascontiguousarray(b.cfac[0, curves])
    ixs = np.ascontiguousarray(1.0 / b.cfac[1, curves])
    pf = np.zeros((2, V))
    args = (
        b.mass[1],
        b.mass[2],
        b.v0,
        b.gravity,
        b.x0,
        b.length0,
        ys,
        ixs,
        b.yield_t,
        b.yield_c,
        b.dt,
        b.n_steps.astype(np.int64),
        b.cx,
        b.cy,
        b.cds,
        b.cs0,
        b.cs1,
        b.curve_off,
        b.curve_a,
        b.curve_b,
        pf,
    )
    cuts = np.linspace(0, V, min(V, 8 * threads) + 1).astype(np.int64)
    with ThreadPoolExecutor(max(1, threads)) as pool:
        list(pool.map(lambda k: _run_range(cuts[k], cuts[k + 1], *args), range(len(cuts) - 1)))
    return SimpleNamespace(peak_force=pf)
