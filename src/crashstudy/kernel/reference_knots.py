"""The reference kernel's knot crossings (docs/solver.md, "Peaks"): which springs follow a curve with a
flagged knot, and the knots a spring passed over in a step, with the peak-force candidate, the crossing
fraction and the force jump. The NumPy twins of the compiled knot laws of :mod:`crashstudy.kernel.laws`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from crashstudy.vocabulary.codes import CRUSH, GENERAL
from crashstudy.vocabulary.materials import KNOT_MATERIALS

if TYPE_CHECKING:
    from crashstudy.arrays.batch import Batch


def spring_knotted(b: Batch) -> np.ndarray:
    """(S,) bool: the spring follows a curve (by elongation) with a knot flagged in ``b.knot_check``."""
    out = np.zeros(len(b.spring_i), dtype=bool)
    for s in range(len(b.spring_i)):
        c = int(b.curve_a[s])
        if b.material[s] in KNOT_MATERIALS and c >= 0:
            out[s] = bool(np.any(b.knot_check[int(b.curve_off[c]) + 1 : int(b.curve_off[c + 1]) - 1]))
    return out


def knot_peak_np(
    cand: np.ndarray, e_lo: np.ndarray, e_hi: np.ndarray, xk: np.ndarray, yk: np.ndarray
) -> np.ndarray:
    """NumPy twin of :func:`crashstudy.kernel.laws.knot_peak`: ``max(cand, |yk|)`` where ``e_lo < xk < e_hi``."""
    ak = np.abs(yk)
    return np.where((xk > e_lo) & (xk < e_hi) & (ak > cand), ak, cand)


def knot_crossing_np(
    b: Batch, s: int, e: np.ndarray, ep: np.ndarray, F: np.ndarray, Fp: np.ndarray, st: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Knots of spring ``s``'s curve passed over on its elastic (loading) path from ``ep`` to ``e``.

    ``st`` is the material state before this step. The path segment ``(lo, hi)`` in the curve's abscissa:
    ``nonlinear_elastic`` (min, max) of (ep, e); ``crush`` (e, e_min before the step) (empty unless the
    spring crushes further); ``general_nonlinear`` never yielded (min, max) of (ep, e), last yielded in
    tension (e_t*, e), in compression (e, e_c*), all minus the loading curve's shift (a reversal this
    step gives an empty segment: skipped). Returns (candidate |force| (0 if none), crossing fraction
    ``theta`` of the largest knot, its force minus ``(1 - theta) Fp + theta F`` (0 if none)).
    """
    kind = b.material[s]
    c = int(b.curve_a[s])
    if kind == CRUSH:
        lo, hi, sh = e, st[0], 0.0
    elif kind == GENERAL:
        mode, et, ec, sh = st[0], st[1], st[3], st[5]
        lo = np.where(mode > 0, et, np.where(mode < 0, e, np.minimum(ep, e))) - sh
        hi = np.where(mode > 0, e, np.where(mode < 0, ec, np.maximum(ep, e))) - sh
    else:
        lo, hi, sh = np.minimum(ep, e), np.maximum(ep, e), 0.0
    ea = e - sh
    epa = ep - sh
    cand = np.zeros_like(e)
    xb = epa
    yb = np.zeros_like(e)
    for k in range(int(b.curve_off[c]) + 1, int(b.curve_off[c + 1]) - 1):
        if not b.knot_check[k]:
            continue
        yk = np.minimum(0.0, b.knot_y[k]) if kind == CRUSH else b.knot_y[k]
        c1 = knot_peak_np(cand, lo, hi, b.cx[k], yk)
        xb = np.where(c1 > cand, b.cx[k], xb)
        yb = np.where(c1 > cand, yk, yb)
        cand = c1
    hit = cand > 0.0
    th = (xb - epa) / np.where(hit, ea - epa, 1.0)
    dF = np.where(hit, yb - ((1.0 - th) * Fp + th * F), 0.0)
    return cand, th, dF
