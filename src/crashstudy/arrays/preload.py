"""The material state and stored energy of preloaded springs at t = 0 (``initial_elongation``).

A spring with ``initial_elongation: e0`` starts as if it had been loaded monotonically from 0 to
``e0`` (docs/format.md). Along such a path every force law is piecewise linear in the elongation, with
kinks only at a curve's knots, where a ``crush`` curve crosses zero (``min(0, L)``) and at the
elastic limit ``+-FY / K`` of an ``elastoplastic`` spring. :func:`preload` therefore walks each
spring through those kinks in order, applying the material law (the NumPy laws of
:mod:`crashstudy.arrays.material_laws`) at each, which leaves the law's state exactly where a monotonic
loading would (a ``general_nonlinear`` spring yields if its loading curve reaches a yield force
anywhere on the path), and integrates the stored energy ``IE0`` exactly by the trapezoidal rule.

Every kernel starts from this state, so the kernels agree on it by construction.
"""

from __future__ import annotations

import numpy as np

from crashstudy.arrays import material_laws as mat
from crashstudy.vocabulary.codes import CRUSH, ELASTOPLASTIC, GENERAL, LINEAR, NONLINEAR, RATE_ELASTIC
from crashstudy.vocabulary.materials import spec


def preload(
    material: np.ndarray,
    curve_a: np.ndarray,
    curve_b: np.ndarray,
    e0: np.ndarray,
    kpar: np.ndarray,
    yield_t: np.ndarray,
    yield_c: np.ndarray,
    kt: np.ndarray,
    fy: np.ndarray,
    cx: np.ndarray,
    cy: np.ndarray,
    cds: np.ndarray,
    cs0: np.ndarray,
    cs1: np.ndarray,
    off: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """(state0 (S, NSTATE, V), IE0 (S, V) [energy]) after loading each spring from 0 to ``e0`` (S, V).

    ``state0`` is ``(0, NSTATE, V)`` when no spring is preloaded (every kernel then starts from zeros).
    """
    S, V = e0.shape
    ie0 = np.zeros((S, V))
    if not np.any(e0 != 0.0):
        return np.zeros((0, mat.NSTATE, V)), ie0
    state = np.zeros((S, mat.NSTATE, V))
    for s in range(S):
        if not np.any(e0[s] != 0.0):
            continue
        kind, c = int(material[s]), int(curve_a[s])
        points = _kinks(kind, c, kpar[s], fy[s], cx, cy, off, V)
        direction = np.sign(e0[s])
        # kinks strictly between 0 and e0, in the order the path meets them; the others become e0 itself
        inside = (points * direction > 0.0) & (points * direction < e0[s] * direction)
        path = np.sort(np.where(inside, points, e0[s]) * direction, axis=0) * direction
        path = np.concatenate([path, e0[s][None, :]])
        e_prev, f_prev = np.zeros(V), np.zeros(V)
        for e in path:
            f = _law(
                kind,
                s,
                c,
                int(curve_b[s]),
                e,
                state[s],
                kpar,
                yield_t,
                yield_c,
                kt,
                fy,
                cx,
                cy,
                cds,
                cs0,
                cs1,
                off,
            )
            ie0[s] += 0.5 * (f + f_prev) * (e - e_prev)
            e_prev, f_prev = e, f
    return state, ie0


def _kinks(
    kind: int, c: int, k: np.ndarray, fy: np.ndarray, cx: np.ndarray, cy: np.ndarray, off: np.ndarray, V: int
) -> np.ndarray:
    """Elongations (M, V) where the force law of a monotonic path may bend."""
    rule = spec(kind).kinks  # the material table's preload kinks
    if rule == "elastic_limit":
        return np.stack([fy / k, -fy / k])
    if rule == "none" or c < 0:
        return np.zeros((0, V))
    a, b = int(off[c]), int(off[c + 1])
    xs, ys = cx[a:b], cy[a:b]
    if rule == "curve_knots":
        return xs
    # min(0, L) bends where L changes sign inside a segment
    with np.errstate(divide="ignore", invalid="ignore"):
        cross = xs[:-1] - ys[:-1] * (xs[1:] - xs[:-1]) / (ys[1:] - ys[:-1])
    cross = np.where(ys[:-1] * ys[1:] < 0.0, cross, xs[:-1])
    return np.concatenate([xs, cross])


def _law(
    kind: int,
    s: int,
    c: int,
    cb: int,
    e: np.ndarray,
    st: np.ndarray,
    kpar: np.ndarray,
    yield_t: np.ndarray,
    yield_c: np.ndarray,
    kt: np.ndarray,
    fy: np.ndarray,
    cx: np.ndarray,
    cy: np.ndarray,
    cds: np.ndarray,
    cs0: np.ndarray,
    cs1: np.ndarray,
    off: np.ndarray,
) -> np.ndarray:
    if kind == LINEAR:
        return kpar[s] * e
    if kind == NONLINEAR or kind == RATE_ELASTIC:  # rate_elastic: loaded at rate 0, along its first curve
        return mat.curve_eval(c, e, cx, cy, cds, cs0, off)
    if kind == CRUSH:
        return mat.crush(e, st, c, kpar[s], cx, cy, cds, cs0, off)
    if kind == GENERAL:
        return mat.general_nonlinear(e, st, c, cb, yield_t[s], yield_c[s], cx, cy, cds, cs0, cs1, off)
    if kind == ELASTOPLASTIC:
        return mat.elastoplastic(e, st, kpar[s], kt[s], fy[s])
    raise ValueError(f"material code {kind} has no initial elongation")
