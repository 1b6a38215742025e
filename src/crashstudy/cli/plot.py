"""``crashstudy plot DIR``: the figures of a result folder written as PNG files."""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import pandas as pd
from matplotlib.figure import Figure

from crashstudy.analysis.factors import factors
from crashstudy.analysis.plot import (
    ITEM_DIM,
    ITEMS_PER_FIGURE,
    _fail,
    _items,
    _need_histories,
    _parse_quantity,
    crash_node,
    free_nodes,
    plot_force_displacement,
    plot_history,
    study_axes,
    study_name,
)
from crashstudy.analysis.plot_density import POINTS_MAX
from crashstudy.analysis.plot_matrix import check_axes, default_metric, metric_columns, plot_matrix
from crashstudy.analysis.plot_style import axis_label, axis_units, unit_text
from crashstudy.errors import InputError, Problem
from crashstudy.results.plot_tag import PLOT_TAG
from crashstudy.safefs import replacing


def _safe(name: str) -> str:
    return "".join(c if c.isalnum() or c in "._-" else "_" for c in name)


def _items_suffix(items: Sequence[str] | None) -> str:
    """``-a-b`` for ``--items a b`` (so that figures of other items do not overwrite these); a long
    list is cut and ends in a short hash of the whole list."""
    if not items:
        return ""
    text = "-" + "-".join(items)
    if len(text) <= 60:
        return text
    import hashlib

    return text[:48] + "-" + hashlib.sha256("\0".join(items).encode()).hexdigest()[:8]


def _matrix_summary(res: Any, axes: list[str], quantity: str | None) -> pd.DataFrame:
    """The summary columns a matrix plot of ``quantity`` uses (variant, axes, status, the metric's columns;
    ~8 B per variant each instead of the whole table): the whole summary when none matches (its message
    lists the valid metrics)."""
    names = res.summary_names()
    base = quantity or "peak_deceleration_g"
    want = {c for c in names if c == quantity or c.startswith(base + ".")}
    if not want:
        return res.summary  # type: ignore[no-any-return]
    keep = {"variant", "status", *axes, *want}
    return res.summary_columns([c for c in names if c in keep])  # type: ignore[no-any-return]


def _matrix_metrics(
    summary: pd.DataFrame,
    axes: list[str],
    quantity: str | None,
    items: Sequence[str] | None,
    nodes: list[str],
    where: str,
    node: str | None = None,
) -> list[str]:
    """Metric columns named by ``--quantity`` (a column, or a metric name with optional ``--items``).
    A metric name without items: its column of ``node`` (:func:`crash_node`) when it has one, else
    the column with the largest values."""
    metrics = metric_columns(summary, axes)
    if quantity in metrics and not items:
        return [quantity]
    base = quantity or "peak_deceleration_g"
    with_items = [c for c in metrics if c.startswith(base + ".")]
    if not with_items:
        bases = sorted({c.split(".", 1)[0] for c in metrics})
        raise _fail(
            where, f"unknown metric {base!r}; valid: {', '.join(bases)} (or a column: {', '.join(metrics)})"
        )
    if not items:
        if node is not None and f"{base}.{node}" in with_items:
            return [f"{base}.{node}"]
        return [default_metric(summary, nodes, prefix=base)]
    valid = [c.split(".", 1)[1] for c in with_items]
    unknown = [i for i in items if i not in valid]
    if unknown:
        raise _fail(
            where, f"{base} has no item {', '.join(map(repr, unknown))}; valid items: {', '.join(valid)}"
        )
    return [f"{base}.{i}" for i in items]


def _xy(args: argparse.Namespace, ds: Any, axes: list[str]) -> tuple[str, str | None]:
    """The matrix plot's axes: ``--x`` (default the first study axis) and ``--y`` (``none``: no second
    axis; default the first axis of another factor)."""
    x = args.x_axis or axes[0]
    if args.y_axis is not None:
        return x, None if args.y_axis.lower() == "none" else args.y_axis  # --y none: line plot
    return x, next((a for a, m in factors(dict(ds.attrs), axes).items() if x not in m), None)


def _schema(res: Any) -> pd.DataFrame:
    """The summary.parquet's columns with their types, no rows."""
    from crashstudy.results.reader import PARQUET, _parquet

    with res.open_file(PARQUET) as fh:
        return _parquet(fh).schema_arrow.empty_table().to_pandas()  # type: ignore[no-any-return]


