"""Crash criteria of a node's acceleration, batched over variants (each with its own time step).

:func:`compute` takes the acceleration ``a^n`` of one node at every step ``t_n = n dt`` of every
variant (the central-difference kernel's ``a^n``) and returns, per variant, the criteria of SPEC
section 6b (user documentation: docs/criteria.md):

- ``peak_g``: peak of the CFC-filtered resultant [g] (the parabola through the largest sample and
  its neighbours, so that it converges as O(dt^3) at a smooth peak, not with the samples' phase);
- ``hic15`` / ``hic36`` with ``*_t1``/``*_t2`` [s]: head injury criterion (FMVSS 208 / J885) of the
  filtered resultant over windows up to 15 / 36 ms;
- ``clip3ms``: highest level the filtered resultant stays at or above for a continuous 3 ms;
  ``clip3ms_cumulative``: highest level exceeded for a cumulative 3 ms (FMVSS 208) [g];
- ``olc``: Euro NCAP occupant load criterion (TB 027) of the filtered velocity along ``direction``
  [g];
- ``dri``: dynamic response index (seat/spine model, ``omega = 52.9 rad/s``, ``zeta = 0.224``) of
  the unfiltered deceleration along ``direction`` [-];
- ``delta_v``: largest change of the velocity along ``direction`` from its initial value
  [velocity].

Velocity: the kernel's half-step velocities are ``v^{n+1/2} = v^{n-1/2} + dt a^n`` with a half step
at ``n = 0``, so ``v(t_n) = (v^{n-1/2} + v^{n+1/2}) / 2 = v0 + trapezoid integral of a``: the
velocity at the full steps, on the same time grid as the acceleration and its filtered copy. OLC
and ``delta_v`` use it (OLC from the filtered acceleration, ``delta_v`` from the raw one).

Deceleration is positive: along ``direction`` it is ``-a . direction``. Resultants are
``|a|``. All signals are read as the piecewise-linear curve through the samples; each criterion is
exact for that curve (see :mod:`crashstudy.metrics.criteria_rows`, :mod:`crashstudy.metrics.criteria_clips`), so
they converge as ``dt`` is halved.

Developers: numba's on-disk cache of the compiled driver checks only this file's time stamp, not
those of :mod:`crashstudy.metrics.criteria_rows`, :mod:`crashstudy.metrics.criteria_clips` and
:mod:`crashstudy.metrics.criteria_filter` whose functions it
compiles in; after editing those, touch this file (or clear ``NUMBA_CACHE_DIR``).
"""

from __future__ import annotations

from collections.abc import Iterable
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from crashstudy.kernel.cache import cached_njit
from crashstudy.kernel.driver import get_threads

from .criteria_clips import clip_cumulative_row, clip_row
from .criteria_filter import (
    CFC_CLASSES,
    coefficients,
    decay_length,
    filter_row,
    j211_filter,
    pad_code,
    rate_too_low,
)
from .criteria_rows import NOT_REACHED, dri_row, hic_row, olc_row, peak_row
from .interpreted import driver_for

__all__ = ["CRITERIA", "EXTRA", "STANDARDS", "UNITS", "compute", "j211_filter", "dri_matrices"]

CRITERIA = ("peak_g", "hic15", "hic36", "clip3ms", "clip3ms_cumulative", "olc", "dri", "delta_v")
EXTRA = {"hic15": ("hic15_t1", "hic15_t2"), "hic36": ("hic36_t1", "hic36_t2")}

STANDARDS = {
    "peak_g": "SAE J211-1 Appendix C CFC filter, peak of the resultant",
    "hic15": "FMVSS 208 (49 CFR 571.208 S6.2) HIC15, SAE J885",
    "hic36": "FMVSS 208 (49 CFR 571.208) HIC36, SAE J885",
    "clip3ms": "3 ms clip, continuous interval (SAE J211-1 filtered resultant)",
    "clip3ms_cumulative": "FMVSS 208 (49 CFR 571.208 S6.3) chest acceleration, cumulative 3 ms",
    "olc": "Euro NCAP TB 027 occupant load criterion (65 mm free flight + 235 mm)",
    "dri": "Dynamic response index, AGARD-AR-330 / MIL-S-9479 (omega 52.9 rad/s, zeta 0.224)",
    "delta_v": "largest velocity change along the direction",
}
UNITS = {
    "peak_g": "g",
    "hic15": "1",
    "hic36": "1",
    "hic15_t1": "s",
    "hic15_t2": "s",
    "hic36_t1": "s",
    "hic36_t2": "s",
    "clip3ms": "g",
    "clip3ms_cumulative": "g",
    "olc": "g",
    "dri": "1",
    "delta_v": "velocity",
}

