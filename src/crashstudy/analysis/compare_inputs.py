"""The two sides of a regression comparison: opening result folders, their damage, the study's
tolerances and the keys that match variants (used by :mod:`crashstudy.analysis.compare`)."""

from __future__ import annotations

import difflib
import json
import math
import os
import re
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from pydantic import TypeAdapter, ValidationError

from crashstudy.errors import InputError, Problem
from crashstudy.results import integrity
from crashstudy.results.store import FINAL, PARTIAL, Results
from crashstudy.results.zarr_file import ZARR_FINAL, ZARR_PARTIAL
from crashstudy.schema.study import Tolerance
from crashstudy.schema.yamlio import format_path, loads_yaml

DEFAULT_RTOL = 1e-6  #: relative tolerance of a metric the ``regression:`` block does not name
DEFAULT_ATOL = 0.0  #: absolute tolerance of a metric the ``regression:`` block does not name
NOT_COMPARED = ("variant", "dt", "dt_crit")  #: numeric bookkeeping columns left out by default
#: Smallest ``atol`` of a column the ``regression:`` block does not name. ``energy_error`` is a
#: round-off residual (1e-14 in a conservative model): its relative change means nothing below this.
ATOL_FLOOR = {"energy_error": 1e-9}
TEXT_COLUMNS = ("status", "failure_reason", "dt_control")
JUNIT_SUITE = "crashstudy compare"
JUNIT_LIST = 10  #: variants listed in a JUnit failure

ResultsLike = Results | str | os.PathLike[str]
WHOLE_ROWS = (
    200_000  #: summary rows up to which compare reads both tables whole (and keeps per-variant arrays)
)


@dataclass
class _Side:
    """One result folder as the comparison sees it: its summary is read whole only when asked for
    (:attr:`summary`); a large one is read block by block (:mod:`crashstudy.analysis.compare_stream`)."""

    dir: Path
    res: Results
    axes: list[str]
    attrs: dict[str, Any]
    role: str
    n_variants: int
    rows: int  # rows of its summary table
    whole: pd.DataFrame | None = None

    @classmethod
    def read(cls, res: ResultsLike, role: str) -> _Side:
        res = res if isinstance(res, Results) else load_results(res, role)
        try:
            with res.raw_dataset as raw:  # the attributes and the size only: no variable read
                attrs, size = dict(raw.attrs), raw.sizes.get("variant")
            rows = res.summary_rows()
            n_variants = int(rows if size is None else size)
        except (OSError, ValueError, KeyError) as exc:
            raise _unreadable(res, role, exc) from None
        axes = list(json.loads(attrs.get("crashstudy_axes", "[]")))
        return cls(res.dir, res, axes, attrs, role, n_variants, rows)

    @property
    def summary(self) -> pd.DataFrame:
        """The summary table, whole (read on first use)."""
        if self.whole is None:
            try:
                self.whole = self.res.summary
            except (OSError, ValueError, KeyError) as exc:
                raise _unreadable(self.res, self.role, exc) from None
        return self.whole

    @property
    def large(self) -> bool:
        """Whether its summary has more than :data:`WHOLE_ROWS` rows (read block by block where it can)."""
        return self.rows > WHOLE_ROWS

    def head(self) -> pd.DataFrame:
        """The summary's first rows (its columns and their types), the whole table when it is read whole."""
        if self.whole is not None or not self.large:
            return self.summary
        blocks = self.res.summary_batches(rows=1)
        try:
            return next(blocks)
        finally:
            blocks.close()

    @property
    def damage(self) -> str:
        """Why the summary does not list each variant of results.nc once ("" if it does)."""
        source = self.res.summary_source
        if self.whole is not None:
            return _damage(
                [self.whole["variant"]] if "variant" in self.whole else [], self.n_variants, self.role, source
            )
        if (
            self.rows == self.n_variants
        ):  # numbered 0, 1, ... in order (as a run writes it): checked per block
            blocks, lo = self.res.summary_batches(["variant"]), 0
            try:
                for b in blocks:
                    if not np.array_equal(b["variant"].to_numpy(), np.arange(lo, lo + len(b))):
                        break
                    lo += len(b)
            finally:
                blocks.close()
            if lo == self.rows:
                return ""
        blocks = self.res.summary_batches(["variant"])
        try:
            return _damage((b["variant"] for b in blocks), self.n_variants, self.role, source)
        finally:
            blocks.close()

    @property
    def study_name(self) -> str:
        title = str(self.attrs.get("title", ""))
        return title.removeprefix("crashstudy results of ") or self.dir.name


