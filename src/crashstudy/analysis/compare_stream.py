"""``crashstudy compare`` of two large results block by block (issue 19): when both summaries list the same
axis values in the same order (a study re-run against its baseline), row i of one matches row i of the
other, so the two tables are read row group by row group side by side, and only what the report needs
is kept (:class:`~crashstudy.analysis.compare_values.ColumnStats` per column, the status changes' count
and first rows): memory bounded by a block, whatever the number of variants. Results in another order
or with other variants are matched by their axis values over the whole tables up to the row count
:attr:`Results.summary <crashstudy.results.reader.Results.summary>` reads whole, and beyond it in parts
split by a hash of their keys (:mod:`crashstudy.analysis.compare_match`)."""

from __future__ import annotations

from collections.abc import Iterator
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from crashstudy.analysis.compare_inputs import _round_key, _Side
from crashstudy.analysis.compare_values import STATUS_KEPT, ColumnStats, _Column, empty_lists, status_rows

if TYPE_CHECKING:
    from collections.abc import Iterable


def aligned(
    a: Iterable[pd.DataFrame], b: Iterable[pd.DataFrame]
) -> Iterator[tuple[pd.DataFrame, pd.DataFrame]]:
    """Pairs of blocks of the same rows of two tables read block by block (their blocks may differ)."""
    ia, ib = iter(a), iter(b)
    ra: pd.DataFrame | None = None
    rb: pd.DataFrame | None = None
    while True:
        while ra is None or not len(ra):
            ra = next(ia, None)
            if ra is None:
                return
        while rb is None or not len(rb):
            rb = next(ib, None)
            if rb is None:
                return
        k = min(len(ra), len(rb))
        yield ra.iloc[:k], rb.iloc[:k]
        ra, rb = ra.iloc[k:], rb.iloc[k:]


def same_order(new: _Side, base: _Side, axes: list[str]) -> str:
    """ "" when both summaries list the same (rounded) axis values in the same order, so that matching by
    axis values pairs row i with row i; else what differs. Read block by block (the axis columns only)."""
    if new.rows != base.rows:
        return f"the new summary has {new.rows} rows, the baseline's {base.rows}"
    lacking = [ax for ax in axes if ax not in new.axes or ax not in base.axes]
    if lacking:
        return f"the axes {lacking} are not in both results"
    cols = axes or ["variant"]
    lo = 0
    for bn, bb in aligned(new.res.summary_batches(cols), base.res.summary_batches(cols)):
        for ax in axes:
            kn, kb = _round_key(bn[ax]), _round_key(bb[ax])
            differ = ~((kn == kb) | (np.isnan(kn) & np.isnan(kb)))
            if differ.any():
                k = int(np.argmax(differ))
                return (
                    f"row {lo + k}: {ax} is {float(bn[ax].iloc[k]):.12g} in the new summary, "
                    f"{float(bb[ax].iloc[k]):.12g} in the baseline's"
                )
        lo += len(bn)
    return ""


def streamed(
    new: _Side, base: _Side, axes: list[str], tolerances: dict[str, tuple[float, float]]
) -> dict[str, Any]:
    """The fields of a :class:`~crashstudy.analysis.compare.Comparison` of two summaries in the same order
    (:func:`same_order`), read side by side block by block; ``tolerances``: column -> (rtol, atol)."""
    stats = {c: ColumnStats(*t) for c, t in tolerances.items()}
    common = list(tolerances)
    cols_new = list(dict.fromkeys([*axes, "variant", "status", "failure_reason", *common]))
    cols_base = list(dict.fromkeys(["variant", "status", *common]))
    status: list[pd.DataFrame] = []
    n_status = n_failures = lo = kept = 0
    for bn, bb in aligned(new.res.summary_batches(cols_new), base.res.summary_batches(cols_base)):
        rows = pd.DataFrame({ax: bn[ax].to_numpy() for ax in axes})
        rows["variant"] = bn["variant"].to_numpy().astype(int)
        rows["baseline_variant"] = bb["variant"].to_numpy().astype(int)
        reason = bn["failure_reason"].astype(object).fillna("").astype(str).to_numpy()
        st = status_rows(
            rows, bb["status"].astype(str).to_numpy(), bn["status"].astype(str).to_numpy(), reason
        )
        n_status += len(st)
        n_failures += int((~st["passed"]).sum())
        if len(st) and kept < STATUS_KEPT:
            status.append(st.head(STATUS_KEPT - kept))
            kept += len(status[-1])
        for c in common:
            old = pd.to_numeric(bb[c], errors="coerce").to_numpy(dtype=np.float64)
            nw = pd.to_numeric(bn[c], errors="coerce").to_numpy(dtype=np.float64)
            stats[c].add(_Column(old, nw, *tolerances[c]), rows, lo)
        lo += len(bn)
    return {
        **empty_lists(axes),
        **({"status": pd.concat(status, ignore_index=True)} if status else {}),
        "stats": stats,
        "n_matched": lo,
        "n_status": n_status,
        "n_status_failures": n_failures,
    }


def streamed_if_large(
    new: _Side, base: _Side, axes: list[str], tolerances: dict[str, tuple[float, float]]
) -> dict[str, Any] | None:
    """The fields of a comparison read block by block when a summary has more than WHOLE_ROWS rows: side by
    side when both list their variants in the same order, else (beyond the rows Results.summary reads
    whole) split into parts by a hash of their keys (:func:`~crashstudy.analysis.compare_match.partitioned`);
    None when the tables are to be read whole."""
    from crashstudy.analysis.compare_match import partitioned

    if not (new.large or base.large):
        return None
    if not same_order(new, base, axes):
        return streamed(new, base, axes, tolerances)
    limits = [s.res.summary_limit for s in (new, base)]
    limit = min(x for x in limits if x is not None) if any(x is not None for x in limits) else None
    if limit is None or max(new.rows, base.rows) <= limit:
        return None
    return partitioned(new, base, axes, tolerances)