def _density_figures(res: Any, ds: Any, args: argparse.Namespace, limit: int) -> list[tuple[str, Figure]]:
    """``plot --kind matrix`` beyond ``limit`` variants: the density matrix of the axes and each metric
    (:mod:`crashstudy.analysis.plot_density`), read block by block; the metric is chosen as the exact
    figure chooses it, from the Parquet schema (and the columns' peaks, read block by block)."""
    import numpy as np

    from crashstudy.analysis import plot_density
    from crashstudy.analysis.plot_style import display_scale
    from crashstudy.results.reader import PARQUET, _parquet

    where, axes = str(args.dir), study_axes(ds)
    x, y = _xy(args, ds, axes)
    check_axes(axes, x, y, where)
    stored = res.summary_source == PARQUET  # else an older folder's summary.csv or dataset
    head = _schema(res) if stored else next(res.summary_batches(rows=1)).iloc[:0]  # names and types
    base, node = args.quantity or "peak_deceleration_g", crash_node(ds)
    named = args.quantity in head or args.items or (node is not None and f"{base}.{node}" in head)
    candidates = [c for c in head.columns if c.startswith(base + ".")]
    if not named and candidates:  # the column with the largest values, as the exact figure takes it
        head = pd.DataFrame({c: [(res.column_peak(c) or (np.nan,))[0]] for c in candidates})
    metrics = _matrix_metrics(head, axes, args.quantity, args.items, free_nodes(ds), where, node)
    columns = [x, *([y] if y else []), *metrics]
    ranges = None
    if stored:
        with res.open_file(PARQUET) as fh:
            ranges = plot_density.statistics_ranges(_parquet(fh), columns)
    if ranges is None:
        ranges = plot_density.scan_ranges(res.summary_batches([*columns, "status"]), columns)
    units = axis_units(ds, axes)
    out = []
    for metric in metrics:
        names = [x, *([y] if y else []), metric]
        d = plot_density.count(res.summary_batches([*names, "status"]), names, ranges)
        unit = ds[metric.split(".", 1)[0]].attrs.get("units") if metric.split(".", 1)[0] in ds else None
        factor, shown = display_scale(unit or "", d.edges[-1])
        labels = [axis_label(a, units) for a in names[:-1]] + [f"{metric}{unit_text(shown)}"]
        fig = plot_density.plot_density(
            d,
            labels,
            f"{study_name(ds)}: {metric}",
            res.summary_rows(),
            limit,
            [1.0] * (len(names) - 1) + [factor],
        )
        suffix = f"-{x}" + (f"-{y}" if y else "") if args.x_axis or args.y_axis else ""
        out.append((f"matrix-{metric}{suffix}", fig))
    return out


def _test_curve(args: argparse.Namespace, ds: object, name: str, groups: list) -> object:
    """``--test FILE [--channel CODE]``: the test curve in the results' units (one history panel only)."""
    if getattr(args, "test", None) is None:
        if getattr(args, "channel", None):
            raise InputError(
                [
                    Problem(
                        str(args.dir),
                        None,
                        "--channel",
                        "--channel names a channel of --test FILE: give --test",
                    )
                ]
            )
        return None
    if len(groups) != 1 or (groups[0] is not None and len(groups[0]) != 1):
        raise InputError(
            [
                Problem(
                    str(args.dir),
                    None,
                    "--test",
                    "a test curve belongs to one item: give --items with one node or spring",
                )
            ]
        )
    from crashstudy.exchange.testcurve import read_curve

    try:
        units = str(ds.attrs.get("units", "SI"))  # type: ignore[attr-defined]
        return read_curve(Path(args.test), channel=args.channel, quantity=name, system=units)
    except ValueError as exc:
        raise InputError(
            [
                Problem(
                    str(args.test),
                    None,
                    f"--{getattr(exc, 'field', 'test')}".replace("--path", "--test"),
                    str(exc),
                )
            ]
        ) from None


