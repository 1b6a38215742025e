"""``crashstudy summary``: the summary table printed block by block (plain, ``--sort``, ``--variant``) and
``summary --exceed`` (an exceedance probability counted per block): memory bounded by a block, whatever the
variant count (issue 19)."""

from __future__ import annotations

import argparse
import math
import sys
from typing import Any

from crashstudy.errors import InputError, Problem

EXIT_OK = 0


def exceed_text(dir_: str, column: str, limit: str) -> str:
    """``summary --exceed COLUMN LIMIT``: the exceedance probability of a column."""
    import numpy as np

    from crashstudy.analysis.sensitivity import exceed_counts, exceedance_of, sample_caveat
    from crashstudy.cli.columns import match_column as _match_column
    from crashstudy.results.store import open_results

    value = _number("--exceed", limit)
    res = open_results(dir_)
    try:  # the column asked for and status, block by block, counted (a 10^8-variant summary is ~25 GB whole)
        with res.raw_dataset as raw:
            attrs = dict(raw.attrs)
        name = _match_column(dir_, column, res.summary_names())
        counts = np.zeros(3, dtype=np.int64)
        for block in res.summary_batches(["status", name]):
            counts += exceed_counts(block, name, value)
    finally:
        res.close()
    text = exceedance_of(name, value, counts).text()
    caveat = sample_caveat(attrs)
    if caveat:
        import textwrap

        print(textwrap.fill(f"warning: {caveat}", 100, subsequent_indent="  "), file=sys.stderr)
        text = text.replace("exact binomial;", "binomial, NOT a random sample;", 1)
    return text