DRI_OMEGA = 52.9  # rad/s
DRI_ZETA = 0.224
HIC_WINDOWS = {"hic15": 0.015, "hic36": 0.036}  # s
CLIP_WINDOW = 0.003  # s
OLC_FREE = 0.065  # m
OLC_RESTRAINED = 0.235  # m
MIN_PART = 256  # variants: fewer run on one thread

_COLS = (
    "peak_g",
    "hic15",
    "hic15_t1",
    "hic15_t2",
    "hic36",
    "hic36_t1",
    "hic36_t2",
    "clip3ms",
    "clip3ms_cumulative",
    "olc",
    "dri",
    "delta_v",
)
# status bits of a variant (the note)
_NO_FILTER, _LOW_RATE, _OLC_FREE, _OLC_END, _SHORT_CLIP, _SHORT, _NOT_FINITE = 1, 2, 4, 8, 16, 32, 64
_NOTES = {
    _NO_FILTER: "sample rate below 4.155 x CFC: the J211 filter is undefined, criteria use the raw signal",
    _LOW_RATE: "sample rate below 10 x CFC (SAE J211-1): the filtered pulse depends on the step",
    _OLC_FREE: "olc: the occupant's 65 mm free flight does not end within the record",
    _OLC_END: "olc: the occupant does not reach the node's velocity within the record",
    _SHORT_CLIP: "clip3ms: the record is shorter than 3 ms",
    _SHORT: "fewer than 2 samples",
    _NOT_FINITE: "the acceleration is not finite (NaN or inf) within the record",
}


def dri_matrices(
    dt_s: np.ndarray, omega: float = DRI_OMEGA, zeta: float = DRI_ZETA
) -> tuple[np.ndarray, ...]:
    """Exact one-step matrices of ``x'' + 2 zeta omega x' + omega^2 x = d`` for ``d`` linear over the step.

    Returns ``(Phi (V, 2, 2), G0 (V, 2), Gs (V, 2))`` with ``z+ = Phi z + G0 d_k + Gs (d_k+1 - d_k)``,
    ``z = (x, x')``, ``h = dt_s`` [s]: ``Phi = exp(A h)``, ``G0 = A^-1 (Phi - I) B`` (the response to a
    constant input), ``Gs = A^-1 (G0 / h - B)`` (to an input rising from 0 to 1 over the step), in
    closed form for the underdamped system (``zeta < 1``), by their series when ``omega h < 0.1``. The tests hold them equal to the
    exponential of ``[[A h, B h, 0], [0, 0, 1], [0, 0, 0]]``.
    """
    h = np.asarray(dt_s, dtype=np.float64)
    sig = zeta * omega
    wd = omega * np.sqrt(1.0 - zeta * zeta)
    e = np.exp(-sig * h)
    c = np.cos(wd * h)
    s = np.sin(wd * h)
    phi = np.empty(h.shape + (2, 2))
    phi[..., 0, 0] = e * (c + sig / wd * s)
    phi[..., 0, 1] = e * s / wd
    phi[..., 1, 0] = -omega * omega * e * s / wd
    phi[..., 1, 1] = e * (c - sig / wd * s)
    g0 = np.empty(h.shape + (2,))
    g0[..., 0] = (1.0 - phi[..., 1, 1] - 2.0 * sig * phi[..., 0, 1]) / (omega * omega)
    g0[..., 1] = phi[..., 0, 1]
    gs = np.empty(h.shape + (2,))
    gs[..., 0] = (1.0 - g0[..., 1] / h - 2.0 * sig * g0[..., 0] / h) / (omega * omega)
    gs[..., 1] = g0[..., 0] / h
    # short steps: the closed forms cancel (relative error ~ 1e-16 / (omega h)^2); sum the series
    # G0 = sum A^k B h^(k+1) / (k+1)!, Gs = sum A^k B h^(k+1) / (k+2)! instead (terms fall as omega h)
    small = omega * h < 0.1
    if np.any(small):
        hs = h[small]
        w = np.zeros(hs.shape + (2,))
        w[..., 1] = 1.0
        s0 = np.zeros_like(w)
        s1 = np.zeros_like(w)
        f0 = hs.copy()  # h^(k+1) / (k+1)!
        f1 = hs / 2.0  # h^(k+1) / (k+2)!
        for k in range(30):
            s0 += w * f0[..., None]
            s1 += w * f1[..., None]
            w = np.stack([w[..., 1], -omega * omega * w[..., 0] - 2.0 * sig * w[..., 1]], axis=-1)
            f0 = f0 * hs / (k + 2)
            f1 = f1 * hs / (k + 3)
        g0[small] = s0
        gs[small] = s1
    return phi, g0, gs


