"""Compiled 3 ms clips of one row (one variant), called by :func:`crashstudy.metrics.criteria.compute`.

Both read samples ``x[0..n-1]`` at ``t_k = k dt`` as the piecewise-linear curve through them and
are exact for that curve; the tests hold them to their definitions on random signals.
"""

from __future__ import annotations

import math

from crashstudy.kernel.cache import cached_njit

_jit = cached_njit(nogil=True)


@_jit
def _sliding_min(x, n, p, out, h):  # pragma: no cover - compiled
    """``out[i] = min(x[i+1 .. i+p])`` for ``i + p <= n - 1`` (``+inf`` when ``p == 0``), by van
    Herk / Gil-Werman: prefix minima ``g`` (kept in ``out``) and suffix minima ``h`` within blocks of
    ``p`` samples, ``min(x[b .. b+p-1]) = min(h[b], g[b+p-1])``; no data-dependent branches."""
    if p == 0:
        for i in range(n):
            out[i] = math.inf
        return
    c = 0
    for k in range(n):
        out[k] = x[k] if c == 0 else min(out[k - 1], x[k])
        c += 1
        if c == p:
            c = 0
    c = n % p  # samples in the last (partial) block: k + 1 is a multiple of p every p from there
    for k in range(n - 1, -1, -1):
        h[k] = x[k] if (k == n - 1 or c == 0) else min(h[k + 1], x[k])
        c = (c - 1) if c > 0 else p - 1
    for i in range(n - p):
        out[i] = min(h[i + 1], out[i + p])


@_jit
def clip_row(x, n, dt, window, mn, h):  # pragma: no cover - compiled
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
    q = p + (1 if f > 0.0 else 0)
    # a first level from the windows [t_i, t_i+q] around the largest sample (they contain
    # [t_i, t_i + window], so their minimum is attained)
    kp = 0
    for k in range(1, n):
        if x[k] > x[kp]:
            kp = k
    i0 = max(0, kp - q)
    i1 = min(kp, n - 1 - q)
    best = -math.inf
    bt = math.nan
    if i1 >= i0:
        _sliding_min(x[i0:], min(n, i1 + q + 1) - i0, q, mn, h)  # mn[i - i0] = min x[i+1 .. i+q]
        for i in range(i0, i1 + 1):
            lev = min(x[i], mn[i - i0])
            if lev > best:
                best = lev
                bt = i * dt
    # only windows starting on a segment that reaches above that level can beat it
    lo_i = n
    hi_i = -1
    for i in range(n - 1 - q + 1):
        if max(x[i], x[i + 1]) > best:
            lo_i = min(lo_i, i)
            hi_i = i
    if hi_i < lo_i:
        return best, bt
    _sliding_min(x[lo_i:], min(n, hi_i + p + 2) - lo_i, p, mn, h)  # mn[i - lo_i] = min x[i+1 .. i+p]
    for i in range(lo_i, hi_i + 1):
        if i + p + (1 if f > 0.0 else 0) > n - 1:
            break
        mi = mn[i - lo_i]
        if min(max(x[i], x[i + 1]), mi) <= best:
            continue  # no window starting on this segment can beat the best
        a0 = x[i]
        da = x[i + 1] - x[i]
        # piece 1: s in [0, 1 - f], end point in segment j = i + p at fraction s + f
        # piece 2: s in [1 - f, 1], end point in segment j = i + p + 1 at fraction s + f - 1
        for piece in range(2):
            if piece == 0:
                s0, s1, j, off = 0.0, 1.0 - f, i + p, f
                c = mi
            else:
                if f == 0.0:
                    break
                s0, s1, j, off = 1.0 - f, 1.0, i + p + 1, f - 1.0
                c = min(mi, x[i + p + 1]) if i + p + 1 <= n - 1 else math.inf
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
def clip_cumulative_row(x, n, dt, window, floor, lo, hi):  # pragma: no cover - compiled
    """Cumulative clip: the highest level ``c`` with ``measure{t : x(t) >= c} >= window`` for the
    piecewise-linear curve (exact). ``floor`` is any level known to qualify (the continuous clip),
    so only segments reaching it count. ``lo``, ``hi`` scratch of length >= n.

    ``measure(c)`` is a sum over segments, each ``dt`` above its top, 0 below its bottom and linear
    between: piecewise linear in ``c`` with breaks at sample values. A bracket ``[cl, ch]`` with
    ``measure(cl) >= window > measure(ch)`` is narrowed at the median break inside it (segments
    entirely above the bracket count ``dt``, those below drop out) until no break is left inside;
    then ``measure`` is linear on the bracket and is solved.
    """
    if n < 2 or (n - 1) * dt < window * (1.0 - 1e-12):
        return math.nan
    m = 0
    for k in range(n - 1):
        h = max(x[k], x[k + 1])
        if h >= floor:
            lo[m] = min(x[k], x[k + 1])
            hi[m] = h
            m += 1
    cl = floor
    ch = math.inf
    fixed = 0.0
    target = window * (1.0 - 1e-12)
    while m > 0:
        cnt = 0
        for q in range(m):
            cnt += (cl < lo[q] < ch) + (cl < hi[q] < ch)
        if cnt == 0:
            break
        pick = cnt // 2
        piv = math.nan
        for q in range(m):
            for e in (lo[q], hi[q]):
                if cl < e < ch:
                    if pick == 0:
                        piv = e
                    pick -= 1
            if piv == piv:
                break
        meas = fixed
        for q in range(m):
            if lo[q] >= piv:
                meas += dt
            elif hi[q] > piv:
                meas += dt * (hi[q] - piv) / (hi[q] - lo[q])
        if meas >= target:
            cl = piv
        else:
            ch = piv
        w = 0
        for q in range(m):
            if lo[q] >= ch:
                fixed += dt
            elif hi[q] > cl:
                lo[w] = lo[q]
                hi[w] = hi[q]
                w += 1
        m = w
    # no break inside (cl, ch): measure(c) = fixed + sum dt (hi - c) / (hi - lo) there
    a = fixed
    b = 0.0
    for q in range(m):
        if lo[q] >= ch:
            a += dt
        elif hi[q] > cl and hi[q] > lo[q]:
            r = dt / (hi[q] - lo[q])
            a += r * hi[q]
            b += r
    if b <= 0.0:
        return cl
    c = (a - window) / b
    return min(max(c, cl), ch)
