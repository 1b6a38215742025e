"""The sections of ``crashstudy report`` drawn from the files other commands write beside the results:
``correlation.csv`` (``crashstudy correlate``), ``sensitivity.csv`` (``crashstudy sensitivity``),
``optimum.yaml`` + ``history.csv`` (``crashstudy optimize``) and ``calibrated.yaml`` (``crashstudy
calibrate``). Each is read as a regular file of bounded size only (:func:`safefs.open_regular`); one that
cannot be parsed is an input error naming it (exit 2), never a traceback.
"""

from __future__ import annotations

import io
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import yaml

from crashstudy.analysis import report_figures as rf
from crashstudy.analysis.report_page import esc, html_table
from crashstudy.errors import InputError, Problem
from crashstudy.safefs import PlantedEntryError, open_regular

FILE_MAX = 512 * 2**20  # bytes of one derived file read (history.csv of a long search stays far below)
CORRELATION_SHOWN = 20  # rows of the correlation table (best R first)


def _read(res: Any, name: str, where: str) -> bytes | None:
    try:
        with open_regular(Path(res.dir) / name, FILE_MAX, what=name) as fh:
            return fh.read()
    except FileNotFoundError:
        return None
    except PlantedEntryError as exc:
        raise InputError([Problem(where, None, name, str(exc))]) from None


def _csv(res: Any, name: str, where: str, needed: set[str]) -> pd.DataFrame | None:
    raw = _read(res, name, where)
    if raw is None:
        return None
    try:
        df = pd.read_csv(io.BytesIO(raw))
    except (ValueError, UnicodeDecodeError, pd.errors.ParserError) as exc:
        raise InputError(
            [Problem(f"{where}/{name}", 1, "", f"not a CSV table ({type(exc).__name__})")]
        ) from None
    missing = needed - set(df.columns)
    if missing:
        raise InputError(
            [
                Problem(
                    f"{where}/{name}",
                    1,
                    "",
                    f"expected the columns {', '.join(sorted(needed))}; missing {', '.join(sorted(missing))}",
                )
            ]
        )
    return df


def _yaml(res: Any, name: str, where: str) -> dict[str, Any] | None:
    raw = _read(res, name, where)
    if raw is None:
        return None
    try:
        data = yaml.safe_load(raw.decode("utf-8"))
    except (yaml.YAMLError, UnicodeDecodeError) as exc:
        line = getattr(getattr(exc, "problem_mark", None), "line", None)
        raise InputError(
            [Problem(f"{where}/{name}", None if line is None else line + 1, "", "not a YAML mapping")]
        ) from None
    if not isinstance(data, dict):
        raise InputError([Problem(f"{where}/{name}", 1, "", "expected a YAML mapping")])
    return data


def read_correlation(res: Any, where: str) -> pd.DataFrame | None:
    """``correlation.csv`` indexed by variant (R, Z, EP, EM, ES, grade), or None."""
    df = _csv(res, "correlation.csv", where, {"variant", "R", "Z", "EP", "EM", "ES", "grade"})
    return None if df is None else df.set_index("variant", drop=False)


def _flat(d: Any, prefix: str = "") -> list[tuple[str, str]]:
    if isinstance(d, dict):
        return [kv for k, v in d.items() for kv in _flat(v, f"{prefix}{k}.")]
    if isinstance(d, list):
        return [(prefix[:-1], ", ".join(f"{x:.6g}" if isinstance(x, float) else str(x) for x in d))]
    return [(prefix[:-1], f"{d:.6g}" if isinstance(d, float) else str(d))]


def correlation_section(rep: Any) -> str:
    df = rep.correlation.sort_values("R", ascending=False)
    cols = [c for c in ("variant", *rep.axes, "R", "Z", "EP", "EM", "ES", "grade") if c in df]
    rows = [
        [f"{v:.4g}" if isinstance(v, float) else v for v in r]
        for r in df[cols].head(CORRELATION_SHOWN).itertuples(index=False, name=None)
    ]
    grades = ", ".join(f"{k}: {v}" for k, v in df["grade"].astype(str).value_counts().items())
    fig = rf.bars(
        [f"variant {v}" for v in df["variant"].head(CORRELATION_SHOWN)][::-1],
        df["R"].head(CORRELATION_SHOWN).to_numpy(dtype=float)[::-1],
        None,
        "R (ISO/TS 18571) [-]",
        "overall rating R of the best-rated variants",
    )
    return (
        f"<p>ISO/TS 18571 ratings of {len(df)} variants against the test curve (correlation.csv; grades {esc(grades)}"
        "; R = 0.4 Z + 0.2 EP + 0.2 EM + 0.2 ES, all [-]). Best first:</p>"
        + html_table(cols, rows, text_cols=(len(cols) - 1,))
        + rep.figures.div(fig, 120 + 22 * len(rows))
    )