def _unreadable(res: Results, role: str, exc: Exception) -> InputError:
    return InputError([Problem(str(res.dir), None, "", f"cannot read the {role} results: {exc}")])


def _damage(variants: Iterable[pd.Series], n_variants: int, role: str, source: str = "summary.csv") -> str:
    """Why the ``variant`` column (given in blocks) does not list each of the ``n_variants`` variants of
    results.nc once ("" if it does); one byte per variant of results.nc."""
    seen, rows = np.zeros(n_variants, dtype=bool), 0
    for raw in variants:
        numbers = pd.to_numeric(raw, errors="coerce").to_numpy(dtype=np.float64)
        rows += len(numbers)
        with np.errstate(invalid="ignore"):
            ours = (
                np.isfinite(numbers)
                & (numbers >= 0)
                & (numbers < n_variants)
                & (numbers == np.floor(numbers))
            )
        seen[numbers[ours].astype(np.int64)] = True
    missing = np.flatnonzero(~seen)
    if not len(missing) and rows == n_variants:
        return ""
    shown = ", ".join(str(int(v)) for v in missing[:10]) + (", ..." if len(missing) > 10 else "")
    what = f"; missing: variants {shown}" if len(missing) else f"; {rows} rows (rows repeated or foreign)"
    return (
        f"the {role} {source} lists {int(seen.sum())} of the "
        f"{n_variants} variants in its results.nc{what}: the result folder is damaged"
    )


_XML_BAD = re.compile("[^\t\n\r\x20-\ud7ff\ue000-\ufffd\U00010000-\U0010ffff]")


def _xml_text(s: str) -> str:
    """Drop the characters XML 1.0 cannot hold (ElementTree escapes the rest)."""
    return _XML_BAD.sub("?", s)


def load_results(directory: str | os.PathLike[str], role: str = "result") -> Results:
    """Open a result folder, or raise :class:`InputError` saying why it holds no results."""
    d = Path(directory)
    if not d.is_dir():
        msg = "is a file, not a result folder" if d.exists() else "result folder not found"
        raise InputError([Problem(str(d), None, "", f"{role}: {msg}")])
    final = integrity.final_name(d)
    if not (d / final).is_file() and not (final == ZARR_FINAL and (d / final).is_dir()):
        partial = next((p for p in (PARTIAL, ZARR_PARTIAL) if (d / p).exists()), None)
        why = (
            f"the run did not finish (only {partial}); finish it with `crashstudy run STUDY -o {d} --resume`"
            if partial
            else f"no {FINAL} here: not a result folder (write one with `crashstudy run STUDY -o {d}`)"
        )
        raise InputError([Problem(str(d), None, "", f"{role}: {why}")])
    return Results(d)


