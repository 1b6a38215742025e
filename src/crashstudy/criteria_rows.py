"""Compiled criteria of one row (one variant), called by :func:`crashstudy.criteria.compute`.

Every function reads samples ``x[0..n-1]`` at ``t_k = k dt`` and treats the signal as the
piecewise-linear curve through them (integrals are exact integrals of that curve, i.e. the
trapezoid rule); each has a plain NumPy twin in the tests.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

_jit = nb.njit(cache=True, nogil=True)
NOT_REACHED = -1.0  # OLC: t1 or t2 not reached within the record


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
def hic_row(x, n, dt, window, cum, blk):  # pragma: no cover - compiled
    """HIC of ``x[:n] >= 0`` [g] sampled every ``dt`` [s] over ``0 < t2 - t1 <= window`` [s].

    Returns ``(hic, t1, t2)`` [-, s, s]. The candidates are every pair of samples ``t1 < t2``
    no more than ``window`` apart, plus the intervals of exactly ``window`` that start or end on a
    sample (the other end interpolated), so that an active window limit is met exactly. The search
    is exact (tests hold it equal to a brute force): the sample pairs are grouped into blocks
    ``B x B``; a block's bound is ``min(S_max^2.5 / L_min^1.5, L_max M^2.5)`` with ``S_max`` the
    integral over its widest interval, ``L_min``/``L_max`` its shortest/longest interval and ``M``
    the largest sample it spans (``HIC = S^2.5/L^1.5`` grows with ``S`` and falls with ``L``, and
    ``S <= L M``); blocks are searched in decreasing bound until the bound cannot beat the best.
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
    best = 0.0
    bi = -1.0
    bj = -1.0
    # intervals of exactly `window` (one end on a sample, the other interpolated)
    if p + 1 <= n - 1 or (p <= n - 1 and frac == 0.0):
        for i in range(n):
            j = i + p
            if j > n - 1 or (j == n - 1 and frac > 0.0):
                break
            s = _int_at(cum, x, j, frac, dt) - cum[i]
            if s > 0.0:
                h = _hic_value(s, window)
                if h > best:
                    best, bi, bj = h, i, j + frac
        for j in range(n - 1, -1, -1):
            jj = j - p - 1 if frac > 0.0 else j - p
            if jj < 0:
                break
            phi = 1.0 - frac if frac > 0.0 else 0.0
            s = cum[j] - _int_at(cum, x, jj, phi, dt)
            if s > 0.0:
                h = _hic_value(s, window)
                if h > best:
                    best, bi, bj = h, jj + phi, j
    # sample pairs 1 <= j - i <= p: branch and bound over blocks
    pmax = min(p, n - 1)
    if pmax >= 1:
        bs = max(4, int(math.sqrt(pmax)))
        nb_ = (n + bs - 1) // bs
        for b in range(nb_):
            m = 0.0
            for k in range(b * bs, min(n, (b + 1) * bs)):
                m = max(m, x[k])
            blk[b] = m
        span = pmax // bs + 2
        npair = nb_ * span
        bound = np.full(npair, -1.0)
        for b in range(nb_):
            i0 = b * bs
            i1 = min(n, i0 + bs) - 1
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
                ub = min(_hic_value(smax, lmin * dt), lmax * dt * m * m * math.sqrt(m))
                bound[b * span + d] = ub * (1.0 + 1e-9)
                # a corner of the block as a first candidate (raises `best` early)
                jc = min(j1, i0 + pmax)
                if jc > i0:
                    s = cum[jc] - cum[i0]
                    h = _hic_value(s, (jc - i0) * dt)
                    if h > best:
                        best, bi, bj = h, i0, jc
        order = np.argsort(-bound)
        for q in order:
            if bound[q] <= best:
                break
            b = q // span
            c = b + q % span
            i0 = b * bs
            i1 = min(n, i0 + bs) - 1
            j0 = c * bs
            j1 = min(n, j0 + bs) - 1
            for i in range(i0, i1 + 1):
                ci = cum[i]
                for j in range(max(j0, i + 1), min(j1, i + pmax) + 1):
                    s = cum[j] - ci
                    if s > 0.0:
                        h = _hic_value(s, (j - i) * dt)
                        if h > best:
                            best, bi, bj = h, i, j
    if bi < 0.0:
        return 0.0, math.nan, math.nan
    return best, bi * dt, bj * dt


@_jit
def _sliding_min(x, n, p, out, dq):  # pragma: no cover - compiled
    """``out[i] = min(x[i+1 .. i+p])`` for ``i + p <= n - 1`` (``+inf`` when ``p == 0``)."""
    if p == 0:
        for i in range(n):
            out[i] = math.inf
        return
    head = 0
    tail = 0
    for k in range(1, n):
        while tail > head and x[dq[tail - 1]] >= x[k]:
            tail -= 1
        dq[tail] = k
        tail += 1
        i = k - p
        if i >= 0:
            while dq[head] < i + 1:
                head += 1
            out[i] = x[dq[head]]


