"""The register constants of a generated kernel: the curves whose coefficients are the same in every
variant (constant curves) or differ by their factors only (factor curves), and the ``cst`` argument
that carries their coefficients (:func:`_const_layout` names them, :func:`_constants` fills them).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from crashstudy.arrays.batch import Batch
    from crashstudy.kernel.gen_rows import Coef


def _constant_curves(b: Batch, vary: frozenset[int] | None) -> list[int]:
    """Curves whose coefficients are the same in every variant of ``b`` and, when ``vary`` (the curves a
    study changes, :attr:`crashstudy.study.plan.Plan.varying_curves`) is given, not among those: their
    numbers stay in registers."""
    out = []
    for c in range(len(b.curve_off) - 1):
        a0, b0 = b.curve_off[c], b.curve_off[c + 1]
        if vary is not None and (c in vary or -1 - c in vary):
            continue
        rows = [b.cx[a0:b0], b.cy[a0:b0], b.cds[a0:b0], b.knot_y[a0:b0], b.cs0[c : c + 1]]
        if all(np.all(r == r[:, :1]) for r in rows):
            out.append(c)
    return out


def _factor_curves(b: Batch, vary: frozenset[int] | None, const: list[int]) -> list[int]:
    """Curves with a constant shape (the points as written, the same in every variant) whose variants
    differ by their factors only (``curves.<id>.scale``, ``x_scale``: Batch.cfac): the shape stays in
    registers and a lane carries its three factors (an effective coefficient is shape x factor, the
    product arrays.batch.build_batch takes)."""
    out = []
    for c in range(len(b.curve_off) - 1):
        a0, b0 = b.curve_off[c], b.curve_off[c + 1]
        if c in const or (vary is not None and c in vary):
            continue
        if all(np.all(r == r[:, :1]) for r in (b.bx[a0:b0], b.by[a0:b0])):
            out.append(c)
    return out


def _const_layout(shape: dict[str, Any]) -> list[tuple[Coef, str, int]]:
    """(coefficient, Batch array, row) of every register coefficient the springs read, in the order
    of the kernel's ``cst`` argument: the constant curves' coefficients and the factor curves' shapes
    (arrays ``bcy``, ``bs0``, ``bds``, ``bx``: see :func:`_constants`)."""
    off, S = shape["off"], shape["S"]
    fac = set(shape.get("fac", ()))
    tcurves = {c for _, c in shape["loads"] if c >= 0} | {c for _, _, _, c in shape["pm"]}
    used = {c for s in range(S) for c in (shape["ca"][s], shape["cb"][s]) if c >= 0} | tcurves
    used |= {c for cs in shape.get("rc", ()) for c in cs}
    out: list[tuple[Coef, str, int]] = []
    for c in shape["const"] + sorted(fac):
        if c not in used:
            continue
        cx, cy, cds, cs0 = ("bx", "by", "bds", "bs0") if c in fac else ("cx", "cy", "cds", "cs0")
        if c in tcurves:
            out.append((("cx", off[c + 1] - 1), cx, off[c + 1] - 1))
        out += [(("cy0", c), cy, off[c]), (("s0", c), cs0, c)]
        for k in range(off[c], off[c + 1] - 1):
            out.append((("cx", k), cx, k))
            if k > off[c]:
                out.append((("ds", k), cds, k))
            if k in shape["kcheck"] and c not in fac:  # a factor curve's knot forces: per-variant rows
                out.append((("kyv", k), "knot_y", k))
    return out


def _constants(b: Batch, shape: dict[str, Any]) -> np.ndarray:
    """The ``cst`` argument: the constant curves' coefficients (the same in every variant) and the
    factor curves' shape coefficients (from the points as written, as arrays.batch.build_batch)."""
    off = b.curve_off
    with np.errstate(all="ignore"):
        slope = [
            np.diff(b.by[off[c] : off[c + 1], :1], axis=0) / np.diff(b.bx[off[c] : off[c + 1], :1], axis=0)
            for c in range(len(off) - 1)
        ]
    bds = np.zeros((len(b.bx), 1))
    for c, sl in enumerate(slope):
        bds[off[c] + 1 : off[c + 1] - 1] = np.diff(sl, axis=0)
    arrays = {"bx": b.bx, "by": b.by, "bds": bds, "bs0": np.array([sl[0] for sl in slope]).reshape(-1, 1)}
    return np.array(
        [(arrays[arr] if arr in arrays else getattr(b, arr))[row, 0] for _, arr, row in _const_layout(shape)]
        + [0.0]
    )
