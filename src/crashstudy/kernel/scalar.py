"""Compiled scalar helpers of the numba kernel (one variant at a time): time curves, curve inverses,
the rare ``general_nonlinear`` reversal (rule 4) and the knot peak test. They follow
:mod:`crashstudy.kernel.materials` (and :func:`crashstudy.kernel.reference.knot_peak_np`).
"""

from __future__ import annotations

import numba as nb
import numpy as np

_jit = nb.njit(cache=True, nogil=True, inline="always")


@_jit
def knot_peak(cand, e_lo, e_hi, xk, yk):  # pragma: no cover - compiled
    """Peak-force candidate of one curve knot, scalars only (inlined into the variant loop).

    ``cand`` the candidate so far [force, >= 0]; ``(e_lo, e_hi)`` the part of the elongation path
    between two steps on which the spring follows the curve elastically, in the curve's own
    abscissa (for a shifted ``general_nonlinear`` loading curve: elongation - shift) [length];
    ``xk``, ``yk`` the knot [length], [force] (``Batch.knot_y``: 0 where the knot is not a local
    maximum of |curve|; a crush spring passes ``min(0, yk)``). Returns ``max(cand, |yk|)`` when
    ``e_lo < xk < e_hi``, else ``cand``. Exact (a compare and a select): the NumPy twin is
    :func:`crashstudy.kernel.reference.knot_peak_np`; a returned value > ``cand`` means this knot
    is the new candidate.
    """
    ak = abs(yk)
    return ak if ((xk > e_lo) & (xk < e_hi) & (ak > cand)) else cand


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
def reverse_yield(e, st, w, ca, cb, yt, yc, v, cx, cy, cds, cs0, cs1, off):  # pragma: no cover - compiled
    """Rule 4 (docs/format.md) for one lane whose unloading branch reached the other direction's yield force.

    ``st[:, w]`` holds the state before this step (a reversing lane is on its unloading line, so the
    vectorised step left it unchanged). Returns the force; updates the state.
    """
    mode = st[0, w]
    et = st[1, w]
    ft = st[2, w]
    ec = st[3, w]
    fc = st[4, w]
    thr_t = ft if st[6, w] > 0 else yt
    thr_c = fc if st[7, w] > 0 else yc
    if mode > 0:  # tension unloading reached compression
        cross = et + unloading_inverse(cb, thr_c - ft, v, cx, cy, cs0, cs1, off)
        shift = cross - curve_inverse(ca, thr_c, -1.0, v, cx, cy, cds, cs0, cs1, off)
        Ls = curve_at(ca, e - shift, v, cx, cy, cds, cs0, off)
        st[3, w] = e
        st[4, w] = Ls
        st[0, w] = -1.0
        st[7, w] = 1.0
    else:  # compression unloading reached tension
        cross = ec + unloading_inverse(cb, thr_t - fc, v, cx, cy, cs0, cs1, off)
        shift = cross - curve_inverse(ca, thr_t, 1.0, v, cx, cy, cds, cs0, cs1, off)
        Ls = curve_at(ca, e - shift, v, cx, cy, cds, cs0, off)
        st[1, w] = e
        st[2, w] = Ls
        st[0, w] = 1.0
        st[6, w] = 1.0
    st[5, w] = shift
    return Ls


_ = np  # numpy is used by numba typing of the arrays passed in