@cached_njit(nogil=True)
def _driver(
    acc, count, dt, dt_s, u0, dirs, cfc, pad, g, want, s_free, s_rest, phi, g0, gs, out, status
):  # pragma: no cover
    nv, nt, nd = acc.shape
    xin = np.empty(nt)
    fc = np.empty((nd, nt))
    work = np.empty(3 * nt + 4)
    res = np.empty(nt)
    dfil = np.empty(nt)
    draw = np.empty(nt)
    u = np.empty(nt)
    cum = np.empty(nt + 1)
    blk = np.empty(nt + 1)
    mn = np.empty(nt)
    hmin = np.empty(nt)
    lo = np.empty(nt)
    hi = np.empty(nt)
    need_res = want[0] or want[1] or want[2] or want[3] or want[4]
    need_filter = need_res or want[5]
    for v in range(nv):
        n = count[v]
        if n < 2:
            status[v] |= 32
            continue
        finite = True
        for k in range(n):
            for d in range(nd):
                if not np.isfinite(acc[v, k, d]):
                    finite = False
        if not finite:
            status[v] |= 64
            continue
        h = dt_s[v]
        a0, a1, a2, b1, b2, defined = coefficients(h, cfc)
        if need_filter and not defined:
            status[v] |= 1
        m = min(decay_length(b2, 1e-12), n - 1) if pad == 2 else 0
        if need_filter:
            for d in range(nd):
                for k in range(n):
                    xin[k] = acc[v, k, d]
                if defined:
                    filter_row(xin, n, a0, a1, a2, b1, b2, pad, m, fc[d], work)
                else:
                    for k in range(n):  # not a slice copy (numba compiles its error message, ~5 s)
                        fc[d, k] = xin[k]
        if need_res:
            ig = 1.0 / g
            if nd == 1:
                for k in range(n):
                    res[k] = abs(fc[0, k]) * ig
            else:
                for k in range(n):
                    r = 0.0
                    for d in range(nd):
                        r += fc[d, k] * fc[d, k]
                    res[k] = np.sqrt(r) * ig
        if want[5]:
            for k in range(n):
                sf = 0.0
                for d in range(nd):
                    sf -= fc[d, k] * dirs[v, d]
                dfil[k] = sf
        if want[6] or want[7]:
            for k in range(n):
                sr = 0.0
                for d in range(nd):
                    sr -= acc[v, k, d] * dirs[v, d]
                draw[k] = sr
        if want[0]:
            out[v, 0] = peak_row(res, n)
        if want[1]:
            out[v, 1], out[v, 2], out[v, 3] = hic_row(res, n, h, 0.015, cum, blk, True)
        if want[2]:
            out[v, 4], out[v, 5], out[v, 6] = hic_row(res, n, h, 0.036, cum, blk, True)
        if want[3] or want[4]:
            lev, _ = clip_row(res, n, h, CLIP_WINDOW, mn, hmin)
            if np.isnan(lev):
                status[v] |= 16
            out[v, 7] = lev
            if want[4]:
                out[v, 8] = clip_cumulative_row(
                    res, n, h, CLIP_WINDOW, lev if lev == lev else -np.inf, lo, hi
                )
        if want[5]:
            u[0] = u0[v]
            for k in range(1, n):
                u[k] = u[k - 1] - 0.5 * dt[v] * (dfil[k - 1] + dfil[k])
            olc, t1, t2 = olc_row(u, n, dt[v], u0[v], s_free, s_rest)
            if t1 == -1.0:
                status[v] |= 4
            elif t2 == -1.0:
                status[v] |= 8
            out[v, 9] = olc / g
        if want[6]:
            for k in range(n):
                xin[k] = draw[k] / g
            out[v, 10] = DRI_OMEGA * DRI_OMEGA * dri_row(xin, n, phi[v], g0[v], gs[v])
        if want[7]:
            uk = 0.0
            best = 0.0
            for k in range(1, n):
                uk -= 0.5 * dt[v] * (draw[k - 1] + draw[k])
                best = max(best, abs(uk))
            out[v, 11] = best


