"""Hand-specialised loop for ``benchmarks/matrix.py``'s grid model (benchmarks only).

The grid: ``nx`` x ``ny`` nodes in 2-D (node ``(i, j)`` at index ``j nx + i``, row ``j = 0`` fixed), a
horizontal ``linear_elastic`` spring between ``(i, j)`` and ``(i + 1, j)`` on every row above the bottom
one, a vertical spring between ``(i, j)`` and ``(i, j + 1)``: ``crush`` on the bottom row, ``linear_elastic``
above. What a hand-coder would write for this structure: no topology arrays in the step, the neighbours
by index arithmetic (two nested loops over the rows and columns per spring family), one variant at a
time with its nodes in a small work array (L1-resident), the variants spread over threads. Per variant
(crashstudy's batch, so element-steps are equal): masses, initial velocities, each spring's stiffness
or unloading stiffness, the crush curve's force and abscissa scale, the step and the step count. The
crush law is crashstudy's :func:`crashstudy.kernel.laws.crush_law` (three selects); the crush curve's
shape is a ramp sum with literal knots. Peak |force| per spring over the steps, compared by
:func:`benchmarks.matrix.hand_loop` with crashstudy's.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from types import SimpleNamespace
from typing import Any

import numba as nb
import numpy as np

from chain_specialised import _pos  # benchmarks/: max(0, x) as a select
from crashstudy.kernel.laws import crush_law

NX = 20  # matrix.grid_model's default width (the row length is not in the batch: asserted below)


@nb.njit(nogil=True, error_model="numpy")
def _run_range(
    lo, hi, nx, ny, hid, vid, cx, cy, inv_mass, x0, v0, l0, k, ys, ixs, dt, n_steps, pf
):  # pragma: no cover  # noqa: E501
    N = nx * ny
    s0 = (cy[1] - cy[0]) / (cx[1] - cx[0])
    s1 = (cy[2] - cy[1]) / (cx[2] - cx[1])
    x, y = np.empty(N), np.empty(N)
    vx, vy = np.empty(N), np.empty(N)
    fx, fy = np.empty(N), np.empty(N)
    S = pf.shape[0]
    peak = np.empty(S)
    emin, fstar = np.empty(nx), np.empty(nx)
    for v in range(lo, hi):
        for q in range(N):
            x[q], y[q] = x0[q, 0, v], x0[q, 1, v]
            vx[q], vy[q] = v0[q, 0, v], v0[q, 1, v]
        peak[:] = 0.0
        emin[:] = 0.0
        fstar[:] = 0.0
        h = dt[v]
        for n in range(n_steps[v] + 1):
            fx[:] = 0.0
            fy[:] = 0.0
            for j in range(ny):
                for i in range(nx):
                    a = j * nx + i
                    if j > 0 and i + 1 < nx:  # horizontal: (i, j) - (i + 1, j), linear
                        s = hid[a]
                        dx, dy = x[a + 1] - x[a], y[a + 1] - y[a]
                        L = np.sqrt(dx * dx + dy * dy)
                        F = k[s, v] * (L - l0[s, v])
                        peak[s] = max(peak[s], abs(F))
                        gx, gy = F * dx / L, F * dy / L
                        fx[a] += gx
                        fy[a] += gy
                        fx[a + 1] -= gx
                        fy[a + 1] -= gy
                    if j + 1 < ny:  # vertical: (i, j) - (i, j + 1), crush on the bottom row
                        s = vid[a]
                        b = a + nx
                        dx, dy = x[b] - x[a], y[b] - y[a]
                        L = np.sqrt(dx * dx + dy * dy)
                        e = L - l0[s, v]
                        if j == 0:
                            z = e * ixs[v]
                            curve = cy[0] + s0 * (z - cx[0]) + (s1 - s0) * _pos(z - cx[1])
                            F, emin[i], fstar[i] = crush_law(e, emin[i], fstar[i], ys[v] * curve, k[s, v])
                        else:
                            F = k[s, v] * e
                        peak[s] = max(peak[s], abs(F))
                        gx, gy = F * dx / L, F * dy / L
                        fx[a] += gx
                        fy[a] += gy
                        fx[b] -= gx
                        fy[b] -= gy
            hs = 0.5 * h if n == 0 else h
            for q in range(nx, N):  # the bottom row is fixed
                vx[q] += hs * (fx[q] * inv_mass[q, 0, v])
                vy[q] += hs * (fy[q] * inv_mass[q, 1, v])
                x[q] += h * vx[q]
                y[q] += h * vy[q]
        for s in range(S):
            pf[s, v] = peak[s]


def run_specialised(b: Any, threads: int = 2) -> SimpleNamespace:
    """Peak |force| per spring (S, V) of every variant of batch ``b`` (a crashstudy Batch of the grid model)."""
    N, D, V = b.x0.shape
    nx, ny = NX, N // NX
    assert D == 2 and N == nx * ny, "not the matrix grid"
    hid, vid = np.full(N, -1, np.int64), np.full(N, -1, np.int64)
    for s, (i, j) in enumerate(zip(b.spring_i.tolist(), b.spring_j.tolist(), strict=True)):
        if j == i + 1:
            hid[i] = s
        else:
            assert j == i + nx, "not the matrix grid"
            vid[i] = s
    crush = vid[:nx]
    assert np.all(b.curve_a[crush] == b.curve_a[crush[0]]) and np.all(np.delete(b.curve_a, crush) < 0)
    c = int(b.curve_a[crush[0]])
    a, z = int(b.curve_off[c]), int(b.curve_off[c + 1])
    assert z - a == 3 and np.all(b.bx[a:z] == b.bx[a:z, :1]), "the crush curve: three points, one shape"
    assert np.all(b.free[:nx] == 0.0) and np.all(b.free[nx:] == 1.0) and len(b.wall_nodes) == 0
    pf = np.zeros((len(b.spring_i), V))
    args = (
        nx,
        ny,
        hid,
        vid,
        b.bx[a:z, 0].copy(),
        b.by[a:z, 0].copy(),
        b.inv_mass,
        b.x0,
        b.v0,
        b.length0,
        b.kpar,
        np.ascontiguousarray(b.cfac[0, c]),
        np.ascontiguousarray(1.0 / b.cfac[1, c]),
        b.dt,
        b.n_steps.astype(np.int64),
        pf,
    )
    cuts = np.linspace(0, V, min(V, 8 * threads) + 1).astype(np.int64)
    with ThreadPoolExecutor(max(1, threads)) as pool:
        list(pool.map(lambda q: _run_range(cuts[q], cuts[q + 1], *args), range(len(cuts) - 1)))
    return SimpleNamespace(peak_force=pf)
