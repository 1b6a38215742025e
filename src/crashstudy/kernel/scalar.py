"""Compiled scalar helpers of the numba kernel (one variant at a time): curve inverses and the
``general_nonlinear`` state machine. They follow :mod:`crashstudy.kernel.materials` line by line.
"""

from __future__ import annotations

import numba as nb
import numpy as np

_jit = nb.njit(cache=True, nogil=True, inline="always")


@_jit
def curve_at(c, e, v, cx, cy, cds, cs0, off):  # pragma: no cover - compiled
    """Curve ``c`` of variant column ``v`` at elongation ``e`` (ramp sum, linear extrapolation)."""
    a = off[c]
    b = off[c + 1]
    y = cy[a, v] + cs0[c, v] * (e - cx[a, v])
    for k in range(a + 1, b - 1):
        y = y + cds[k, v] * max(0.0, e - cx[k, v])
    return y


@_jit
def time_curve_at(c, t, v, cx, cy, cds, cs0, off):  # pragma: no cover - compiled
    a = off[c]
    b = off[c + 1]
    eps = 1e-9 * (cx[b - 1, v] - cx[a, v])  # materials.TIME_EPS
    if t < cx[a, v] - eps or t > cx[b - 1, v] + eps:
        return 0.0
    return curve_at(c, t, v, cx, cy, cds, cs0, off)


@_jit
def curve_inverse(c, f, direction, v, cx, cy, cds, cs0, cs1, off):  # pragma: no cover - compiled
    a = off[c]
    b = off[c + 1]
    n = b - a
    prev_x = 0.0
    prev_y = curve_at(c, 0.0, v, cx, cy, cds, cs0, off)
    for q in range(n):
        k = a + q if direction > 0 else b - 1 - q
        if cx[k, v] * direction > 0:
            lo = min(prev_y, cy[k, v])
            hi = max(prev_y, cy[k, v])
            if hi > lo and f >= lo and f <= hi:
                return prev_x + (f - prev_y) / (cy[k, v] - prev_y) * (cx[k, v] - prev_x)
            prev_x = cx[k, v]
            prev_y = cy[k, v]
    slope = cs1[c, v] if direction > 0 else cs0[c, v]
    if slope != 0.0:
        ext = (f - prev_y) / slope
        if ext * direction >= 0:
            return prev_x + ext
    return prev_x


@_jit
def unloading_inverse(c, f, v, cx, cy, cs0, cs1, off):  # pragma: no cover - compiled
    a = off[c]
    b = off[c + 1]
    if f <= cy[a, v]:
        out = cx[a, v] + (f - cy[a, v]) / cs0[c, v]
    else:
        out = cx[b - 1, v] + (f - cy[b - 1, v]) / cs1[c, v]
    for k in range(a, b - 1):
        if f > cy[k, v] and f <= cy[k + 1, v]:
            out = cx[k, v] + (f - cy[k, v]) / (cy[k + 1, v] - cy[k, v]) * (cx[k + 1, v] - cx[k, v])
    return out


@_jit
def general_nonlinear(e, st, w, ca, cb, yt, yc, v, cx, cy, cds, cs0, cs1, off):  # pragma: no cover - compiled
    """Force of a general_nonlinear spring; ``st[:, w]`` is this variant's state (see materials.py)."""
    mode = st[0, w]
    et = st[1, w]
    ft = st[2, w]
    ec = st[3, w]
    fc = st[4, w]
    shift = st[5, w]
    yld_t = st[6, w]
    yld_c = st[7, w]
    L = curve_at(ca, e - shift, v, cx, cy, cds, cs0, off)
    thr_t = ft if yld_t > 0 else yt
    thr_c = fc if yld_c > 0 else yc
    F = 0.0
    to_t = False
    to_c = False
    rev_t = False
    rev_c = False
    if mode == 0:
        F = L
        to_t = L >= yt
        to_c = L <= yc
    elif mode > 0:
        if e >= et:
            F = L
            et = e
            ft = L
        else:
            F = ft + curve_at(cb, e - et, v, cx, cy, cds, cs0, off)
            rev_c = F <= thr_c
    else:
        if e <= ec:
            F = L
            ec = e
            fc = L
        else:
            F = fc + curve_at(cb, e - ec, v, cx, cy, cds, cs0, off)
            rev_t = F >= thr_t
    if rev_c:
        cross = et + unloading_inverse(cb, thr_c - ft, v, cx, cy, cs0, cs1, off)
        shift = cross - curve_inverse(ca, thr_c, -1.0, v, cx, cy, cds, cs0, cs1, off)
    if rev_t:
        cross = ec + unloading_inverse(cb, thr_t - fc, v, cx, cy, cs0, cs1, off)
        shift = cross - curve_inverse(ca, thr_t, 1.0, v, cx, cy, cds, cs0, cs1, off)
    if rev_c or rev_t:
        Ls = curve_at(ca, e - shift, v, cx, cy, cds, cs0, off)
        F = Ls
        if rev_c:
            ec = e
            fc = Ls
        else:
            et = e
            ft = Ls
    if to_t:
        et = e
        ft = L
    if to_c:
        ec = e
        fc = L
    if to_t or rev_t:
        mode = 1.0
        yld_t = 1.0
    elif to_c or rev_c:
        mode = -1.0
        yld_c = 1.0
    st[0, w] = mode
    st[1, w] = et
    st[2, w] = ft
    st[3, w] = ec
    st[4, w] = fc
    st[5, w] = shift
    st[6, w] = yld_t
    st[7, w] = yld_c
    return F


_ = np  # numpy is used by numba typing of the arrays passed in
