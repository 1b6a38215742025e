"""The SAE J211-1 Appendix C channel filter, batched over variants that each have their own step.

J211-1 (March 1995, Appendix C) defines the CFC filter as a 2-pole Butterworth low-pass run forward
and then backward over the record (a 4-pole, phaseless filter). For a sample interval ``T`` [s]
and channel class ``CFC`` [Hz]::

    wd = 2 pi CFC 2.0775            wa = sin(wd T / 2) / cos(wd T / 2)
    a0 = wa^2 / (1 + sqrt(2) wa + wa^2)          a1 = 2 a0          a2 = a0
    b1 = -2 (wa^2 - 1) / (1 + sqrt(2) wa + wa^2)
    b2 = (-1 + sqrt(2) wa - wa^2) / (1 + sqrt(2) wa + wa^2)
    Y[t] = a0 X[t] + a1 X[t-1] + a2 X[t-2] + b1 Y[t-1] + b2 Y[t-2]

(``scipy.signal.lfilter(b=[a0, a1, a2], a=[1, -b1, -b2])`` is one pass). The pair has gain
``1 / (1 + (tan(pi f T) / wa)^4)`` exactly, -3 dB near ``1.65 CFC`` (the J211 ``F_N``), unit gain
at 0 Hz. The coefficients depend on ``T``, so each variant gets its own; scipy's ``lfilter`` takes
one coefficient set per call, hence the numba loop here (tests hold it equal to ``lfilter`` row by
row).

Start and end of the record (``pad``): the recursion needs input before the first and after the
last sample. ``"constant"`` (default) continues the record by its first value before it and its
last value after it, for ever: the forward pass starts in the steady state of the first value,
and the forward response to the constant tail, a decaying oscillation at the filter's pole, is
summed in closed form into the backward pass's starting state (exactly what an infinitely long
constant pad gives, at no cost). ``"zero"`` does the same with zero acceleration before and after
the record (a node at rest or in free flight outside the record). ``"reflect"`` is scipy's
``filtfilt(padtype="odd")``: point-reflected copies of ``pad_length`` samples at each end (at most
``count - 1``), the passes starting in the steady state of the pad's first value. See
docs/criteria.md for the effect on a pulse that starts at ``t = 0``.

Sample rate: post-processors implementing J211-1 ask for at least 10 CFC (about 6 times the
-3 dB frequency; docs/criteria.md). Below it :func:`rate_too_low` is true (the criteria say so in their note); below
``4.155 CFC`` (``wd T / 2 >= pi / 2``) the design is undefined and the row is left unfiltered.
"""

from __future__ import annotations

import math

import numpy as np

from crashstudy.kernel.cache import cached_njit

from .interpreted import driver_for

CFC_CLASSES = (60, 180, 600, 1000)
PADS = ("constant", "zero", "reflect")
J211_FACTOR = 2.0775
MIN_RATE_PER_CFC = 10.0  # samples per second per hertz of channel class (J211 post-processors' rule)

_jit = cached_njit(nogil=True)


@_jit
def coefficients(
    dt_s: float, cfc: float
) -> tuple[float, float, float, float, float, bool]:  # pragma: no cover
    """J211-1 Appendix C coefficients ``(a0, a1, a2, b1, b2, defined)`` for step ``dt_s`` [s].

    ``defined`` is False when ``wd dt / 2 >= pi / 2`` (sample rate below ``4.155 CFC``); then the
    coefficients of the identity ``(1, 0, 0, 0, 0)`` are returned.
    """
    half = 2.0 * math.pi * cfc * J211_FACTOR * dt_s / 2.0
    if not (half > 0.0) or half >= 0.5 * math.pi * (1.0 - 1e-9):
        return 1.0, 0.0, 0.0, 0.0, 0.0, False
    wa = math.sin(half) / math.cos(half)
    s2 = math.sqrt(2.0)
    den = 1.0 + s2 * wa + wa * wa
    a0 = wa * wa / den
    b1 = -2.0 * (wa * wa - 1.0) / den
    b2 = (-1.0 + s2 * wa - wa * wa) / den
    return a0, 2.0 * a0, a0, b1, b2, True


@_jit
def decay_length(b2: float, tol: float) -> int:  # pragma: no cover - compiled
    """Samples after which the filter's free response has shrunk below ``tol`` (pole radius ``sqrt(-b2)``)."""
    r = math.sqrt(max(-b2, 1e-300))
    if r <= 0.0 or r >= 1.0:
        return 1
    return int(math.ceil(math.log(tol) / math.log(r))) + 2