def study_tolerances(attrs: dict[str, Any]) -> dict[str, Tolerance]:
    """The ``regression:`` tolerances a result stores (its ``regression`` attribute, validated when the
    study was loaded); results written before that attribute existed: the block of the stored study."""
    if "regression" in attrs:
        return {k: Tolerance(**v) for k, v in json.loads(str(attrs["regression"])).items()}
    text = str(attrs.get("study_yaml", "") or "")
    if not text.strip():
        return {}
    file = str(attrs.get("study_file", "") or "<study_yaml>")
    doc = loads_yaml(text, file=file)
    block = doc.data.get("regression") or {}
    try:
        return TypeAdapter(dict[str, Tolerance]).validate_python(block)
    except ValidationError as exc:
        problems = []
        for err in exc.errors():
            loc = ("regression", *(p for p in err["loc"] if isinstance(p, (str, int))))
            problems.append(Problem(file, doc.line_of(loc), format_path(loc), err["msg"]))
        raise InputError(problems) from None


def _round_key(x: pd.Series) -> np.ndarray:
    """Axis values rounded to about 12 significant digits, so that text round-trips still match."""
    m, e = np.frexp(pd.to_numeric(x, errors="coerce").to_numpy(dtype=np.float64))
    return np.ldexp(np.round(m * 2.0**40) / 2.0**40, e)


def _keys(df: pd.DataFrame, axes: list[str]) -> pd.DataFrame:
    """Match key of every row: rounded axis values (NaN for an axis this side lacks), the
    occurrence number among equal values, and the row number."""
    keys = pd.DataFrame(
        {f"_k{i}": _round_key(df[ax]) if ax in df else np.nan for i, ax in enumerate(axes)}, index=df.index
    )
    keys["_dup"] = keys.groupby(list(keys.columns), dropna=False).cumcount() if axes else np.arange(len(df))
    keys["_row"] = np.arange(len(df))
    return keys.reset_index(drop=True)


def _axis_frame(df: pd.DataFrame, rows: np.ndarray, axes: list[str]) -> pd.DataFrame:
    return pd.DataFrame(
        {ax: df[ax].to_numpy()[rows] if ax in df else np.full(len(rows), np.nan) for ax in axes}
    )


def _metric_columns(df: pd.DataFrame, axes: list[str], named: set[str]) -> list[str]:
    skip = set(axes) | set(TEXT_COLUMNS) | (set(NOT_COMPARED) - named)
    return [
        c
        for c in df.columns
        if c not in skip and pd.api.types.is_numeric_dtype(df[c]) and not pd.api.types.is_bool_dtype(df[c])
    ]


def _tolerance_for(
    col: str, tolerances: dict[str, Tolerance], rtol: float, atol: float
) -> tuple[float, float]:
    t = tolerances.get(col) or tolerances.get(col.split(".", 1)[0])
    return (t.rtol, t.atol) if t is not None else (rtol, max(atol, ATOL_FLOOR.get(col, 0.0)))


def _check_keys(tolerances: dict[str, Tolerance], columns: set[str], attrs: dict[str, Any]) -> None:
    names = columns | {c.split(".", 1)[0] for c in columns}
    bad = [k for k in tolerances if k not in names]
    if not bad:
        return
    file = str(attrs.get("study_file", "") or "<study_yaml>")
    doc = loads_yaml(str(attrs.get("study_yaml", "") or "{}"), file=file)
    problems = []
    for k in bad:
        close = difflib.get_close_matches(k, sorted(names), n=3, cutoff=0.5)
        hint = f"; did you mean {', '.join(close)}?" if close else f"; metrics: {', '.join(sorted(names))}"
        problems.append(
            Problem(
                file,
                doc.line_of(("regression", k)),
                f"regression.{k}",
                f"no summary metric or column {k!r} in the results{hint}",
            )
        )
    raise InputError(problems)


def check_tolerance(name: str, value: Any, option: str | None = None) -> float:
    """``value`` as a float if it is a finite number >= 0, else an :class:`InputError` naming ``option``."""
    try:
        number = float(value)
    except (TypeError, ValueError):
        number = math.nan
    if not (math.isfinite(number) and number >= 0):
        raise InputError(
            [
                Problem(
                    "crashstudy compare",
                    None,
                    option or name,
                    f"expected a finite number >= 0 for the {name}, got {value!r}",
                )
            ]
        )
    return number
