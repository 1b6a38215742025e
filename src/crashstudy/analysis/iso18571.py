"""ISO/TS 18571 objective rating of model curves against one test curve (docs/correlation.md), vectorised
over variants: ``rate(test, models)`` scores a (V, n) array of model curves in one call.

Both curves are sampled at :data:`RATE_HZ` on one time grid (:func:`resample`). With the test curve ``T``
(the reference) and a model curve ``C`` (the comparison), ``N`` samples each:

- corridor score Z: inner and outer half-widths ``a = A0 max|T|`` and ``b = B0 max|T|``; a point scores 1
  within ``a``, 0 beyond ``b`` and ``((b - |C - T|) / (b - a))^KZ`` between; Z is the mean over the points.
- phase: the Pearson correlation of the overlapping parts of ``T`` and ``C`` shifted by ``m`` samples
  either way, ``m < EPS_P N``; the shift of the largest correlation (the smallest shift on a tie, the
  model shifted left before right) is ``m*``; ``EP = ((EPS_P N - m*) / (EPS_P N))^KP``, 1 for ``m* = 0``.
  The magnitude and slope scores compare the overlapping parts at ``m*``.
- magnitude score EM: dynamic time warping of the shifted curves (cost ``(C_i - T_j)^2``, steps (1, 0),
  (0, 1), (1, 1), a Sakoe-Chiba band ``|i - j| < ceil(DTW_BAND n)``); along the warping path
  ``e = sum|C_i - T_j| / sum|T_j|`` and ``EM = ((EPS_M - e) / EPS_M)^KM``, 0 beyond ``EPS_M``.
- slope score ES: the derivatives (central differences, one-sided at the ends) smoothed by a 9-point
  moving average (1, 3, 5, 7 points at the first and last four samples);
  ``e = sum|C' - T'| / sum|T'|``, ``ES = (EPS_S - e) / EPS_S``, 0 beyond ``EPS_S``.
- ``R = 0.4 Z + 0.2 EP + 0.2 EM + 0.2 ES``; its grade by :data:`GRADES`.

The phase search is one FFT cross-correlation per block of variants; the warping and the slopes of
every variant are one compiled call (:func:`_shifted_errors`, parallel over variants, a banded cost
matrix of ``n (2 ceil(DTW_BAND n) - 1)`` doubles per thread). The definitions follow the
``objective-rating-metrics`` package (VSI TU Graz), the independent implementation the tests compare
against (tests/test_iso18571.py).
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

RATE_HZ = 10_000.0  # both curves are rated at 10 kHz
DT = 1.0 / RATE_HZ
A0, B0, KZ = 0.05, 0.5, 2  # corridor: inner, outer half-width (fractions of the test's peak), exponent
EPS_P, KP = 0.2, 1  # phase: largest shift (fraction of the samples), exponent
EPS_M, KM = 0.5, 1  # magnitude: error limit, exponent
EPS_S = 2.0  # slope: error limit
DTW_BAND = 0.1  # Sakoe-Chiba band of the warping (fraction of the samples)
WEIGHTS = {"Z": 0.4, "EP": 0.2, "EM": 0.2, "ES": 0.2}
#: ISO/TS 18571:2014 sliding scale: R above the bound gets the grade; otherwise "poor"
GRADES = ((0.94, "excellent"), (0.80, "good"), (0.58, "fair"))
MIN_SAMPLES = 20  # fewer samples on the rated interval (2 ms at 10 kHz) cannot be rated
BLOCK = 256  # variants per block of the NumPy parts (memory: a few (BLOCK, 2 n) arrays)


def grade(r: float) -> str:
    """The ISO/TS 18571:2014 grade of an overall rating ``r`` ("" when it is not a number)."""
    if not np.isfinite(r):
        return ""
    return next((name for bound, name in GRADES if r > bound), "poor")


def rating_grid(t0: float, t1: float) -> np.ndarray:
    """Times ``t0, t0 + DT, ...`` up to ``t1`` (the 10 kHz grid the curves are rated on)."""
    k = int(math.floor((t1 - t0) / DT * (1.0 + 1e-12) + 1e-9))
    return t0 + DT * np.arange(k + 1)


def resample(t: np.ndarray, y: np.ndarray, grid: np.ndarray) -> np.ndarray:
    """Linear interpolation of ``y`` (len(t)) or of each row of ``y`` (rows, len(t)), sampled at increasing
    ``t``, onto ``grid`` (inside ``t``)."""
    t = np.asarray(t, dtype=float)
    i = np.clip(np.searchsorted(t, grid, side="right") - 1, 0, len(t) - 2)
    w = (grid - t[i]) / (t[i + 1] - t[i])
    y = np.asarray(y, dtype=float)
    if y.ndim == 1:
        return y[i] * (1.0 - w) + y[i + 1] * w
    out = np.empty((len(y), len(grid)))
    for lo in range(0, len(y), BLOCK):  # blocks of rows: no temporaries of the whole size
        out[lo : lo + BLOCK] = y[lo : lo + BLOCK, i] * (1.0 - w) + y[lo : lo + BLOCK, i + 1] * w
    return out


def corridor(test: np.ndarray, models: np.ndarray) -> np.ndarray:
    """Corridor score Z of each row of ``models`` (V, n) against ``test`` (n)."""
    peak = float(np.max(np.abs(test)))
    a, b = A0 * peak, B0 * peak
    d = np.abs(models - test)
    c = ((b - d) / (b - a)) ** KZ
    c = np.where(d < a, 1.0, np.where(d > b, 0.0, c))
    return c.mean(axis=-1)


def best_shift(test: np.ndarray, models: np.ndarray) -> np.ndarray:
    """Per row of ``models`` the signed shift (samples) of the largest correlation: ``+m`` compares
    ``test[:-m]`` with ``model[m:]`` (the model shifted left), ``-m`` ``test[m:]`` with ``model[:-m]``."""
    n = test.shape[-1]
    window = int(math.floor(n * EPS_P) + 1)  # shifts 0 .. window - 1
    m = np.arange(window)
    length = (n - m).astype(float)
    size = 1 << int(math.ceil(math.log2(2 * n)))
    x = (test - test.mean()) / (np.std(test) or 1.0)  # Pearson is blind to offset and scale: better rounding
    cx, cx2 = np.concatenate([[0.0], np.cumsum(x)]), np.concatenate([[0.0], np.cumsum(x * x)])
    fx = np.conj(np.fft.rfft(x, size))
    out = np.empty(len(models), dtype=np.int64)
    for lo in range(0, len(models), BLOCK):  # blocks of variants (memory), each one vectorised call
        y = models[lo : lo + BLOCK]
        y = (y - y.mean(axis=1, keepdims=True)) / np.where((s := y.std(axis=1, keepdims=True)) > 0, s, 1.0)
        cy = np.concatenate([np.zeros((len(y), 1)), np.cumsum(y, axis=1)], axis=1)
        cy2 = np.concatenate([np.zeros((len(y), 1)), np.cumsum(y * y, axis=1)], axis=1)
        xc = np.fft.irfft(fx * np.fft.rfft(y, size, axis=1), size, axis=1)  # xc[k] = sum_i x[i] y[i + k]
        left = _pearson(
            xc[:, m], cx[n - m], cx2[n - m], cy[:, n, None] - cy[:, m], cy2[:, n, None] - cy2[:, m], length
        )  # x[:n-m] with y[m:]
        right = _pearson(
            xc[:, (size - m) % size], cx[n] - cx[m], cx2[n] - cx2[m], cy[:, n - m], cy2[:, n - m], length
        )  # x[m:] with y[:n-m]
        order = np.empty(
            (len(y), 2 * window - 1)
        )  # candidates in the standard's order: 0, L1, R1, L2, R2, ...
        order[:, 0] = left[:, 0]
        order[:, 1::2], order[:, 2::2] = left[:, 1:], right[:, 1:]
        first_nan = np.isnan(order[:, 0])  # no correlation at 0: nothing beats it (the reference keeps m = 0)
        k = np.argmax(np.where(np.isnan(order), -np.inf, order), axis=1)
        k[first_nan] = 0
        out[lo : lo + BLOCK] = np.where(k == 0, 0, np.where(k % 2 == 1, (k + 1) // 2, -(k // 2)))
    return out


def _pearson(
    sxy: np.ndarray, sx: np.ndarray, sxx: np.ndarray, sy: np.ndarray, syy: np.ndarray, n: np.ndarray
) -> np.ndarray:
    with np.errstate(invalid="ignore", divide="ignore"):
        cov = sxy - sx * sy / n
        vx, vy = sxx - sx * sx / n, syy - sy * sy / n
        return cov / np.sqrt(np.maximum(vx, 0.0) * np.maximum(vy, 0.0))


def phase_score(shift: np.ndarray, n: int) -> np.ndarray:
    """EP of shifts ``shift`` (samples) on ``n`` samples."""
    limit = n * EPS_P
    m = np.abs(shift).astype(float)
    return np.where(m == 0, 1.0, np.where(m >= limit, 0.0, ((limit - m) / limit) ** KP))


def rate(test: np.ndarray, models: np.ndarray) -> dict[str, np.ndarray]:
    """Scores ``R, Z, EP, EM, ES`` (each (V,)) and ``shift`` (samples, see :func:`best_shift`) of every
    row of ``models`` (V, n) against ``test`` (n), both sampled at :data:`RATE_HZ` on the same grid."""
    test = np.ascontiguousarray(test, dtype=np.float64)
    models = np.ascontiguousarray(np.atleast_2d(models), dtype=np.float64)
    n = test.shape[-1]
    if models.shape[-1] != n or n < MIN_SAMPLES:
        raise ValueError(f"expected curves of one length >= {MIN_SAMPLES}; got {n} and {models.shape[-1]}")
    if not np.all(np.isfinite(test)) or not np.any(test != test[0]):
        raise ValueError(
            "the test curve is constant (or not finite) on the rated interval: its corridor, "
            "correlation and slopes are undefined; rate another interval or channel"
        )
    z = np.concatenate([corridor(test, models[lo : lo + BLOCK]) for lo in range(0, len(models), BLOCK)])
    shift = best_shift(test, models)
    err_m, err_s = _shifted_errors(test, models, shift, DTW_BAND, DT)
    with np.errstate(invalid="ignore"):
        em = np.where(err_m == 0, 1.0, np.where(err_m > EPS_M, 0.0, ((EPS_M - err_m) / EPS_M) ** KM))
        es = np.where(err_s <= 0, 1.0, np.where(err_s >= EPS_S, 0.0, (EPS_S - err_s) / EPS_S))
    em = np.where(np.isnan(err_m), np.nan, em)
    es = np.where(np.isnan(err_s), np.nan, es)
    ep = phase_score(shift, n)
    r = WEIGHTS["Z"] * z + WEIGHTS["EP"] * ep + WEIGHTS["EM"] * em + WEIGHTS["ES"] * es
    return {"R": r, "Z": z, "EP": ep, "EM": em, "ES": es, "shift": shift}


@nb.njit(cache=True, nogil=True, parallel=True)
def _shifted_errors(test, models, shift, band, dt):  # pragma: no cover - compiled
    """Per variant (parallel): the magnitude error after warping and the slope error of the curves
    overlapping at ``shift``; NaN where the test's part has no magnitude (or no slope)."""
    nv, n = models.shape
    err_m = np.empty(nv)
    err_s = np.empty(nv)
    for v in nb.prange(nv):
        m = abs(shift[v])
        k = n - m
        lo_c, lo_t = (m, 0) if shift[v] >= 0 else (0, m)
        c = models[v, lo_c : lo_c + k]
        t = test[lo_t : lo_t + k]
        err_m[v] = _warped_error(c, t, band)
        err_s[v] = _slope_error(c, t, dt)
    return err_m, err_s


