"""Which springs went past the drawn ends of their material curves.

A material curve is extrapolated along its first and last segment (docs/format.md, "curves"): a
crash box crushed beyond the last point of its test curve, or a spring stretched beyond it, carries a
force nobody measured. ``past_curve_end`` says so per variant and spring, from the spring's extremes
(``max_crush``, ``max_elongation``) and the x range of its curve in that variant (after a study's
scaling):

- ``nonlinear_elastic`` (its curve), both ends;
- ``general_nonlinear`` (its loading curve): the compression end (the most compressed point is always
  reached along the loading curve), and the tension end only without a ``compression_yield`` (after a
  compression yield a stretch follows the unloading curve, whose origin moved: the loading curve's
  range says nothing there);
- ``crush`` (its loading curve), the compression end only (it never pulls);
- ``rate_elastic`` (all its curves), both ends: the narrowest range of its curves;
- other materials have no drawn curve of elongation (a ``nonlinear_damper`` curve is of the rate).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from crashstudy.results.tables import stored_ids
from crashstudy.vocabulary.codes import GENERAL
from crashstudy.vocabulary.materials import MATERIALS

PAST_FIRST, PAST_LAST = 1.0, 2.0  # codes, added: 3 = both ends
ENDS_OF = {m.code: m.curve_ends for m in MATERIALS if any(m.curve_ends)}  # (first end, last end) checked


def curve_springs(material: np.ndarray, curve: np.ndarray) -> list[int]:
    """The springs whose extremes are checked against a drawn curve."""
    return [s for s in range(len(material)) if int(material[s]) in ENDS_OF and int(curve[s]) >= 0]


def past_curve_ends(
    b: Any, max_crush: np.ndarray, max_elongation: np.ndarray, cols: np.ndarray
) -> np.ndarray:
    """(S, V) codes (``PAST_FIRST`` + ``PAST_LAST``) of the springs of batch ``b`` whose extremes (S, V)
    passed an end of their curve; column k of the extremes belongs to variant ``cols[k]`` of ``b``."""
    out = np.zeros(max_crush.shape)
    for s in curve_springs(b.material, b.curve_a):
        curves = [int(b.curve_a[s])]
        if b.rate_off[s + 1] > b.rate_off[s]:  # rate_elastic: every one of its curves
            curves = [int(c) for c in b.rate_curve[b.rate_off[s] : b.rate_off[s + 1]]]
        first_x = np.max([b.cx[b.curve_off[c], cols] for c in curves], axis=0)
        last_x = np.min([b.cx[b.curve_off[c + 1] - 1, cols] for c in curves], axis=0)
        first_end, last_end = ENDS_OF[int(b.material[s])]
        if first_end:
            out[s] += np.where(-max_crush[s] < first_x, PAST_FIRST, 0.0)
        if last_end:
            past = max_elongation[s] > last_x
            if int(b.material[s]) == GENERAL:
                past &= np.isneginf(b.yield_c[s, cols])  # never yields in compression: a stretch stays on L
            out[s] += np.where(past, PAST_LAST, 0.0)
    return out


BLOCK = 1_000_000  # variants read at once


def warnings_of(nc: Any) -> list[str]:
    """One line per spring of a result store that went past a curve end in some variant. ``nc``: the store
    read through the netCDF4 API (:meth:`crashstudy.results.reader.Results.stored`)."""
    if "past_curve_end" not in nc.variables:
        return []
    springs = stored_ids(nc, "spring")
    n = len(nc.dimensions["variant"])
    var = nc.variables["past_curve_end"]
    var.set_auto_mask(False)  # (variant, spring), NaN: failed
    counts = np.zeros((len(springs), 2), dtype=np.int64)
    for lo in range(0, n, BLOCK):  # block by block: bounded memory for any number of variants
        codes = np.asarray(var[lo : lo + BLOCK])
        counts[:, 0] += np.isin(codes, (1.0, 3.0)).sum(axis=0)
        counts[:, 1] += np.isin(codes, (2.0, 3.0)).sum(axis=0)
    out = []
    for k, spring in enumerate(springs):
        first, last = int(counts[k, 0]), int(counts[k, 1])
        said = [
            f"compressed past its curve's first point in {first}" if first else "",
            f"stretched past its last point in {last}" if last else "",
        ]
        if first or last:
            out.append(
                f"spring {spring} was " + " and ".join(t for t in said if t) + f" of {n} variants: its force "
                "there is extrapolated along the curve's end segment (past_curve_end in the summary)"
            )
    return out
