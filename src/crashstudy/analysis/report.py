"""``crashstudy report DIR``: one self-contained HTML page of a result folder (SPEC 8d, docs/report.md).

The folder is read through :func:`crashstudy.open_results` (the one reader: manifest checked); the files
other commands write beside the results (``sensitivity.csv``, ``optimum.yaml``/``history.csv``,
``calibrated.yaml``, ``correlation.csv``) are read as regular files only (:func:`safefs.open_regular`),
each section present when its file is. The derived-file sections live in :mod:`.report_extra`.

Sampling: the scatter figures (parallel coordinates, anthill plots) draw every ok variant up to
:data:`SCATTER_MAX`, else a reproducible random sample of that size (said on the page); the table holds
every variant up to :data:`TABLE_MAX`, else a sample of that size that keeps every failed variant and the
chosen ones.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from datetime import datetime, timezone
from typing import Any

import numpy as np
import pandas as pd
import yaml

from crashstudy.analysis import report_figures as rf
from crashstudy.analysis.plot import crash_node, free_nodes, study_axes, study_name
from crashstudy.analysis.plot_style import axis_units, unit_text
from crashstudy.analysis.report_limits import (
    LIMITS,
    NO_LIMIT,
    Check,
    constraint_checks,
    criteria_columns,
    limit_checks,
    passes_all,
    user_checks,
)
from crashstudy.analysis.report_page import Figures, esc, html_table, interactive_table, page, table_data
from crashstudy.errors import InputError, Problem

SCATTER_MAX = 2000  # ok variants drawn in the parallel coordinates and anthill plots; more: a random sample
TABLE_MAX = 10_000  # rows of the summary table; more: a sample (every failed and chosen variant kept)
FAILURES_SHOWN = 200  # failed variants listed one by one
RESPONSES_MAX = 6  # default responses (parallel coordinates, anthill plots)
CHOSEN_MAX = 12  # variants whose histories are drawn
HISTORY_PLOTS = 3  # history figures (one per metric node)
SAMPLE_SEED = 0
TEXT_COLUMNS = ("status", "failure_reason", "dt_control", "criteria_note")


def _fail(where: str, field: str, message: str) -> InputError:
    return InputError([Problem(where, None, field, message)])


def _unit(ds: Any, column: str) -> str:
    base = column.split(".", 1)[0]
    if column in ds.variables:
        return str(ds[column].attrs.get("units", ""))
    return str(ds[base].attrs.get("units", "")) if base in ds.variables else ""


def _shown_unit(unit: str) -> str:
    return "-" if unit == "1" else unit


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
            raise _fail(where, "--variants", f"{part!r} is not a variant number, a range A-B or one of "
                        f"{', '.join(named)}") from None  # fmt: skip
        if not (0 <= a <= b < n):
            raise _fail(where, "--variants", f"{part!r}: variants are numbered 0 to {n - 1}")
        out.extend(range(a, b + 1))
    out = list(dict.fromkeys(out))
    if len(out) > CHOSEN_MAX:
        raise _fail(where, "--variants", f"{len(out)} variants chosen; at most {CHOSEN_MAX} histories are drawn")
    return out


def _baseline(summary: pd.DataFrame, axes: list[str], ok: np.ndarray) -> int | None:
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


def _sample(index: np.ndarray, limit: int, keep: Sequence[int] = ()) -> np.ndarray:
    if len(index) <= limit:
        return index
    rng = np.random.default_rng(SAMPLE_SEED)
    kept = np.intersect1d(index, np.asarray(keep, dtype=int))
    rest = np.setdiff1d(index, kept)
    pick = rng.choice(rest, size=max(0, limit - len(kept)), replace=False)
    return np.sort(np.concatenate([kept, pick]))


class Report:
    """Gathers what the page shows; :meth:`html` renders it."""

    def __init__(self, res: Any, variants: str | None = None, responses: Sequence[str] | None = None,
                 test: tuple[np.ndarray, np.ndarray] | None = None, where: str = "",
                 limits: Sequence[str] = ()) -> None:  # fmt: skip
        self.res, self.where = res, where or str(res.dir)
        self.ds = res.dataset
        self.summary = res.summary.reset_index(drop=True)
        self.axes = study_axes(self.ds)
        self.units = axis_units(self.ds, self.axes)
        self.ok = self.summary["status"].astype(str).to_numpy() == "ok"
        self.study = self._study_dict()
        cols = list(self.summary.columns)
        if responses:
            unknown = [r for r in responses if r not in cols]
            if unknown:
                raise _fail(self.where, "--responses", f"no summary column {', '.join(map(repr, unknown))}; "
                            "columns: see `crashstudy summary DIR --variant 0`")  # fmt: skip
            self.responses = list(responses)
        else:
            self.responses = default_responses(self.summary, self.ds)
        self.criteria = criteria_columns(self.summary)
        self.checks: list[Check] = user_checks(limits, cols, self.where) + constraint_checks(self.study, cols)
        self.checks += limit_checks([c for c in self.criteria if c in self.responses])
        self.key = self.responses[0] if self.responses else None
        self.named = self._named()
        n = len(self.summary)
        self.chosen = (parse_variants(variants, n, self.named, self.where) if variants
                       else list(dict.fromkeys(v for v in self.named.values() if v is not None)))  # fmt: skip
        self.test = test
        self.figures = Figures()
        self.notes: list[str] = []

    def _study_dict(self) -> dict[str, Any]:
        try:
            loaded = yaml.safe_load(self.ds.attrs.get("study_yaml", "") or "{}")
        except yaml.YAMLError:
            return {}
        return loaded if isinstance(loaded, dict) else {}

    def _named(self) -> dict[str, int | None]:
        variant = self.summary["variant"].to_numpy()
        named: dict[str, int | None] = {"worst": None, "best": None, "baseline": _baseline(self.summary, self.axes, self.ok)}
        if self.key is not None:
            v = np.where(self.ok, self.summary[self.key].to_numpy(dtype=float), np.nan)
            if np.isfinite(v).any():
                named["worst"], named["best"] = int(variant[np.nanargmax(v)]), int(variant[np.nanargmin(v)])
        return named

    # --- sections -----------------------------------------------------------------------------------

    def study_section(self) -> str:
        a, s = self.ds.attrs, self.summary
        counts = s["status"].astype(str).value_counts()
        final = self.res.dir / "results.nc"
        written = datetime.fromtimestamp(os.stat(final).st_mtime, tz=timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
        kept = [v for v in ("acceleration", "velocity", "displacement", "position", "spring_force",
                            "spring_elongation", "filtered_acceleration", "wall_force") if v in self.ds.data_vars]  # fmt: skip
        rows = [("study", a.get("study_name", "-")), ("study file", a.get("study_file", "-")),
                ("model", f"{a.get('model_name', '-')} ({a.get('model_file', '-')})"),
                ("units", a.get("units", "-")), ("variants", f"{len(s)}"),
                ("by status", ", ".join(f"{k}: {v}" for k, v in counts.items())),
                ("histories kept", ", ".join(kept) or "none (output.histories: none)"),
                ("end time", f"{float(s['t_end'].max()):g} s" if "t_end" in s else "-"),
                ("run time", f"not recorded in the folder; results.nc written {written}"),
                ("crashstudy version", a.get("crashstudy_version", "-")),
                ("model sha256", a.get("model_sha256", "-")), ("study sha256", a.get("study_sha256", "-"))]  # fmt: skip
        out = html_table(["", ""], rows, text_cols=(0, 1))
        if self.axes:
            axrows = []
            for ax in self.axes:
                v = s[ax].to_numpy(dtype=float)
                axrows.append((ax, _shown_unit(self.units[ax]), f"{np.nanmin(v):.6g}", f"{np.nanmax(v):.6g}",
                               len(np.unique(v[np.isfinite(v)]))))  # fmt: skip
            out += "<h3>Axes</h3>" + html_table(["axis", "unit", "min", "max", "distinct values"], axrows, (0, 1))
        manifest = self.res.manifest or {}
        if manifest:
            mrows = [(k, v.get("size", "-"), v.get("sha256", "(results.nc: per-variant checksums inside)"))
                     for k, v in manifest.items() if isinstance(v, dict)]  # fmt: skip
            out += ("<h3>Files (manifest.json, run " + esc(a.get("run_id", "-")) + ")</h3>"
                    + html_table(["file", "bytes", "sha256"], mrows, (0, 2)))  # fmt: skip
        named = ", ".join(f"{k}: variant {v}" for k, v in self.named.items() if v is not None)
        if named:
            out += (f'<p class="note">Chosen variants ({esc(named)}): worst and best by {esc(self.key)}; baseline = '
                    "the ok variant nearest the middle of every axis range.</p>")  # fmt: skip
        return out

    def failures_section(self) -> str:
        s = self.summary[~self.ok]
        head = ["variant", *[f"{a} [{_shown_unit(self.units[a])}]" if self.units[a] else a for a in self.axes],
                "failure reason"]
        rows = [[int(r["variant"]), *[f"{r[a]:.6g}" for a in self.axes], r.get("failure_reason", "")]
                for _, r in s.head(FAILURES_SHOWN).iterrows()]  # fmt: skip
        more = f'<p class="note">and {len(s) - FAILURES_SHOWN} more (filter the table: status=failed)</p>' \
            if len(s) > FAILURES_SHOWN else ""  # fmt: skip
        kinds = s["failure_reason"].astype(str).str.replace(r"[-+]?\d[\d.]*(e[-+]?\d+)?", "#", regex=True)
        summary = "".join(f"<li>{v} x {esc(k)}</li>" for k, v in list(kinds.value_counts().items())[:10])
        return (f'<p class="bad">{len(s)} of {len(self.summary)} variants failed; reasons (numbers as #):</p><ul>{summary}</ul>'
                + html_table(head, rows, text_cols=(len(head) - 1,), cls="failures") + more)  # fmt: skip

    def table_section(self) -> str:
        s = self.summary
        extra = [c for c in s.columns if c.startswith("peak_deceleration_g.") and c.split(".", 1)[1] in free_nodes(self.ds)]
        cols = list(dict.fromkeys(["variant", *self.axes, "status", "failure_reason", *self.responses,
                                   *self.criteria, *extra, "energy_error"]))  # fmt: skip
        cols = [c for c in cols if c in s and not c.split(".", 1)[0].endswith(("_t1", "_t2"))]
        index = np.arange(len(s))
        keep = [int(i) for i in np.nonzero(~self.ok)[0]] + [int(np.nonzero(s["variant"].to_numpy() == v)[0][0]) for v in self.chosen]
        shown = _sample(index, TABLE_MAX, keep)
        note = (f"every variant ({len(s)})" if len(shown) == len(s) else
                f"a sample of {len(shown)} of {len(s)} variants (every failed and chosen variant, the rest at random "
                f"with seed {SAMPLE_SEED}; above {TABLE_MAX} variants the table is sampled: summary.parquet has all)")  # fmt: skip
        meta = [(c, "" if c in ("variant",) else _shown_unit(self.units.get(c) or _unit(self.ds, c)), c in TEXT_COLUMNS)
                for c in cols]  # fmt: skip
        sub = s.iloc[shown][cols]
        rows = [[None if isinstance(v, float) and not np.isfinite(v) else v for v in r]
                for r in sub.itertuples(index=False, name=None)]  # fmt: skip
        return (f'<p class="note">The table holds {esc(note)}. Click a heading to sort; the filter takes words and '
                "column comparisons such as <code>hic15&gt;700</code> or <code>status=failed</code>.</p>"
                + interactive_table(table_data(meta, rows)))  # fmt: skip

    def _scatter_index(self) -> np.ndarray:
        ok = np.nonzero(self.ok)[0]
        shown = _sample(ok, SCATTER_MAX)
        if len(shown) < len(ok):
            self.notes.append(f"scatter figures: a random sample of {len(shown)} of {len(ok)} ok variants "
                              f"(seed {SAMPLE_SEED}; above {SCATTER_MAX} they are sampled)")  # fmt: skip
        return shown

    def design_section(self) -> str:
        if not self.responses:
            return '<p class="note">No responses to draw.</p>'
        idx = self._scatter_index()
        s = self.summary.iloc[idx]
        passed = passes_all(s, self.checks) if self.checks else None
        cols = [(a, self.units[a], s[a].to_numpy(dtype=float)) for a in self.axes]
        cols += [(r, _unit(self.ds, r), s[r].to_numpy(dtype=float)) for r in self.responses]
        cb = (self.key, s[self.key].to_numpy(dtype=float)) if self.key else None
        sampled = f" (sample of {len(idx)} of {int(self.ok.sum())} ok variants)" if len(idx) < self.ok.sum() else ""
        out = ""
        if self.checks:
            npass = int(passes_all(self.summary[self.ok], self.checks).sum())
            out += (f"<p>Pass (green) = every check holds; fail (red) = at least one does not. {npass} of "
                    f"{int(self.ok.sum())} ok variants pass.</p><ul>"
                    + "".join(f"<li>{esc(c.text)}{esc(unit_text(_unit(self.ds, c.column)))} &mdash; "
                              f"{esc(c.source)}</li>" for c in self.checks) + "</ul>")  # fmt: skip
        else:
            out += "<p class=\"note\">No limits or constraints apply to these responses: lines coloured by " \
                   f"{esc(self.key)}.</p>"  # fmt: skip
        out += self.figures.div(rf.parcoords(cols, passed, cb, f"axes to responses{sampled}"), 460)
        if self.axes:
            out += "<h3>Each response against each axis</h3>"
            if self.checks:
                out += ('<p class="note">Green/red: the response\'s own limit or constraint (dashed line) holds or '
                        "not; a response without one is coloured by every check.</p>")
            for r in self.responses:
                own = [c for c in self.checks if c.column == r]
                colour = passes_all(s, own) if own else passed
                fig = rf.anthill(cols[: len(self.axes)], (r, _unit(self.ds, r), s[r].to_numpy(dtype=float)), colour,
                                 self.checks, f"{r}{sampled}")  # fmt: skip
                rows = (len(self.axes) + 2) // 3
                out += self.figures.div(fig, 300 * rows + 80)
        return out

    def criteria_section(self) -> str:
        rows, panels = [], []
        s = self.summary
        variant = s["variant"].to_numpy()
        for c in self.criteria:
            name, _, node = c.partition(".")
            if name.endswith(("_t1", "_t2")):
                continue
            v = np.where(self.ok, s[c].to_numpy(dtype=float), np.nan)
            if not np.isfinite(v).any():
                continue
            unit = _unit(self.ds, c)
            lim = LIMITS.get(name)
            over = int(np.nansum(v > lim.value)) if lim else 0
            std = str(self.ds[name].attrs.get("standard", "")) if name in self.ds.variables else ""
            rows.append((name, node, _shown_unit(unit), f"{np.nanmin(v):.4g}", f"{np.nanmedian(v):.4g}",
                         f"{np.nanmax(v):.4g}", int(variant[np.nanargmax(v)]),
                         f"{lim.value:g}" if lim else "-", f"{over} of {int(np.isfinite(v).sum())}" if lim else "-",
                         lim.source if lim else NO_LIMIT.get(name, "-"), std))  # fmt: skip
            panels.append((c, unit, v, lim.value if lim else None))
        if not rows:
            return ""
        head = ["criterion", "node", "unit", "min", "median", "max", "max in variant", "usual limit",
                "variants above", "limit from", "computed per"]  # fmt: skip
        out = html_table(head, rows, text_cols=(0, 1, 2, 9, 10))
        cols = min(len(panels), 3)
        out += self.figures.div(rf.criteria_histograms(panels, "criteria over the ok variants (red: usual limit)"),
                                280 * ((len(panels) + cols - 1) // cols) + 80)  # fmt: skip
        return out

    def history_section(self) -> str:
        from crashstudy.analysis.plot import history_values

        ds = self.ds
        plots: list[tuple[str, str]] = []
        if "filtered_acceleration" in ds.data_vars:
            fa = ds["filtered_acceleration"]
            first = fa.isel(variant=0)
            plots = [("filtered_acceleration", str(n)) for n in ds["node"].values
                     if np.isfinite(first.sel(node=n).values).any()]  # fmt: skip
        if not plots and "acceleration" in ds.data_vars:
            plots = [("acceleration", crash_node(ds) or free_nodes(ds)[0])]
        if not plots and "spring_force" in ds.data_vars:
            plots = [("spring_force", str(ds["spring"].values[0]))]
        if not plots or not self.chosen:
            return ""
        pos = {int(v): i for i, v in enumerate(self.summary["variant"].to_numpy())}
        t = np.asarray(ds["time"].values, dtype=float) * 1e3
        label_of = {v: k for k, v in self.named.items() if v is not None}
        corr = getattr(self, "correlation", None)
        labels = []
        for v in self.chosen:
            lab = f"variant {v}" + (f" ({label_of[v]})" if v in label_of else "")
            lab += ", " + ", ".join(f"{a.rsplit('.', 1)[-1]} {self.summary[a].iloc[pos[v]]:.4g}" for a in self.axes)
            if corr is not None and v in corr.index:
                lab += f", R {corr.loc[v, 'R']:.3f} ({corr.loc[v, 'grade']})"
            if self.summary["status"].iloc[pos[v]] != "ok":
                lab += " FAILED"
            labels.append(lab)
        chosen = ds.isel(variant=[pos[v] for v in self.chosen])
        test = (self.test[0] * 1e3, self.test[1]) if self.test is not None else None
        out = (f'<p class="note">Variants {", ".join(map(str, self.chosen))} (--variants to choose; worst/best by '
               f"{esc(self.key)}){'; dashed black: the --test curve' if test is not None else ''}.</p>")
        for quantity, item in plots[:HISTORY_PLOTS]:
            values, name, unit = history_values(chosen, quantity, item)
            curves = [(lab, t, values[k]) for k, lab in enumerate(labels)]
            fig = rf.histories(curves, "time [ms]", rf.label(f"{name} {item}", _shown_unit(unit)),
                               f"{name} of {item}: chosen variants", test)  # fmt: skip
            out += self.figures.div(fig, 460)
        return out

    def html(self, plotly_js: str) -> str:
        from crashstudy.analysis import report_extra

        sections = [("study", "Study", self.study_section())]
        if not self.ok.all():
            sections.append(("failures", "Failed variants", self.failures_section()))
        sections.append(("table", "Summary table", self.table_section()))
        if self.responses:
            sections.append(("design", "Design space: parallel coordinates and anthill plots", self.design_section()))
        crit = self.criteria_section()
        if crit:
            sections.append(("criteria", "Crash criteria against their usual limits", crit))
        self.correlation = report_extra.read_correlation(self.res, self.where)
        hist = self.history_section()
        if hist:
            sections.append(("histories", "Histories of chosen variants", hist))
        sections += report_extra.sections(self)
        title = f"{study_name(self.ds)}: crashstudy report"
        subtitle = (f"{len(self.summary)} variants, {int((~self.ok).sum())} failed; model "
                    f"{self.ds.attrs.get('model_name', '-')}; crashstudy {self.ds.attrs.get('crashstudy_version', '-')}")
        if self.notes:
            sections[0] = (sections[0][0], sections[0][1], sections[0][2] + "".join(
                f'<p class="note">Sampled: {esc(n)}.</p>' for n in self.notes))  # fmt: skip
        return page(title, subtitle, sections, plotly_js, has_table=True)


def build_report(res: Any, variants: str | None = None, responses: Sequence[str] | None = None,
                 test: tuple[np.ndarray, np.ndarray] | None = None, where: str = "",
                 limits: Sequence[str] = ()) -> str:  # fmt: skip
    """The HTML text of the report of the open result folder ``res``."""
    from plotly.offline import get_plotlyjs

    return Report(res, variants, responses, test, where, limits).html(get_plotlyjs())

