"""Compiled criteria of one row (one variant), called by :func:`crashstudy.metrics.criteria.compute`.

Every function reads samples ``x[0..n-1]`` at ``t_k = k dt`` and treats the signal as the
piecewise-linear curve through them (integrals are exact integrals of that curve, i.e. the
trapezoid rule); each has a plain NumPy twin in the tests.
"""

from __future__ import annotations

import math

import numpy as np

from crashstudy.kernel.cache import cached_njit

_jit = cached_njit(nogil=True)
NOT_REACHED = -1.0  # OLC: t1 or t2 not reached within the record
BLOCK = 1.5  # HIC search: blocks of BLOCK sqrt(window / dt) samples, rows taken 16 samples at a time


@_jit
def _int_at(cum, x, j, phi, dt):  # pragma: no cover - compiled
    """Integral of the piecewise-linear curve from 0 to ``(j + phi) dt``, ``0 <= phi <= 1``."""
    if phi <= 0.0:
        return cum[j]
    return cum[j] + dt * phi * (x[j] + 0.5 * phi * (x[j + 1] - x[j]))


@_jit
def _hic_value(s, ln):  # pragma: no cover - compiled
    return s * s * math.sqrt(s) / (ln * math.sqrt(ln))


@_jit
def peak_row(x, n):  # pragma: no cover - compiled
    """Largest value of ``x[:n]``, refined by the parabola through the largest sample and its two
    neighbours when it is interior and curved (``y1 - (y0 - y2)^2 / (8 (y0 - 2 y1 + y2))``)."""
    k = 0
    for i in range(1, n):
        if x[i] > x[k]:
            k = i
    if 0 < k < n - 1:
        y0, y1, y2 = x[k - 1], x[k], x[k + 1]
        den = y0 - 2.0 * y1 + y2
        if den < 0.0:
            return y1 - (y0 - y2) * (y0 - y2) / (8.0 * den)
    return x[k]


@_jit
def _beats(s, ln, best2):  # pragma: no cover - compiled
    """``S^2.5 / L^1.5 > best`` without roots: ``S^5 > best^2 L^3`` (all positive)."""
    s2 = s * s
    return s2 * s2 * s > best2 * ln * ln * ln


@_jit
def _sift_down(key, heap, i, size):  # pragma: no cover - compiled
    """Restore the max-heap order of ``heap[:size]`` (indices into ``key``) below position ``i``."""
    while True:
        c = 2 * i + 1
        if c >= size:
            return
        if c + 1 < size and key[heap[c + 1]] > key[heap[c]]:
            c += 1
        if key[heap[c]] <= key[heap[i]]:
            return
        heap[i], heap[c] = heap[c], heap[i]
        i = c