def sensitivity_section(rep: Any, df: pd.DataFrame) -> str:
    out = ""
    for metric, part in df.groupby("metric", sort=False):
        unit = rf.label(str(metric), _unit_of(rep, str(metric)))
        groups = (
            part["group"].astype(object).where(part["group"].notna(), "")
            if "group" in part
            else [""] * len(part)
        )
        names = [
            f"{g}: {a}" if isinstance(g, str) and g else str(a)
            for g, a in zip(groups, part["axis"], strict=True)
        ]
        conf = part["confidence"].to_numpy(dtype=float) if "confidence" in part else None
        fig = rf.bars(
            names,
            part["value"].to_numpy(dtype=float),
            conf,
            "index [-] (error bars: confidence)",
            f"sensitivity of {unit}",
            group=[str(i) for i in part["index"]],
        )
        out += rep.figures.div(fig, 140 + 34 * len(part))
        rows = [
            (n, i, f"{v:.4g}", "-" if not np.isfinite(c) else f"{c:.3g}")
            for n, i, v, c in zip(
                names, part["index"], part["value"], part.get("confidence", np.nan), strict=True
            )
        ]
        out += html_table(["axis", "index", "value", "confidence (95 %)"], rows, text_cols=(0, 1))
    return (
        "<p>sensitivity.csv (crashstudy sensitivity): indices of each metric to each axis, with their 95 % "
        "confidence half-widths.</p>" + out
    )


def _unit_of(rep: Any, column: str) -> str:
    base = column.split(".", 1)[0]
    return str(rep.ds[base].attrs.get("units", "")) if base in rep.ds.variables else ""


def optimisation_section(rep: Any, opt: dict[str, Any] | None, hist: pd.DataFrame | None) -> str:
    out = ""
    if opt is not None:
        rows = [(k, v) for k, v in _flat(opt)]
        out += "<p>optimum.yaml (crashstudy optimize):</p>" + html_table(["", ""], rows, text_cols=(0, 1))
    if hist is not None and len(hist):
        objective = next(iter((opt or {}).get("objective", {}) or {}), None) or next(
            (c for c in hist.columns if "." in c), None
        )
        if objective is not None and objective in hist:
            y = hist[objective].to_numpy(dtype=float)
            feasible = hist["feasible"].astype(str).str.lower().isin(["true", "1"]).to_numpy()
            best = np.fmin.accumulate(np.where(feasible, y, np.inf))
            best[~np.isfinite(best)] = np.nan
            fig = rf.optimisation_history(
                np.arange(len(y)),
                y,
                feasible,
                best,
                "candidate [-] (in order of evaluation)",
                rf.label(objective, _unit_of(rep, objective)),
                f"optimisation history: {len(y)} candidates, {int(feasible.sum())} feasible",
            )
            out += rep.figures.div(fig, 420)
    return out


def calibration_section(rep: Any, cal: dict[str, Any]) -> str:
    rows = [(k, v) for k, v in _flat(cal)]
    return (
        "<p>calibrated.yaml (crashstudy calibrate; calibration.png beside it draws data and fit):</p>"
        + html_table(["", ""], rows, text_cols=(0, 1))
    )


def sections(rep: Any) -> list[tuple[str, str, str]]:
    out = []
    if rep.correlation is not None:
        out.append(("correlation", "Correlation with the test (ISO/TS 18571)", correlation_section(rep)))
    sens = _csv(rep.res, "sensitivity.csv", rep.where, {"metric", "axis", "index", "value"})
    if sens is not None and len(sens):
        out.append(("sensitivity", "Sensitivity", sensitivity_section(rep, sens)))
    opt = _yaml(rep.res, "optimum.yaml", rep.where)
    hist = _csv(rep.res, "history.csv", rep.where, {"feasible"})
    if opt is not None or hist is not None:
        out.append(("optimisation", "Optimisation", optimisation_section(rep, opt, hist)))
    cal = _yaml(rep.res, "calibrated.yaml", rep.where)
    if cal is not None:
        out.append(("calibration", "Calibration", calibration_section(rep, cal)))
    return out