@_jit
def clip_row(x, n, dt, window, mn, dq):  # pragma: no cover - compiled
    """Continuous clip: the highest level ``c`` such that the piecewise-linear curve stays ``>= c``
    over an interval of ``window`` [s] (exact for that curve). Returns ``(level, t_start)``.

    With ``t1 = (i + s) dt`` and ``window = (p + f) dt``, the minimum over ``[t1, t1 + window]`` is
    ``min(x(t1), x(t1 + window), min of the samples inside)``: on each piece of ``s`` where the
    samples inside do not change, a minimum of two linear functions and a constant, whose largest
    value is at a piece end or where two of the three are equal.
    """
    wn = window / dt
    p = int(math.floor(wn * (1.0 + 1e-12)))
    f = max(wn - p, 0.0)
    if n < 2 or p + (1 if f > 0.0 else 0) > n - 1:
        return math.nan, math.nan
    _sliding_min(x, n, p, mn, dq)
    best = -math.inf
    bt = math.nan
    for i in range(n - 1):
        if i + p + (1 if f > 0.0 else 0) > n - 1:
            break
        a0 = x[i]
        da = x[i + 1] - x[i]
        # piece 1: s in [0, 1 - f], end point in segment j = i + p at fraction s + f
        # piece 2: s in [1 - f, 1], end point in segment j = i + p + 1 at fraction s + f - 1
        for piece in range(2):
            if piece == 0:
                s0, s1, j, off = 0.0, 1.0 - f, i + p, f
                c = mn[i]
            else:
                if f == 0.0:
                    break
                s0, s1, j, off = 1.0 - f, 1.0, i + p + 1, f - 1.0
                c = min(mn[i], x[i + p + 1]) if i + p + 1 <= n - 1 else math.inf
            if j > n - 1:
                break
            b0 = x[j]
            db = (x[j + 1] - x[j]) if j + 1 <= n - 1 else 0.0
            # A(s) = a0 + da s ; B(s) = b0 + db (s + off) ; C = c
            cand_s = (s0, s1, 0.0, 0.0, 0.0)
            ncand = 2
            den = da - db
            if den != 0.0:
                sc = (b0 + db * off - a0) / den
                if s0 < sc < s1:
                    cand_s = (s0, s1, sc, 0.0, 0.0)
                    ncand = 3
            for q in range(ncand + 2):
                if q < ncand:
                    s = cand_s[q]
                elif q == ncand:  # A = C
                    if da == 0.0:
                        continue
                    s = (c - a0) / da
                else:  # B = C
                    if db == 0.0:
                        continue
                    s = (c - b0) / db - off
                if not (s0 <= s <= s1):
                    continue
                if j + 1 > n - 1 and s + off > 0.0:
                    continue
                lev = min(a0 + da * s, b0 + db * (s + off), c)
                if lev > best:
                    best = lev
                    bt = (i + s) * dt
    return best, bt


@_jit
def clip_cumulative_row(x, n, dt, window, floor, buf):  # pragma: no cover - compiled
    """Cumulative clip: the highest level ``c`` with ``measure{t : x(t) >= c} >= window`` for the
    piecewise-linear curve (exact). ``floor`` is any level known to qualify (the continuous clip),
    so only segments reaching above it are swept. ``buf`` scratch of length >= 4 n."""
    if n < 2 or (n - 1) * dt < window * (1.0 - 1e-12):
        return math.nan
    # events: (level, kind, rate): kind 0 = segment starts counting (at its top) with rate dt/(hi-lo),
    # kind 1 = stops (at its bottom), kind 2 = a flat segment adds dt at once
    ne = 0
    lev = buf[0 : 2 * n]
    rate = buf[2 * n : 4 * n]
    for k in range(n - 1):
        hi = max(x[k], x[k + 1])
        lo = min(x[k], x[k + 1])
        if hi < floor:
            continue
        if hi > lo:
            r = dt / (hi - lo)
            lev[ne] = hi
            rate[ne] = r
            ne += 1
            lev[ne] = lo
            rate[ne] = -r
            ne += 1
        else:
            lev[ne] = hi
            rate[ne] = math.inf  # flat: marker
            ne += 1
    order = np.argsort(-lev[:ne])
    meas = 0.0
    slope = 0.0
    cur = math.inf
    for q in order:
        L = lev[q]
        if slope > 0.0 and cur != math.inf:
            need = window - meas
            gain_ = slope * (cur - L)
            if gain_ >= need:
                return cur - need / slope
            meas += gain_
        cur = L
        if rate[q] == math.inf:
            meas += dt
            if meas >= window * (1.0 - 1e-12):
                return L
        else:
            slope += rate[q]
    if slope > 0.0:
        return cur - (window - meas) / slope
    return floor


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
