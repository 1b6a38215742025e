"""Which variants and responses ``crashstudy report`` shows: the default responses, ``--variants`` (numbers,
ranges and the names worst/best/baseline), the baseline variant and the reproducible samples of large studies.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import pandas as pd

from crashstudy.analysis.plot import crash_node
from crashstudy.analysis.report_limits import criteria_columns
from crashstudy.errors import InputError, Problem

RESPONSES_MAX = 6  # default responses (parallel coordinates, anthill plots)
CHOSEN_MAX = 12  # variants whose histories are drawn
SAMPLE_SEED = 0


def fail(where: str, field: str, message: str) -> InputError:
    return InputError([Problem(where, None, field, message)])


def default_responses(summary: pd.DataFrame, ds: Any) -> list[str]:
    """The crash node's peak deceleration in g, then the criteria (not their times), at most RESPONSES_MAX."""
    out = []
    node = crash_node(ds)
    if node and f"peak_deceleration_g.{node}" in summary:
        out.append(f"peak_deceleration_g.{node}")
    out += [c for c in criteria_columns(summary) if c.split(".", 1)[0] not in ("peak_g", "delta_v")]
    if len(out) < 2:
        out += [c for c in summary.columns if c.startswith("peak_force.") and summary[c].notna().any()][:2]
    return list(dict.fromkeys(out))[:RESPONSES_MAX]


def parse_variants(text: str, n: int, named: dict[str, int | None], where: str) -> list[int]:
    """``--variants``: comma-separated variant numbers, ranges ``A-B`` and the names in ``named``."""
    out: list[int] = []
    for part in (p.strip() for p in text.split(",")):
        if not part:
            continue
        if part in named:
            if named[part] is not None:
                out.append(int(named[part]))  # type: ignore[arg-type]
            continue
        lo, dash, hi = part.partition("-")
        try:
            a, b = int(lo), int(hi) if dash else int(lo)
        except ValueError:
            raise fail(
                where,
                "--variants",
                f"{part!r} is not a variant number, a range A-B or one of {', '.join(named)}",
            ) from None
        if not (0 <= a <= b < n):
            raise fail(where, "--variants", f"{part!r}: variants are numbered 0 to {n - 1}")
        out.extend(range(a, b + 1))
    out = list(dict.fromkeys(out))
    if len(out) > CHOSEN_MAX:
        raise fail(
            where, "--variants", f"{len(out)} variants chosen; at most {CHOSEN_MAX} histories are drawn"
        )
    return out


def baseline(summary: pd.DataFrame, axes: list[str], ok: np.ndarray) -> int | None:
    """The ok variant nearest the middle of every axis range (axes scaled to [0, 1])."""
    if not ok.any():
        return None
    if not axes:
        return int(summary["variant"].to_numpy()[np.argmax(ok)])
    x = summary[axes].to_numpy(dtype=float)
    span = np.nanmax(x, axis=0) - np.nanmin(x, axis=0)
    z = (x - np.nanmin(x, axis=0)) / np.where(span > 0, span, 1.0)
    d = np.where(ok, ((z - 0.5) ** 2).sum(axis=1), np.inf)
    return int(summary["variant"].to_numpy()[int(np.argmin(d))])


def sample(index: np.ndarray, limit: int, keep: Sequence[int] = ()) -> np.ndarray:
    if len(index) <= limit:
        return index
    rng = np.random.default_rng(SAMPLE_SEED)
    kept = np.intersect1d(index, np.asarray(keep, dtype=int))
    rest = np.setdiff1d(index, kept)
    pick = rng.choice(rest, size=max(0, limit - len(kept)), replace=False)
    return np.sort(np.concatenate([kept, pick]))