def _number(option: str, text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not math.isfinite(value):
        raise InputError([Problem(option, None, "", f"expected a finite number, got {text!r}")])
    return value


def summary_command(args: argparse.Namespace) -> int:
    """``crashstudy summary DIR``: the table (or one variant's row), read block by block: memory bounded by
    a block (:data:`crashstudy.results.reader.READ_BLOCK` rows) and ``--head``, whatever the variant count.
    Only ``--sort`` with ``--head 0`` (every row, sorted) holds the shown columns whole."""
    import json

    from crashstudy.cli.columns import arg_problem
    from crashstudy.cli.columns import match_column as _match_column
    from crashstudy.results.reader import READ_BLOCK
    from crashstudy.results.store import open_results

    if args.head < 0:
        raise InputError(
            [arg_problem("--head", f"expected 0 (every row) or a number of rows, got {args.head}")]
        )
    if args.exceed:
        print(exceed_text(args.dir, *args.exceed))
        return EXIT_OK
    res = open_results(args.dir)
    try:
        names = res.summary_names()
        with res.raw_dataset as raw:  # units and axes from the store, no text decoded, no variable read
            units = _column_units(raw, names)
            axes = [a for a in json.loads(raw.attrs.get("crashstudy_axes", "[]")) if a in names]
        if args.variant is not None:
            return _print_variant(res.summary_row(args.variant), units, args, res)
        col = _match_column(args.dir, args.sort, names) if args.sort else None  # any column, shown or not
        shown = names
        if args.columns:
            picked = [
                c for c in names if any(k in c for k in args.columns) and c != "variant" and c not in axes
            ]
            if col is not None and col not in ("variant", *axes, *picked):
                picked.append(col)  # the sort column is always shown
            shown = ["variant", *axes, *picked]
        read = shown + (
            ["failure_reason"] if "failure_reason" in names and "failure_reason" not in shown else []
        )
        total = res.summary_rows()
        if col is None:
            blocks = _first_rows(res.summary_batches(read), args.head)
        else:
            blocks = iter([_top_rows(res.summary_batches(read), col, args.ascending, args.head)])
        if (
            args.head or total <= READ_BLOCK
        ):  # at most --head (or READ_BLOCK) rows: one table, as it always was
            import pandas as pd

            blocks = iter([pd.concat(list(blocks)) if total else pd.DataFrame(columns=read)])
        first = True
        for block in blocks:  # --head 0: block by block, each with the failure reasons of its rows
            if first or len(block):
                _print_block(block, shown, units, header=first, more=total - args.head if args.head else 0)
            first = False
    finally:
        res.close()
    return EXIT_OK


def _first_rows(batches: Any, head: int) -> Any:
    """The blocks of the table up to ``head`` rows (0: every block)."""
    left = head
    for b in batches:
        if head:
            b = b.iloc[:left]
            left -= len(b)
        if len(b):
            yield b
        if head and left <= 0:
            return


def _top_rows(batches: Any, column: str, ascending: bool, head: int) -> Any:
    """The ``head`` rows sorted by ``column`` (stable, NaN last), kept while the blocks stream past: the top
    rows of the rows seen so far followed by the next block, sorted again, are the top rows of both. Text
    columns sort as text. ``head`` 0: every row, sorted (the shown columns held whole)."""
    import pandas as pd

    top = None
    for b in batches:
        if not pd.api.types.is_numeric_dtype(b[column]):
            b[column] = b[column].astype(str)
        both = b if top is None else pd.concat([top, b])
        top = both.sort_values(column, ascending=ascending, kind="stable")
        if head:
            top = top.head(head)
    return top if top is not None else pd.DataFrame()


def _print_block(block: Any, shown: list[str], units: dict[str, str], header: bool, more: int) -> None:
    """Print a block of rows (its header with the units only for the first one), the count of ``more``
    rows not shown, then the failure reasons of its rows."""
    import shutil
    import textwrap

    import pandas as pd

    width = shutil.get_terminal_size((100, 24)).columns  # COLUMNS, else the terminal, else 100
    reasons = block["failure_reason"] if "failure_reason" in block else None
    table = block[[c for c in shown if c != "failure_reason"]].copy()
    cols = list(table.columns)
    table.columns = pd.MultiIndex.from_tuples([(c, f"[{units[c]}]" if units.get(c) else "") for c in cols])
    with pd.option_context(
        "display.max_columns",
        None,
        "display.width",
        width,
        "display.max_colwidth",
        None,
        "display.expand_frame_repr",
        True,
        "display.max_rows",
        None,
    ):
        print(table.to_string(line_width=width, header=header))
    if more > 0:
        print(f"... {more} more rows (--head 0 shows all)")
    if reasons is not None and (reasons.astype(str) != "").any():
        print("failure reasons:")
        for v, why in zip(block["variant"], reasons.astype(str), strict=True):
            if why:
                print(
                    textwrap.fill(
                        f"variant {v}: {why}", width, subsequent_indent="    ", break_long_words=False
                    )
                )


def _column_units(ds: Any, columns: list[str]) -> dict[str, str]:
    """Unit of each summary column as the result store keeps it (``""`` for none or a pure number)."""
    out = {}
    for c in columns:
        name = c if c in ds.variables else c.split(".", 1)[0]
        unit = str(ds[name].attrs.get("units", "")) if name in ds.variables else ""
        out[c] = "" if unit == "1" else unit
    return out


def _print_variant(rows: Any, units: dict[str, str], args: argparse.Namespace, res: Any) -> int:
    from crashstudy.cli.columns import arg_problem

    if rows.empty:
        raise InputError(
            [
                arg_problem(
                    args.dir,
                    f"--variant {args.variant}: the variants are numbered 0 to {res.summary_rows() - 1}",
                )
            ]
        )
    row = rows.iloc[0]
    labels = {c: c + (f" [{units[c]}]" if units.get(c) else "") for c in rows.columns}
    w = max(len(x) for x in labels.values())
    for c in rows.columns:
        v = row[c]
        text = f"{v:.6g}" if isinstance(v, float) else str(v)
        print(f"{labels[c]:<{w}}  {text}")
    return EXIT_OK