@_jit
def hic_row(x, n, dt, window, cum, blk, refine):  # pragma: no cover - compiled
    """HIC of ``x[:n] >= 0`` [g] sampled every ``dt`` [s] over ``0 < t2 - t1 <= window`` [s].

    Returns ``(hic, t1, t2)`` [-, s, s]. The candidates are every pair of samples ``t1 < t2``
    no more than ``window`` apart, plus the intervals of exactly ``window`` that start or end on a
    sample (the other end interpolated), so that an active window limit is met exactly, and (with
    ``refine``, the product passes True; no default: a call that omits it is another numba signature,
    compiled again for ~3 CPU s) the intervals of exactly ``window`` whose start lies between samples where the
    integral over the window is stationary (``x(t1) = x(t1 + window)``, solved on each piece of the
    piecewise-linear curve): the window-limited HIC is then exact for that curve. The search
    is exact (tests hold it equal to a brute force): the sample pairs are grouped into blocks
    ``B x B`` (``B ~ sqrt(window / dt)``); a block's bound is ``min(S_max^2.5 / L_min^1.5,
    L_max M^2.5)`` with ``S_max`` the integral over its widest interval, ``L_min``/``L_max`` its
    shortest/longest interval and ``M`` the largest sample it spans (``HIC = S^2.5/L^1.5`` grows
    with ``S`` and falls with ``L``, and ``S <= L M``); a whole row of blocks is skipped when
    ``S_row M_row^1.5`` cannot beat the best; blocks are searched in decreasing bound until the
    bound cannot beat the best, each row of a block 16 samples at a time under the same bound.
    ``cum`` and ``blk`` are scratch of length >= n + 1.
    """
    if n < 2:
        return math.nan, math.nan, math.nan
    cum[0] = 0.0
    for k in range(1, n):
        cum[k] = cum[k - 1] + 0.5 * dt * (x[k - 1] + x[k])
    wn = window / dt
    p = int(math.floor(wn * (1.0 + 1e-12)))
    frac = max(wn - p, 0.0)
    # intervals of exactly `window` (one end on a sample, the other interpolated): largest S
    sw = 0.0
    wi = -1.0
    wj = -1.0
    if p + 1 <= n - 1 or (p <= n - 1 and frac == 0.0):
        for i in range(n):
            j = i + p
            if j > n - 1 or (j == n - 1 and frac > 0.0):
                break
            s = _int_at(cum, x, j, frac, dt) - cum[i]
            if s > sw:
                sw, wi, wj = s, i, j + frac
        phi = 1.0 - frac if frac > 0.0 else 0.0
        for j in range(n - 1, -1, -1):
            jj = j - p - 1 if frac > 0.0 else j - p
            if jj < 0:
                break
            s = cum[j] - _int_at(cum, x, jj, phi, dt)
            if s > sw:
                sw, wi, wj = s, jj + phi, j
        if refine:  # t1 between samples: S'(t1) = x(t1 + window) - x(t1) = 0 on a piece
            for i in range(n - 1):
                for piece in range(2):
                    if piece == 0:
                        s0, s1, j, off = 0.0, 1.0 - frac, i + p, frac
                    else:
                        if frac == 0.0:
                            break
                        s0, s1, j, off = 1.0 - frac, 1.0, i + p + 1, frac - 1.0
                    if j + 1 > n - 1:
                        break
                    da = x[i + 1] - x[i]
                    db = x[j + 1] - x[j]
                    if db - da >= 0.0:
                        continue  # no interior maximum of S on this piece
                    st = (x[j] + db * off - x[i]) / (da - db)
                    if s0 < st < s1:
                        s = _int_at(cum, x, j, st + off, dt) - _int_at(cum, x, i, st, dt)
                        if s > sw:
                            sw, wi, wj = s, i + st, j + st + off
    best = _hic_value(sw, window) if sw > 0.0 else 0.0
    bi = wi
    bj = wj
    # sample pairs 1 <= j - i <= p: branch and bound over blocks
    pmax = min(p, n - 1)
    if pmax >= 1:
        bs = max(4, int(BLOCK * math.sqrt(pmax)))
        nb_ = (n + bs - 1) // bs
        for b in range(nb_):
            m = 0.0
            for k in range(b * bs, min(n, (b + 1) * bs)):
                m = max(m, x[k])
            blk[b] = m
            # first candidates: from each block start, lengths pmax, pmax/2, ...
            i0 = b * bs
            ln = pmax
            while ln >= 1:
                jc = min(i0 + ln, n - 1)
                if jc > i0:
                    s = cum[jc] - cum[i0]
                    if _beats(s, (jc - i0) * dt, best * best):
                        best, bi, bj = _hic_value(s, (jc - i0) * dt), i0, jc
                ln //= 2
        span = pmax // bs + 2
        npair = nb_ * span
        bound = np.full(npair, -1.0)
        mpow = np.zeros(npair)
        for b in range(nb_):
            i0 = b * bs
            i1 = min(n, i0 + bs) - 1
            # all pairs starting in this block: S <= S_row, S / L <= M_row, HIC = S (S/L)^1.5
            mrow = 0.0
            for c in range(b, min(nb_, (i1 + pmax) // bs + 1)):
                mrow = max(mrow, blk[c])
            srow = cum[min(n - 1, i1 + pmax)] - cum[i0]
            if srow * mrow * math.sqrt(mrow) * (1.0 + 1e-9) <= best:
                continue
            m = 0.0
            for d in range(span):
                c = b + d
                if c >= nb_:
                    break
                j0 = c * bs
                j1 = min(n, j0 + bs) - 1
                if j0 - i1 > pmax:
                    break
                m = max(m, blk[c])
                lmin = max(j0 - i1, 1)
                lmax = min(j1 - i0, pmax)
                if lmax < 1:
                    continue
                smax = cum[min(j1, i1 + pmax)] - cum[i0]
                if smax <= 0.0:
                    continue
                m25 = m * m * math.sqrt(m)
                ub = min(_hic_value(smax, lmin * dt), lmax * dt * m25)
                bound[b * span + d] = ub * (1.0 + 1e-9)
                mpow[b * span + d] = m25 * (1.0 + 1e-9)
        # blocks that can beat the best, in decreasing bound, popped from a max-heap (numba's np.argsort
        # quicksort took ~8 s of the criteria's compile; the heap compiles in well under a second)
        heap = np.nonzero(bound > best)[0]
        size = heap.size
        for i in range(size // 2 - 1, -1, -1):
            _sift_down(bound, heap, i, size)
        best2 = best * best * (1.0 - 1e-9)  # sub-block tests: a little loose, never skip a winner
        while size > 0:
            q = heap[0]
            if bound[q] <= best:
                break
            size -= 1
            heap[0] = heap[size]
            _sift_down(bound, heap, 0, size)
            b = q // span
            c = b + q % span
            i0 = b * bs
            i1 = min(n, i0 + bs) - 1
            j0 = c * bs
            j1 = min(n, j0 + bs) - 1
            m25 = mpow[q]
            for i in range(i0, i1 + 1):
                ci = cum[i]
                jl = max(j0, i + 1)
                jhi = min(j1, i + pmax)
                while jl <= jhi:
                    jh = min(jl + 15, jhi)
                    if (jh - i) * dt * m25 > best and _beats(cum[jh] - ci, (jl - i) * dt, best2):
                        for j in range(jl, jh + 1):
                            s = cum[j] - ci
                            if s > 0.0 and _beats(s, (j - i) * dt, best2):
                                h = _hic_value(s, (j - i) * dt)
                                if h > best:
                                    best, bi, bj = h, i, j
                                    best2 = best * best * (1.0 - 1e-9)
                    jl = jh + 1
    if bi < 0.0:
        return 0.0, math.nan, math.nan
    return best, bi * dt, bj * dt


@_jit
def olc_row(u, n, dt, u0, s_free, s_rest):  # pragma: no cover - compiled
    """Occupant load criterion from the node's speed ``u[:n]`` along the direction [length/time]
    with initial speed ``u0``: a free occupant at ``u0`` moves ``s_free`` relative to the node (time
    ``t1``), then decelerates at a constant rate ``olc`` so that it reaches the node's speed at ``t2``
    after a further ``s_rest``. With ``D(t) = u0 - u(t)`` (piecewise linear):
    ``int_0^t1 D = s_free`` and ``int_t1^t2 D - D(t2) (t2 - t1) / 2 = s_rest``, both solved exactly
    within a step; ``olc = D(t2) / (t2 - t1)``. Returns ``(olc, t1, t2)`` [length/time^2, time,
    time]; ``(nan, NOT_REACHED, ..)`` when the record ends first. ``G`` is linear within a step
    (its quadratic terms cancel), so ``t2`` is exact for the piecewise-linear ``D``."""
    if n < 2:
        return math.nan, math.nan, math.nan
    # phase 1
    acc = 0.0
    t1 = NOT_REACHED
    k1 = -1
    for k in range(n - 1):
        d0 = u0 - u[k]
        d1 = u0 - u[k + 1]
        seg = 0.5 * dt * (d0 + d1)
        if acc + seg >= s_free and seg > 0.0:
            # solve acc + d0 tau + (d1 - d0) tau^2 / (2 dt) = s_free, tau in [0, dt]
            tau = _root(0.5 * (d1 - d0) / dt, d0, acc - s_free, dt)
            t1 = k * dt + tau
            k1 = k
            break
        acc += seg
    if k1 < 0:
        return math.nan, NOT_REACHED, NOT_REACHED
    tau1 = t1 - k1 * dt
    d0 = u0 - u[k1]
    slope = ((u0 - u[k1 + 1]) - d0) / dt
    # G(t) = int_t1^t D - D(t)(t - t1)/2 - s_rest, piecewise quadratic in t
    integ = 0.0  # int_t1^(start of current piece)
    start = t1
    ds = d0 + slope * tau1  # D at piece start
    k = k1
    while k < n - 1:
        dk1 = u0 - u[k + 1]
        tend = (k + 1) * dt
        sl = (dk1 - (u0 - u[k])) / dt
        # on [start, tend]: D(t) = ds + sl h, h = t - start, int_t1^t D = integ + ds h + sl h^2 / 2,
        # G = integ + ds h + sl h^2/2 - (ds + sl h)(e + h)/2 - s_rest with e = start - t1: the h^2
        # terms cancel, so G is linear on the piece
        e = start - t1
        qb = 0.5 * ds - 0.5 * sl * e
        qc = integ - 0.5 * ds * e - s_rest
        h_end = tend - start
        if qb * h_end + qc >= 0.0:
            h = _root(0.0, qb, qc, h_end)
            t2 = start + h
            dd = ds + sl * h
            if t2 - t1 <= 0.0:
                return math.nan, t1, NOT_REACHED
            return dd / (t2 - t1), t1, t2
        integ += ds * h_end + 0.5 * sl * h_end * h_end
        ds = dk1
        start = tend
        k += 1
    return math.nan, t1, NOT_REACHED


@_jit
def _root(qa, qb, qc, hmax):  # pragma: no cover - compiled
    """The smallest root in ``[0, hmax]`` of ``qa h^2 + qb h + qc`` (which is <= 0 at 0 and >= 0 at
    ``hmax``), by a stable quadratic formula, falling back to bisection."""
    if qa == 0.0:
        h = -qc / qb if qb != 0.0 else 0.0
    else:
        disc = qb * qb - 4.0 * qa * qc
        if disc < 0.0:
            disc = 0.0
        sq = math.sqrt(disc)
        qq = -0.5 * (qb + (sq if qb >= 0.0 else -sq))
        r1 = qq / qa
        r2 = qc / qq if qq != 0.0 else r1
        h = math.inf
        for r in (r1, r2):
            if -1e-12 * hmax <= r <= hmax * (1.0 + 1e-12) and r < h:
                h = r
        if h == math.inf:
            lo, hi = 0.0, hmax
            for _ in range(100):
                mid = 0.5 * (lo + hi)
                if qa * mid * mid + qb * mid + qc >= 0.0:
                    hi = mid
                else:
                    lo = mid
            h = hi
    return min(max(h, 0.0), hmax)


@_jit
def dri_row(d, n, phi, g0, gs):  # pragma: no cover - compiled
    """Largest compression ``x`` of ``x'' + 2 zeta omega x' + omega^2 x = d(t)`` from rest, ``d``
    piecewise linear between samples (exact per step: ``z+ = Phi z + G0 d_k + Gs (d_k+1 - d_k)``).
    Returns ``max(0, max_k x_k)`` in the units of ``d`` times s^2."""
    x = 0.0
    v = 0.0
    xmax = 0.0
    for k in range(n - 1):
        dk = d[k]
        dd = d[k + 1] - dk
        xn = phi[0, 0] * x + phi[0, 1] * v + g0[0] * dk + gs[0] * dd
        v = phi[1, 0] * x + phi[1, 1] * v + g0[1] * dk + gs[1] * dd
        x = xn
        if x > xmax:
            xmax = x
    return xmax