@nb.njit(cache=True, nogil=True)
def _warped_error(x, y, band):  # pragma: no cover - compiled
    """sum|x_i - y_j| / sum|y_j| along the DTW path of ``x`` (rows) against ``y`` (columns): cumulative
    cost D[i, j] = (x_i - y_j)^2 + min(D[i-1, j], D[i, j-1], D[i-1, j-1]) within |i - j| <= w, the path
    traced back from the end, on a tie the first of (i-1, j), (i, j-1), (i-1, j-1)."""
    n = x.shape[0]
    w = int(math.ceil(band * n)) - 1
    width = 2 * w + 1
    d = np.full((n, width), np.inf)  # d[i, j - i + w]
    for i in range(n):
        for j in range(max(0, i - w), min(n, i + w + 1)):
            cost = (x[i] - y[j]) ** 2
            if i == 0 and j == 0:
                d[i, w] = cost
                continue
            best = np.inf
            if i > 0 and j - i + 1 + w < width:  # (i-1, j): column j - (i-1) + w
                best = d[i - 1, j - i + 1 + w]
            if j > 0 and j - 1 - i + w >= 0 and d[i, j - 1 - i + w] < best:
                best = d[i, j - 1 - i + w]
            if i > 0 and j > 0 and d[i - 1, j - i + w] < best:
                best = d[i - 1, j - i + w]
            d[i, j - i + w] = cost + best
    i = n - 1
    j = n - 1
    num = abs(x[i] - y[j])
    den = abs(y[j])
    while i > 0 or j > 0:
        bi, bj = -1, -1
        best = np.inf
        if i > 0 and j - i + 1 + w < width and d[i - 1, j - i + 1 + w] < best:
            best, bi, bj = d[i - 1, j - i + 1 + w], i - 1, j
        if j > 0 and j - 1 - i + w >= 0 and d[i, j - 1 - i + w] < best:
            best, bi, bj = d[i, j - 1 - i + w], i, j - 1
        if i > 0 and j > 0 and d[i - 1, j - i + w] < best:
            best, bi, bj = d[i - 1, j - i + w], i - 1, j - 1
        if bi < 0:  # no finite predecessor (cannot happen within the band)
            return np.nan
        i, j = bi, bj
        num += abs(x[i] - y[j])
        den += abs(y[j])
    return num / den if den > 0 else np.nan