@_jit
def _tail_state(y1, y0, c, a0, a1, a2, b1, b2):  # pragma: no cover - compiled
    """Backward-pass outputs ``(z_N, z_N+1)`` for forward outputs ``y_N = y0``, ``y_N+1 = y1`` whose
    input is the constant ``c`` from step N on: the forward tail is ``c + 2 Re(alpha lam^k)``
    (``lam`` the pole), and the backward pass run from infinity over it is
    ``c + 2 Re(alpha H lam^k)``, ``H = (a0 + a1 lam + a2 lam^2) / (1 - b1 lam - b2 lam^2)``."""
    re = 0.5 * b1
    im = math.sqrt(max(-b2 - re * re, 0.0))
    e0 = y0 - c
    e1 = y1 - c
    ar = 0.5 * e0
    ai = (ar * re - 0.5 * e1) / im if im > 0.0 else 0.0
    lam = complex(re, im)
    h = (a0 + a1 * lam + a2 * lam * lam) / (1.0 - b1 * lam - b2 * lam * lam)
    beta = complex(ar, ai) * h
    w0 = 2.0 * beta.real
    w1 = 2.0 * (beta * lam).real
    return c + w0, c + w1


@_jit
def _pass(src, dst, n, backward, x1, x2, y1, y2, a0, a1, a2, b1, b2):  # pragma: no cover - compiled
    """One pass of ``y = a0 x + a1 x' + a2 x'' + b1 y' + b2 y''`` over ``src[:n]`` into ``dst``, in
    index order or (``backward``) reverse order, from the previous inputs ``x1, x2`` and outputs
    ``y1, y2``. After two plain steps it runs the same filter with its denominator multiplied by
    ``1 + b1 q - b2 q^2`` (``q`` the delay): ``y_k = c2 y_k-2 - c4 y_k-4 + w_k``, poles ``+-lam``
    (as stable as the filter's own), so that the even and odd samples form two independent chains
    and the loop is not bound by one multiply-add per sample."""
    c2 = 2.0 * b2 + b1 * b1
    c4 = b2 * b2
    # v_k = a0 x_k + a1 x_k-1 + a2 x_k-2 ; w_k = v_k + b1 v_k-1 - b2 v_k-2
    v1 = a0 * x1 + a1 * x2 + a2 * x2  # v at k-1 (x before that taken as x2: steady or irrelevant)
    v2 = v1
    ym1 = y1  # y_k-1
    ym2 = y2  # y_k-2
    ym3 = y2
    ym4 = y2
    # far oversampled (wa < ~1e-4, a0 < 1e-8) the pair's recursion loses digits faster than the
    # plain one (error ~ eps / wa^2: 4e-8 at CFC 60 and 10 MHz): plain steps throughout there
    start = min(n, 2) if a0 >= 1e-8 else n
    for k in range(start):
        i = n - 1 - k if backward else k
        xk = src[i]
        vk = a0 * xk + a1 * x1 + a2 * x2
        yk = vk + b1 * ym1 + b2 * ym2
        dst[i] = yk
        x2 = x1
        x1 = xk
        v2 = v1
        v1 = vk
        ym4 = ym3
        ym3 = ym2
        ym2 = ym1
        ym1 = yk
    for k in range(start, n):
        i = n - 1 - k if backward else k
        xk = src[i]
        vk = a0 * xk + a1 * x1 + a2 * x2
        wk = vk + b1 * v1 - b2 * v2
        yk = (wk - c4 * ym4) + c2 * ym2
        dst[i] = yk
        x2 = x1
        x1 = xk
        v2 = v1
        v1 = vk
        ym4 = ym3
        ym3 = ym2
        ym2 = ym1
        ym1 = yk


@_jit
def filter_row(x, n, a0, a1, a2, b1, b2, pad, pad_length, out, work):  # pragma: no cover - compiled
    """Forward-backward J211 filter of ``x[:n]`` into ``out[:n]``; ``pad`` 0 constant, 1 zero, 2 reflect.

    ``work`` is scratch of length >= ``n + 2 pad_length + 2``. ``out`` may be ``x``.
    """
    if n == 0:
        return
    if n == 1:
        out[0] = x[0]  # a lone sample is left as it is
        return
    if pad == 2:
        m = min(pad_length, n - 1)
        ln = n + 2 * m
        for k in range(m):
            work[k] = 2.0 * x[0] - x[m - k]
            work[m + n + k] = 2.0 * x[n - 1] - x[n - 2 - k]
        for k in range(n):
            work[m + k] = x[k]
        x1 = work[0]
        x2 = x1
        y1 = x1
        y2 = x1
        for k in range(ln):
            xk = work[k]
            yk = a0 * xk + a1 * x1 + a2 * x2 + b1 * y1 + b2 * y2
            x2 = x1
            x1 = xk
            y2 = y1
            y1 = yk
            work[k] = yk
        u1 = work[ln - 1]
        u2 = u1
        z1 = u1
        z2 = u1
        for k in range(ln - 1, -1, -1):
            uk = work[k]
            zk = a0 * uk + a1 * u1 + a2 * u2 + b1 * z1 + b2 * z2
            u2 = u1
            u1 = uk
            z2 = z1
            z1 = zk
            if m <= k < m + n:
                out[k - m] = zk
        return
    pre = x[0] if pad == 0 else 0.0
    post = x[n - 1] if pad == 0 else 0.0
    _pass(x, work, n, False, pre, pre, pre, pre, a0, a1, a2, b1, b2)
    # two more forward steps into the constant tail, then the tail in closed form
    yn = a0 * post + a1 * x[n - 1] + a2 * x[n - 2] + b1 * work[n - 1] + b2 * work[n - 2]
    yn1 = a0 * post + a1 * post + a2 * x[n - 1] + b1 * yn + b2 * work[n - 1]
    zn, zn1 = _tail_state(yn1, yn, post, a0, a1, a2, b1, b2)
    _pass(work, out, n, True, yn, yn1, zn, zn1, a0, a1, a2, b1, b2)