def plot_command(args: argparse.Namespace) -> list[Path]:
    """``crashstudy plot DIR``: write the figures of ``args.kind`` as PNGs; return their paths.

    ``args`` carries ``dir``, ``kind``, ``quantity``, ``items``, ``x_axis``, ``y_axis``,
    ``max_variants``, ``output`` (default ``DIR/plots``) and optionally ``time_unit`` and
    ``accel_unit``. History figures hold at most :data:`ITEMS_PER_FIGURE` subplots; more items are
    spread over several files. File names carry the quantity and the ``--items`` given.
    """
    from crashstudy.results.store import open_results

    where = str(args.dir)
    try:
        res = open_results(args.dir)
    except FileNotFoundError as exc:
        raise _fail(where, str(exc)) from None
    ds = res.raw_dataset if args.kind == "matrix" else res.dataset  # matrix: attributes only, no text decoded
    out = Path(args.output) if args.output else Path(args.dir) / "plots"
    figures: list[tuple[str, Figure]] = []
    try:
        limit = POINTS_MAX if getattr(args, "max_points", None) is None else args.max_points
        if limit < 0:
            raise _fail(where, f"--max-points {limit}: give a number of variants, 0 or more")
        if args.kind == "matrix" and study_axes(ds) and res.summary_rows() > limit:
            figures = _density_figures(res, ds, args, limit)
        elif args.kind == "matrix":
            axes = study_axes(ds)
            summary = _matrix_summary(res, axes, args.quantity)
            if not axes:
                raise _fail(
                    where,
                    "these results have no study axes (a single model run); a matrix plot needs a study",
                )
            x, y = _xy(args, ds, axes)
            node = crash_node(ds)
            for metric in _matrix_metrics(
                summary, axes, args.quantity, args.items, free_nodes(ds), where, node
            ):
                units = (
                    ds[metric.split(".", 1)[0]].attrs.get("units") if metric.split(".", 1)[0] in ds else None
                )
                fig = plot_matrix(
                    summary,
                    metric,
                    x,
                    y,
                    axes=axes,
                    units=units,
                    title=f"{study_name(ds)}: {metric}",
                    axis_units=axis_units(ds, axes),
                    factors=factors(dict(ds.attrs), axes),
                )
                suffix = f"-{x}" + (f"-{y}" if y else "") if args.x_axis or args.y_axis else ""
                figures.append((f"matrix-{metric}{suffix}", fig))
        elif args.kind == "pulse":
            from crashstudy.analysis.plot_pulse import metric_nodes, plot_pulse

            if args.quantity:
                raise _fail(
                    where, "pulse draws filtered_acceleration beside acceleration; --quantity does not apply"
                )
            if "filtered_acceleration" not in ds.data_vars:
                plot_pulse(ds)  # raises with the reason
            nodes = _items(ds, "node", args.items, metric_nodes(ds))
            for n, lo in enumerate(range(0, len(nodes), ITEMS_PER_FIGURE)):
                fig = plot_pulse(ds, nodes[lo : lo + ITEMS_PER_FIGURE], args.max_variants)
                figures.append((f"pulse{_items_suffix(args.items)}{f'-{n + 1}' if n else ''}", fig))
        elif args.kind == "force-displacement":
            if args.quantity:
                raise _fail(
                    where, "force-displacement draws spring_force against crush; --quantity does not apply"
                )
            _need_histories(ds, ["spring_force", "spring_elongation"])
            springs = _items(ds, "spring", args.items, [str(v) for v in ds["spring"].values])
            for n, lo in enumerate(range(0, len(springs), ITEMS_PER_FIGURE)):
                fig = plot_force_displacement(ds, springs[lo : lo + ITEMS_PER_FIGURE], args.max_variants)
                figures.append(
                    (f"force-displacement{_items_suffix(args.items)}{f'-{n + 1}' if n else ''}", fig)
                )
        else:
            quantity = args.quantity or "spring_force"
            name, _ = _parse_quantity(ds, quantity)
            _need_histories(ds, [name])
            dim = ITEM_DIM[name]
            if dim is None:
                groups: list[list[str] | None] = [None if not args.items else list(args.items)]
            else:
                default = free_nodes(ds) if dim == "node" else [str(v) for v in ds[dim].values]
                chosen = _items(ds, dim, args.items, default)
                groups = [
                    chosen[lo : lo + ITEMS_PER_FIGURE] for lo in range(0, len(chosen), ITEMS_PER_FIGURE)
                ]
            units = {
                "time_unit": getattr(args, "time_unit", None),
                "accel_unit": getattr(args, "accel_unit", None),
            }
            test = _test_curve(args, ds, name, groups)
            for n, group in enumerate(groups):
                fig = plot_history(ds, quantity, group, args.max_variants, **units, test=test)
                figures.append(
                    (f"history-{quantity}{_items_suffix(args.items)}{f'-{n + 1}' if n else ''}", fig)
                )
        out.mkdir(parents=True, exist_ok=True)
        paths = []
        for stem, fig in figures:
            path = out / f"{_safe(stem)}.png"
            with replacing(path, mode="wb") as fh:  # a planted link is replaced, never written through
                fig.savefig(fh, format="png", dpi=100, metadata={PLOT_TAG: str(res.path)})
            paths.append(path)
        return paths
    except InputError as exc:  # name the folder as the user typed it
        raise InputError([Problem(where, p.line, p.field, p.message) for p in exc.problems]) from None
    finally:
        if args.kind == "matrix":
            ds.close()
        res.close()