def compute(
    acc: np.ndarray,
    count: np.ndarray,
    dt: np.ndarray,
    v0: np.ndarray,
    direction: np.ndarray,
    cfc: int,
    criteria: Iterable[str],
    g: float,
    *,
    metre: float = 1.0,
    second: float = 1.0,
    pad: str = "constant",
) -> dict[str, np.ndarray]:
    """Criteria of SPEC 6b for every variant of one node.

    Parameters
    ----------
    acc : (V, T, D) float64, the node's acceleration at ``t_n = n dt[v]``, ``n < count[v]``
        [length/time^2] (the rest of each row is ignored).
    count : (V,) int, steps per variant.
    dt : (V,) float, each variant's step [model time].
    v0 : (V, D) initial velocity [length/time].
    direction : (D,) or (V, D) unit vector (normalised here) along which deceleration is positive.
    cfc : SAE J211 channel class, 60 | 180 | 600 | 1000.
    criteria : names from :data:`CRITERIA`.
    g : standard gravity in the model's units (9.80665 in SI, 9806.65 in mm/s^2, 9.80665e-3 mm/ms^2).
    metre : model length units in one metre (1000 for a mm model): OLC's 65 mm + 235 mm.
    second : model time units in one second (1000 for a ms model): the filter's rate, the HIC and
        clip windows and the DRI frequency are in seconds; ``*_t1``/``*_t2`` are returned in seconds.
    pad : the filter's continuation of the record, ``"constant"`` | ``"zero"`` | ``"reflect"``
        (:mod:`crashstudy.metrics.criteria_filter`).

    Returns
    -------
    ``{name: (V,) float64}`` for each asked criterion and its :data:`EXTRA`, NaN where
    ``count < 2``, the acceleration is not finite within the record, or the criterion is undefined, and ``"criteria_note"``: (V,) object array of
    ``""`` or why a value is not trusted.
    """
    names = list(dict.fromkeys(criteria))
    bad = [c for c in names if c not in CRITERIA]
    if bad:
        raise ValueError(f"unknown criteria {bad}; expected names from {CRITERIA}")
    if int(cfc) not in CFC_CLASSES:
        raise ValueError(f"cfc must be one of {CFC_CLASSES}, got {cfc!r}")
    acc = np.asarray(acc, dtype=np.float64)
    if acc.ndim != 3:
        raise ValueError("acc must be (V, T, D)")
    nv, nt, nd = acc.shape
    count = np.minimum(np.asarray(count, dtype=np.int64).reshape(nv), nt)
    dt = np.asarray(dt, dtype=np.float64).reshape(nv)
    dirs = np.broadcast_to(np.asarray(direction, dtype=np.float64), (nv, nd)).copy()
    norm = np.linalg.norm(dirs, axis=1, keepdims=True)
    dirs = dirs / np.where(norm > 0.0, norm, 1.0)
    u0 = np.einsum("vd,vd->v", np.asarray(v0, dtype=np.float64).reshape(nv, nd), dirs)
    dt_s = dt / float(second)
    want = np.array([c in names for c in CRITERIA])
    phi, g0, gs = (
        dri_matrices(dt_s) if want[6] else (np.zeros((nv, 2, 2)), np.zeros((nv, 2)), np.zeros((nv, 2)))
    )
    out = np.full((nv, len(_COLS)), np.nan)
    status = np.zeros(nv, dtype=np.int64)
    acc = np.ascontiguousarray(acc)
    consts = (float(cfc), pad_code(pad), float(g), want, OLC_FREE * metre, OLC_RESTRAINED * metre)
    driver, compiled = driver_for(
        _driver, int(np.sum(count))
    )  # a small record on a fresh machine: no compile

    def part(
        lo: int, hi: int
    ) -> None:  # variants lo:hi (the compiled driver holds no GIL: parts run side by side)
        s = slice(lo, hi)
        driver(
            acc[s], count[s], dt[s], dt_s[s], u0[s], dirs[s], *consts, phi[s], g0[s], gs[s], out[s], status[s]
        )

    bounds = np.linspace(0, nv, min(get_threads(), max(nv // MIN_PART, 1)) + 1).astype(np.int64)
    if len(bounds) <= 2 or not compiled:
        part(0, nv)
    else:
        with ThreadPoolExecutor(len(bounds) - 1) as pool:
            list(pool.map(part, bounds[:-1], bounds[1:]))
    filtered = bool(want[:6].any())
    if filtered:
        status |= np.where(rate_too_low(dt, float(cfc), second) & (status & _NO_FILTER == 0), _LOW_RATE, 0)
    result: dict[str, np.ndarray] = {}
    for name in names:
        for col in (name, *EXTRA.get(name, ())):
            result[col] = out[:, _COLS.index(col)].copy()
    if "olc" not in names:
        status &= ~(_OLC_FREE | _OLC_END)
    if "clip3ms" not in names and "clip3ms_cumulative" not in names:
        status &= ~_SHORT_CLIP
    notes = np.full(nv, "", dtype=object)
    for code in np.unique(status[status != 0]):
        notes[status == code] = "; ".join(text for bit, text in _NOTES.items() if code & bit)
    result["criteria_note"] = notes
    return result


assert NOT_REACHED == -1.0  # the driver tests t1/t2 against -1.0