@_jit
def _filter_batch(a, count, dt_s, cfc, pad, pad_tol, out):  # pragma: no cover - compiled
    nv, nt = a.shape
    ok = np.ones(nv, dtype=np.bool_)
    for v in range(nv):
        n = count[v]
        a0, a1, a2, b1, b2, defined = coefficients(dt_s[v], cfc)
        ok[v] = defined
        m = min(decay_length(b2, pad_tol), max(n - 1, 0)) if pad == 2 else 0
        work = np.empty(n + 2 * m + 2)
        if defined:
            filter_row(a[v], n, a0, a1, a2, b1, b2, pad, m, out[v], work)
        else:
            # a loop, not out[v, :n] = a[v, :n]: numba compiles a slice copy's error message (~5 s)
            for k in range(n):
                out[v, k] = a[v, k]
        out[v, n:] = np.nan
    return ok


def pad_code(pad: str) -> int:
    if pad not in PADS:
        raise ValueError(f"pad must be one of {PADS}, got {pad!r}")
    return PADS.index(pad)


def j211_filter(
    a: np.ndarray,
    count: np.ndarray,
    dt: np.ndarray,
    cfc: int,
    *,
    second: float = 1.0,
    pad: str = "constant",
    pad_tol: float = 1e-12,
) -> np.ndarray:
    """SAE J211-1 Appendix C CFC filter of each row, each with its own step.

    Parameters
    ----------
    a : (V, T) float64, the samples at ``t_n = n dt[v]``, ``n < count[v]`` (the rest is ignored).
    count : (V,) int, samples per row.
    dt : (V,) float, the step of each row [model time].
    cfc : channel frequency class [Hz], 60 | 180 | 600 | 1000 (any positive value is computed).
    second : model time units in one second (1 for s, 1000 for ms).
    pad : ``"constant"`` | ``"zero"`` | ``"reflect"``: the record's continuation before and after
        (module docstring).
    pad_tol : for ``"reflect"``, the pad is as long as the free response needs to fall below this.

    Returns
    -------
    (V, T) float64: filtered rows, NaN past ``count[v]``. Rows whose sample rate is below
    ``4.155 CFC`` are returned unfiltered (see :func:`rate_too_low`).
    """
    a = np.ascontiguousarray(a, dtype=np.float64)
    if a.ndim != 2:
        raise ValueError("a must be (V, T)")
    count = np.minimum(np.asarray(count, dtype=np.int64), a.shape[1])
    dt_s = np.asarray(dt, dtype=np.float64) / float(second)
    out = np.empty_like(a)
    run, _ = driver_for(_filter_batch, int(np.sum(count)))  # a small record on a fresh machine: no compile
    run(a, count, dt_s, float(cfc), pad_code(pad), float(pad_tol), out)
    return out


def rate_too_low(dt: np.ndarray, cfc: float, second: float = 1.0) -> np.ndarray:
    """True where the sample rate ``second / dt`` is below ``10 CFC`` (the J211 post-processors' rule)."""
    return np.asarray(second / np.asarray(dt, dtype=np.float64)) < MIN_RATE_PER_CFC * cfc


def gain(f: np.ndarray, dt_s: float, cfc: float) -> np.ndarray:
    """Exact gain of the forward-backward pair at frequency ``f`` [Hz]: ``1 / (1 + (tan(pi f T)/wa)^4)``."""
    wa = math.tan(math.pi * cfc * J211_FACTOR * dt_s)
    return 1.0 / (1.0 + (np.tan(np.pi * np.asarray(f) * dt_s) / wa) ** 4)
