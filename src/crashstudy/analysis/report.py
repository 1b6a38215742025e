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
import yaml

from crashstudy.analysis import report_figures as rf
from crashstudy.analysis.plot import free_nodes, study_axes, study_name
from crashstudy.analysis.plot_style import axis_units, unit_text
from crashstudy.analysis.report_limits import (
    Check,
    constraint_checks,
    criteria_columns,
    limit_checks,
    passes_all,
    user_checks,
)
from crashstudy.analysis.report_page import (
    Figures,
    column_unit,
    esc,
    html_table,
    interactive_table,
    page,
    shown_unit,
    table_data,
)
from crashstudy.analysis.report_responses import criteria_section, history_section
from crashstudy.analysis.report_variants import (
    SAMPLE_SEED,
    baseline,
    default_responses,
    fail,
    parse_variants,
    sample,
)

SCATTER_MAX = 2000  # ok variants drawn in the parallel coordinates and anthill plots; more: a random sample
TABLE_MAX = 10_000  # rows of the summary table; more: a sample (every failed and chosen variant kept)
FAILURES_SHOWN = 200  # failed variants listed one by one
TEXT_COLUMNS = ("status", "failure_reason", "dt_control", "criteria_note")


class Report:
    """Gathers what the page shows; :meth:`html` renders it."""

    def __init__(
        self,
        res: Any,
        variants: str | None = None,
        responses: Sequence[str] | None = None,
        test: tuple[np.ndarray, np.ndarray] | None = None,
        where: str = "",
        limits: Sequence[str] = (),
    ) -> None:
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
                raise fail(
                    self.where,
                    "--responses",
                    f"no summary column {', '.join(map(repr, unknown))}; "
                    "columns: see `crashstudy summary DIR --variant 0`",
                )
            self.responses = list(responses)
        else:
            self.responses = default_responses(self.summary, self.ds)
        self.criteria = criteria_columns(self.summary)
        self.checks: list[Check] = user_checks(limits, cols, self.where) + constraint_checks(self.study, cols)
        self.checks += limit_checks([c for c in self.criteria if c in self.responses])
        self.key = self.responses[0] if self.responses else None
        self.named = self._named()
        n = len(self.summary)
        self.chosen = (
            parse_variants(variants, n, self.named, self.where)
            if variants
            else list(dict.fromkeys(v for v in self.named.values() if v is not None))
        )
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
        named: dict[str, int | None] = {
            "worst": None,
            "best": None,
            "baseline": baseline(self.summary, self.axes, self.ok),
        }
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
        written = datetime.fromtimestamp(os.stat(final).st_mtime, tz=timezone.utc).strftime(
            "%Y-%m-%d %H:%M UTC"
        )
        kept = [
            v
            for v in (
                "acceleration",
                "velocity",
                "displacement",
                "position",
                "spring_force",
                "spring_elongation",
                "filtered_acceleration",
                "wall_force",
            )
            if v in self.ds.data_vars
        ]
        rows = [
            ("study", a.get("study_name", "-")),
            ("study file", a.get("study_file", "-")),
            ("model", f"{a.get('model_name', '-')} ({a.get('model_file', '-')})"),
            ("units", a.get("units", "-")),
            ("variants", f"{len(s)}"),
            ("by status", ", ".join(f"{k}: {v}" for k, v in counts.items())),
            ("histories kept", ", ".join(kept) or "none (output.histories: none)"),
            ("end time", f"{float(s['t_end'].max()):g} s" if "t_end" in s else "-"),
            ("run time", f"not recorded in the folder; results.nc written {written}"),
            ("crashstudy version", a.get("crashstudy_version", "-")),
            ("model sha256", a.get("model_sha256", "-")),
            ("study sha256", a.get("study_sha256", "-")),
        ]
        out = html_table(["", ""], rows, text_cols=(0, 1))
        if self.axes:
            axrows = []
            for ax in self.axes:
                v = s[ax].to_numpy(dtype=float)
                axrows.append(
                    (
                        ax,
                        shown_unit(self.units[ax]),
                        f"{np.nanmin(v):.6g}",
                        f"{np.nanmax(v):.6g}",
                        len(np.unique(v[np.isfinite(v)])),
                    )
                )
            out += "<h3>Axes</h3>" + html_table(
                ["axis", "unit", "min", "max", "distinct values"], axrows, (0, 1)
            )
        manifest = self.res.manifest or {}
        if manifest:
            mrows = [
                (k, v.get("size", "-"), v.get("sha256", "(results.nc: per-variant checksums inside)"))
                for k, v in manifest.items()
                if isinstance(v, dict)
            ]
            out += (
                "<h3>Files (manifest.json, run "
                + esc(a.get("run_id", "-"))
                + ")</h3>"
                + html_table(["file", "bytes", "sha256"], mrows, (0, 2))
            )
        named = ", ".join(f"{k}: variant {v}" for k, v in self.named.items() if v is not None)
        if named:
            out += (
                f'<p class="note">Chosen variants ({esc(named)}): worst and best by {esc(self.key)}; baseline = '
                "the ok variant nearest the middle of every axis range.</p>"
            )
        return out

    def failures_section(self) -> str:
        s = self.summary[~self.ok]
        head = [
            "variant",
            *[f"{a} [{shown_unit(self.units[a])}]" if self.units[a] else a for a in self.axes],
            "failure reason",
        ]
        rows = [
            [int(r["variant"]), *[f"{r[a]:.6g}" for a in self.axes], r.get("failure_reason", "")]
            for _, r in s.head(FAILURES_SHOWN).iterrows()
        ]
        more = (
            f'<p class="note">and {len(s) - FAILURES_SHOWN} more (filter the table: status=failed)</p>'
            if len(s) > FAILURES_SHOWN
            else ""
        )
        kinds = s["failure_reason"].astype(str).str.replace(r"[-+]?\d[\d.]*(e[-+]?\d+)?", "#", regex=True)
        summary = "".join(f"<li>{v} x {esc(k)}</li>" for k, v in list(kinds.value_counts().items())[:10])
        return (
            f'<p class="bad">{len(s)} of {len(self.summary)} variants failed; reasons (numbers as #):</p><ul>{summary}</ul>'
            + html_table(head, rows, text_cols=(len(head) - 1,), cls="failures")
            + more
        )

    def table_section(self) -> str:
        s = self.summary
        extra = [
            c
            for c in s.columns
            if c.startswith("peak_deceleration_g.") and c.split(".", 1)[1] in free_nodes(self.ds)
        ]
        cols = list(
            dict.fromkeys(
                [
                    "variant",
                    *self.axes,
                    "status",
                    "failure_reason",
                    *self.responses,
                    *self.criteria,
                    *extra,
                    "energy_error",
                ]
            )
        )
        cols = [c for c in cols if c in s and not c.split(".", 1)[0].endswith(("_t1", "_t2"))]
        index = np.arange(len(s))
        keep = [int(i) for i in np.nonzero(~self.ok)[0]] + [
            int(np.nonzero(s["variant"].to_numpy() == v)[0][0]) for v in self.chosen
        ]
        shown = sample(index, TABLE_MAX, keep)
        note = (
            f"every variant ({len(s)})"
            if len(shown) == len(s)
            else f"a sample of {len(shown)} of {len(s)} variants (every failed and chosen variant, the rest at random "
            f"with seed {SAMPLE_SEED}; above {TABLE_MAX} variants the table is sampled: summary.parquet has all)"
        )
        meta = [
            (
                c,
                "" if c in ("variant",) else shown_unit(self.units.get(c) or column_unit(self.ds, c)),
                c in TEXT_COLUMNS,
            )
            for c in cols
        ]
        sub = s.iloc[shown][cols]
        rows = [
            [None if isinstance(v, float) and not np.isfinite(v) else v for v in r]
            for r in sub.itertuples(index=False, name=None)
        ]
        return (
            f'<p class="note">The table holds {esc(note)}. Click a heading to sort; the filter takes words and '
            "column comparisons such as <code>hic15&gt;700</code> or <code>status=failed</code>.</p>"
            + interactive_table(table_data(meta, rows))
        )

    def _scatter_index(self) -> np.ndarray:
        ok = np.nonzero(self.ok)[0]
        shown = sample(ok, SCATTER_MAX)
        if len(shown) < len(ok):
            self.notes.append(
                f"scatter figures: a random sample of {len(shown)} of {len(ok)} ok variants "
                f"(seed {SAMPLE_SEED}; above {SCATTER_MAX} they are sampled)"
            )
        return shown

    def design_section(self) -> str:
        if not self.responses:
            return '<p class="note">No responses to draw.</p>'
        idx = self._scatter_index()
        s = self.summary.iloc[idx]
        passed = passes_all(s, self.checks) if self.checks else None
        cols = [(a, self.units[a], s[a].to_numpy(dtype=float)) for a in self.axes]
        cols += [(r, column_unit(self.ds, r), s[r].to_numpy(dtype=float)) for r in self.responses]
        cb = (self.key, s[self.key].to_numpy(dtype=float)) if self.key else None
        sampled = (
            f" (sample of {len(idx)} of {int(self.ok.sum())} ok variants)" if len(idx) < self.ok.sum() else ""
        )
        out = ""
        if self.checks:
            npass = int(passes_all(self.summary[self.ok], self.checks).sum())
            out += (
                f"<p>Pass (green) = every check holds; fail (red) = at least one does not. {npass} of "
                f"{int(self.ok.sum())} ok variants pass.</p><ul>"
                + "".join(
                    f"<li>{esc(c.text)}{esc(unit_text(column_unit(self.ds, c.column)))} &mdash; "
                    f"{esc(c.source)}</li>"
                    for c in self.checks
                )
                + "</ul>"
            )
        else:
            out += (
                '<p class="note">No limits or constraints apply to these responses: lines coloured by '
                f"{esc(self.key)}.</p>"
            )
        out += self.figures.div(rf.parcoords(cols, passed, cb, f"axes to responses{sampled}"), 460)
        if self.axes:
            out += "<h3>Each response against each axis</h3>"
            if self.checks:
                out += (
                    '<p class="note">Green/red: the response\'s own limit or constraint (dashed line) holds or '
                    "not; a response without one is coloured by every check.</p>"
                )
            for r in self.responses:
                own = [c for c in self.checks if c.column == r]
                colour = passes_all(s, own) if own else passed
                fig = rf.anthill(
                    cols[: len(self.axes)],
                    (r, column_unit(self.ds, r), s[r].to_numpy(dtype=float)),
                    colour,
                    self.checks,
                    f"{r}{sampled}",
                )
                rows = (len(self.axes) + 2) // 3
                out += self.figures.div(fig, 300 * rows + 80)
        return out

    def html(self, plotly_js: str) -> str:
        from crashstudy.analysis import report_extra

        sections = [("study", "Study", self.study_section())]
        if not self.ok.all():
            sections.append(("failures", "Failed variants", self.failures_section()))
        sections.append(("table", "Summary table", self.table_section()))
        if self.responses:
            sections.append(
                ("design", "Design space: parallel coordinates and anthill plots", self.design_section())
            )
        crit = criteria_section(self)
        if crit:
            sections.append(("criteria", "Crash criteria against their usual limits", crit))
        self.correlation = report_extra.read_correlation(self.res, self.where)
        hist = history_section(self)
        if hist:
            sections.append(("histories", "Histories of chosen variants", hist))
        sections += report_extra.sections(self)
        title = f"{study_name(self.ds)}: crashstudy report"
        subtitle = (
            f"{len(self.summary)} variants, {int((~self.ok).sum())} failed; model "
            f"{self.ds.attrs.get('model_name', '-')}; crashstudy {self.ds.attrs.get('crashstudy_version', '-')}"
        )
        if self.notes:
            sections[0] = (
                sections[0][0],
                sections[0][1],
                sections[0][2] + "".join(f'<p class="note">Sampled: {esc(n)}.</p>' for n in self.notes),
            )
        return page(title, subtitle, sections, plotly_js, has_table=True)


def build_report(
    res: Any,
    variants: str | None = None,
    responses: Sequence[str] | None = None,
    test: tuple[np.ndarray, np.ndarray] | None = None,
    where: str = "",
    limits: Sequence[str] = (),
) -> str:
    """The HTML text of the report of the open result folder ``res``."""
    from plotly.offline import get_plotlyjs

    return Report(res, variants, responses, test, where, limits).html(get_plotlyjs())