@nb.njit(cache=True, nogil=True)
def _smoothed_slope(y, dt):  # pragma: no cover - compiled
    n = y.shape[0]
    g = np.empty(n)
    g[0] = (y[1] - y[0]) / dt
    g[n - 1] = (y[n - 1] - y[n - 2]) / dt
    for i in range(1, n - 1):
        g[i] = (y[i + 1] - y[i - 1]) / (2.0 * dt)
    s = np.empty(n)
    for k in range(4):  # the first and last four samples: means of the first (last) 1, 3, 5, 7 slopes
        nr = 2 * k + 1
        a = 0.0
        b = 0.0
        for q in range(nr):
            a += g[q]
            b += g[n - 1 - q]
        s[k] = a / nr
        s[n - 1 - k] = b / nr
    for i in range(4, n - 4):
        a = 0.0
        for q in range(i - 4, i + 5):
            a += g[q]
        s[i] = a / 9.0
    return s


@nb.njit(cache=True, nogil=True)
def _slope_error(c, t, dt):  # pragma: no cover - compiled
    sc = _smoothed_slope(c, dt)
    st = _smoothed_slope(t, dt)
    num = 0.0
    den = 0.0
    for i in range(c.shape[0]):
        num += abs(sc[i] - st[i])
        den += abs(st[i])
    return num / den if den > 0 else np.nan


