"""The usual limits a crash engineer holds the criteria against (for ``crashstudy report``), and the
optimisation constraints of a study: which variant passes which check.

Each limit names the document it comes from. They are the common reference values for a 50th-percentile
adult male occupant (or a seated aircrew member for DRI), not a rating: a report says "above the usual
limit", never "unsafe".
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd

from crashstudy.errors import InputError, Problem
from crashstudy.schema.study import CONSTRAINT


@dataclass(frozen=True)
class Limit:
    value: float
    unit: str  # "1" = dimensionless
    source: str


#: criterion (summary column name before the dot) -> its usual upper limit
LIMITS: dict[str, Limit] = {
    "hic15": Limit(
        700.0, "1", "FMVSS 208 S6.2 (49 CFR 571.208), Hybrid III 50th male; also Euro NCAP/ECE R94 upper"
    ),
    "hic36": Limit(1000.0, "1", "FMVSS 208 before 2000 (HIC36), ECE R94 HPC 1000"),
    "clip3ms": Limit(60.0, "g", "FMVSS 208 S6.3 chest resultant, 3 ms clip, Hybrid III 50th male"),
    "clip3ms_cumulative": Limit(60.0, "g", "FMVSS 208 S6.3 (cumulative 3 ms wording)"),
    "olc": Limit(25.0, "g", "Euro NCAP MPDB assessment protocol: OLC modifier from 25 g (full at 40 g)"),
    "dri": Limit(18.0, "1", "MIL-S-9479 ejection seats, DRI 18 ~ 5 % spinal injury risk (AGARD-AR-330)"),
}
NO_LIMIT = {
    "peak_g": "SAE J211-1 filtered peak; no single limit (pulse-dependent)",
    "delta_v": "severity measure of the impact; no limit",
}
CRITERIA = ("peak_g", "hic15", "hic36", "clip3ms", "clip3ms_cumulative", "olc", "dri", "delta_v")


@dataclass(frozen=True)
class Check:
    """``column op value``: a limit or an optimisation constraint; ``source`` says which."""

    column: str
    op: str  # "<=" or ">="
    value: float
    source: str

    def passes(self, values: np.ndarray) -> np.ndarray:
        """True where the check holds (NaN, a failed variant, never passes)."""
        with np.errstate(invalid="ignore"):
            return values <= self.value if self.op == "<=" else values >= self.value

    @property
    def text(self) -> str:
        return f"{self.column} {self.op} {self.value:g}"


def criteria_columns(summary: pd.DataFrame) -> list[str]:
    """The criteria columns of a summary (``hic15.occupant``, ...), in :data:`CRITERIA` order."""
    cols = [c for c in summary.columns if "." in c]
    return [c for name in CRITERIA for c in cols if c.split(".", 1)[0] == name]


def limit_checks(columns: list[str]) -> list[Check]:
    return [
        Check(c, "<=", LIMITS[c.split(".", 1)[0]].value, LIMITS[c.split(".", 1)[0]].source)
        for c in columns
        if c.split(".", 1)[0] in LIMITS
    ]


def constraint_checks(study: dict, columns: list[str]) -> list[Check]:
    """The ``optimize.constraints`` of a study (as its YAML loads) on columns the summary has."""
    opt = study.get("optimize") if isinstance(study, dict) else None
    out = []
    for text in (opt or {}).get("constraints", []) if isinstance(opt, dict) else []:
        m = CONSTRAINT.match(str(text))
        if not m or m.group(1) not in columns:
            continue
        try:
            value = float(m.group(3))
        except ValueError:
            continue
        out.append(Check(m.group(1), m.group(2), value, "the study's optimize: constraints"))
    return out


def user_checks(texts: Sequence[str], columns: list[str], where: str) -> list[Check]:
    """``--limits 'COLUMN<=NUMBER' ...``: the user's own checks (the optimize: constraint syntax)."""
    out = []
    for text in texts:
        m = CONSTRAINT.match(str(text))
        value = _number(m.group(3)) if m else None
        if m is None or value is None or m.group(1) not in columns:
            why = (
                f"{m.group(1)!r} is not a summary column"
                if m and value is not None and m.group(1) not in columns
                else "expected COLUMN<=NUMBER or COLUMN>=NUMBER"
            )
            raise InputError([Problem(where, None, "--limits", f"{text!r}: {why}")])
        out.append(Check(m.group(1), m.group(2), value, "--limits"))
    return out


def _number(text: str) -> float | None:
    try:
        value = float(text)
    except ValueError:
        return None
    return value if np.isfinite(value) else None


def passes_all(summary: pd.DataFrame, checks: list[Check]) -> np.ndarray:
    """Per row: True when every check holds."""
    ok = np.ones(len(summary), dtype=bool)
    for c in checks:
        ok &= c.passes(np.asarray(summary[c.column], dtype=float))
    return ok
