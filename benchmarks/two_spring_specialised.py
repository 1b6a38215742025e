"""Hand-specialised loop for the 2-spring model of ``small_models.py`` (benchmarks only).

What the hardware gives for this one model: 1-D, a fixed wall node 0 and two masses; spring ``s1``
joins the wall and mass 1, ``s2`` mass 1 and mass 2, both ``nonlinear_elastic`` with curves that
are compile-time constants (ramp sums, branch-free). One fused loop over the variants of a block
(``BLOCK`` contiguous columns) does both springs, both node updates and every summary of a time
step, so LLVM can put several variants in one SIMD instruction (``fastmath``, inverse masses: an upper
bound on speed, not a twin; peak forces agree with crashstudy's to about 1e-9). It takes the same per-variant steps
as crashstudy (``dt``, ``n_steps`` from the batch), so element-steps are equal, and computes peak
|force|, largest crush and absorbed energy per spring and peak |acceleration| per mass;
``small_models.py`` checks the peak forces against crashstudy's.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import numba as nb
import numpy as np

BLOCK = 256
# the curves of small_models.MODELS[2] (x: elongation m, y: force N); ramp sums y0 + s0 (e - x0) + sum ds max(0, e - xk)
C1 = ((-0.2, -4.0e5), (-0.05, -6.0e4), (0.0, 0.0), (0.05, 6.0e4))
C2 = ((-0.2, -2.0e5), (-0.05, -3.0e4), (0.0, 0.0), (0.05, 3.0e4))


def _ramp(curve: tuple[tuple[float, float], ...]) -> tuple[float, ...]:
    x = np.array([p[0] for p in curve])
    y = np.array([p[1] for p in curve])
    s = np.diff(y) / np.diff(x)
    out = [float(y[0]), float(s[0]), float(x[0])]
    for k in range(1, len(x) - 1):
        out += [float(x[k]), float(s[k] - s[k - 1])]
    return tuple(out)


R1, R2 = _ramp(C1), _ramp(C2)


@nb.njit(cache=True, nogil=True, fastmath=True, inline="always")
def _f1(e):  # pragma: no cover - compiled
    return R1[0] + R1[1] * (e - R1[2]) + R1[4] * max(0.0, e - R1[3]) + R1[6] * max(0.0, e - R1[5])


@nb.njit(cache=True, nogil=True, fastmath=True, inline="always")
def _f2(e):  # pragma: no cover - compiled
    return R2[0] + R2[1] * (e - R2[2]) + R2[4] * max(0.0, e - R2[3]) + R2[6] * max(0.0, e - R2[5])


@nb.njit(cache=True, nogil=True, fastmath=True)
def _block(lo, hi, m1, m2, v1_0, v2_0, dt, n_steps, peak_f, crush, energy, peak_a):  # pragma: no cover
    B = hi - lo
    u1 = np.zeros(B)
    u2 = np.zeros(B)
    v1 = np.empty(B)
    v2 = np.empty(B)
    f1p = np.zeros(B)
    f2p = np.zeros(B)
    e1p = np.zeros(B)
    e2p = np.zeros(B)
    pf1 = np.zeros(B)
    pf2 = np.zeros(B)
    c1 = np.zeros(B)
    c2 = np.zeros(B)
    w1 = np.zeros(B)
    w2 = np.zeros(B)
    pa1 = np.zeros(B)
    pa2 = np.zeros(B)
    for w in range(B):
        v1[w] = v1_0[lo + w]
        v2[w] = v2_0[lo + w]
    n_max = 0
    for w in range(B):
        n_max = max(n_max, n_steps[lo + w])
    for n in range(n_max + 1):
        for w in range(B):  # branch-free: a lane past its step count is masked (mk = 0), not skipped
            k = lo + w
            mk = 1.0 if n <= n_steps[k] else 0.0
            h = dt[k]
            e1 = u1[w]
            e2 = u2[w] - u1[w]
            f1 = _f1(e1)
            f2 = _f2(e2)
            a1 = (f2 - f1) * m1[k]  # m1, m2: inverse masses
            a2 = -f2 * m2[k]
            hn = h if n > 0 else 0.5 * h
            w1[w] += mk * (0.5 * (f1 + f1p[w]) * (e1 - e1p[w]))
            w2[w] += mk * (0.5 * (f2 + f2p[w]) * (e2 - e2p[w]))
            pf1[w] = max(pf1[w], mk * abs(f1))
            pf2[w] = max(pf2[w], mk * abs(f2))
            c1[w] = max(c1[w], -(mk * e1))
            c2[w] = max(c2[w], -(mk * e2))
            pa1[w] = max(pa1[w], mk * abs(a1))
            pa2[w] = max(pa2[w], mk * abs(a2))
            v1[w] += mk * (hn * a1)
            v2[w] += mk * (hn * a2)
            u1[w] += mk * (h * v1[w])
            u2[w] += mk * (h * v2[w])
            f1p[w] = f1
            f2p[w] = f2
            e1p[w] = e1
            e2p[w] = e2
    for w in range(B):
        k = lo + w
        peak_f[0, k], peak_f[1, k] = pf1[w], pf2[w]
        crush[0, k], crush[1, k] = c1[w], c2[w]
        energy[0, k], energy[1, k] = w1[w], w2[w]
        peak_a[0, k], peak_a[1, k] = pa1[w], pa2[w]


def run_specialised(
    m1: np.ndarray,
    m2: np.ndarray,
    v1: np.ndarray,
    v2: np.ndarray,
    dt: np.ndarray,
    n_steps: np.ndarray,
    threads: int = 2,
) -> dict[str, np.ndarray]:
    """Integrate every variant (arrays of length V); returns the summaries, springs/masses on axis 0."""
    V = len(dt)
    out = {k: np.zeros((2, V)) for k in ("peak_force", "max_crush", "absorbed_energy", "peak_acceleration")}
    starts = list(range(0, V, BLOCK)) + [V]
    args = (
        1.0 / m1,
        1.0 / m2,
        v1,
        v2,
        dt,
        n_steps.astype(np.int64),
        out["peak_force"],
        out["max_crush"],
        out["absorbed_energy"],
        out["peak_acceleration"],
    )
    with ThreadPoolExecutor(threads) as pool:
        list(pool.map(lambda b: _block(starts[b], starts[b + 1], *args), range(len(starts) - 1)))
    return out