def rated_interval(
    t_model: np.ndarray, t_test: np.ndarray, window: tuple[float, float] | None
) -> tuple[float, float]:
    """The interval both curves cover (cut to ``window`` when given), in model time."""
    t0, t1 = max(float(t_model[0]), float(t_test[0])), min(float(t_model[-1]), float(t_test[-1]))
    if window is not None:
        t0, t1 = max(t0, float(window[0])), min(t1, float(window[1]))
    return t0, t1


def rate_histories(
    t_model: np.ndarray,
    models: np.ndarray,
    t_test: np.ndarray,
    test: np.ndarray,
    second: float,
    window: tuple[float, float] | None = None,
) -> dict[str, np.ndarray]:
    """:func:`rate` of the histories ``models`` (V, len(t_model)) against the test curve (``t_test``,
    ``test``), both resampled to :data:`RATE_HZ` on their common interval (cut to ``window``); times in
    model units, ``second`` of them in one second. Rows that are not finite score NaN. Adds ``t0``,
    ``t1`` (the interval) and ``samples``. ValueError when the interval holds too few samples."""
    t0, t1 = rated_interval(t_model, t_test, window)
    grid = rating_grid(t0 / second, t1 / second) * second if t1 > t0 else np.empty(0)
    if len(grid) < MIN_SAMPLES:
        raise ValueError(
            f"the test ({t_test[0]:g} .. {t_test[-1]:g}) and the model ({t_model[0]:g} .. "
            f"{t_model[-1]:g}) overlap{f' within the window {window[0]:g} .. {window[1]:g}' if window else ''}"
            f" on {max(len(grid), 0)} samples at 10 kHz; at least {MIN_SAMPLES} are needed"
        )
    y_test = resample(t_test, test, grid)
    y = resample(t_model, models, grid)
    ok = np.all(np.isfinite(y), axis=1)
    out = {k: np.full(len(models), np.nan) for k in ("R", "Z", "EP", "EM", "ES", "shift")}
    if ok.any():
        scores = rate(y_test, y[ok])
        for k, v in scores.items():
            out[k][ok] = v
    out["t0"], out["t1"], out["samples"] = np.array(t0), np.array(t1), np.array(len(grid))
    return out
