"""The ``optimize:`` and ``calibrate:`` blocks of a study, checked before anything runs.

``validate``, ``run``, ``optimize`` and ``calibrate`` all load a study through
:func:`crashstudy.study.plan.load_study`, which calls :func:`check_blocks`: so a reversed bound, a
misspelt variable, a constraint on a column the run does not produce, an unknown or fixed channel
node or a missing data file is an input error (exit 2, file:line:field) in every command, not a
traceback or a silent pass in one of them (docs/optimize.md).

:data:`BLOCKS` names, for every top-level field of a study file, what checks it beyond its schema;
a test walks :class:`~crashstudy.schema.study.Study`'s fields and requires an entry for each, so a
block added later cannot go unchecked.
"""

from __future__ import annotations

import difflib
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from crashstudy.arrays.compiler import Topology
from crashstudy.errors import Problem
from crashstudy.schema.study import CONSTRAINT, Study
from crashstudy.schema.yamlio import LoadedYaml
from crashstudy.study.values import check_values, unknown_path

NODE_QUANTITIES = ("acceleration", "velocity", "displacement")


@dataclass(frozen=True)
class Context:
    """What the checks of a block need: the study, its file, its folder and the model as compiled."""

    study: Study
    doc: LoadedYaml
    base_dir: Path
    topo: Topology
    data: dict[str, Any]  # the model's data after ``set``
    base: np.ndarray
    interval: float

    def problem(self, path: tuple[str | int, ...], msg: str) -> Problem:
        return Problem(self.doc.file, self.doc.line_of(path), ".".join(str(p) for p in path), msg)


def summary_column_names(topo: Topology) -> list[str]:
    """The numeric columns of a run's summary table (``summary.parquet``): what ``minimize`` and
    ``constraints`` may name. Axis columns are the variables themselves and are not offered."""
    from crashstudy.metrics.record import asked_nodes, result_names
    from crashstudy.vocabulary.summary import SUMMARY_META

    items = {"spring": topo.spring_ids, "node": topo.node_ids, "wall": topo.wall_ids}
    cols: list[str] = []
    for name, (dims, _, _) in SUMMARY_META.items():
        cols += [f"{name}.{i}" for i in items[dims[0]]] if dims else [name]
    for name in result_names(topo):
        cols += [f"{name}.{n}" for n in asked_nodes(topo, name)]
    return cols


def _unknown_column(col: str, columns: list[str]) -> str:
    close = difflib.get_close_matches(col, columns, n=3, cutoff=0.5)
    hint = f"closest: {', '.join(close)}" if close else f"e.g. {', '.join(columns[:4])}"
    return f"no summary column {col!r}: not a numeric column of this model's results ({hint}; docs/format.md, Results)"


def _variables(ctx: Context, block: str, variables: dict[str, list[float]]) -> list[Problem]:
    """Each variable: a numeric field of the model, low < high, and both bounds give a valid model."""
    problems: list[Problem] = []
    for path, (lo, hi) in variables.items():
        at = (block, "variables", path)
        ref = ctx.topo.paths.get(path)
        if ref is None:
            problems.append(ctx.problem(at, unknown_path(path, ctx.topo)))
        elif not lo < hi:
            problems.append(ctx.problem(at, f"bounds [low, high] need low < high, got [{lo!r}, {hi!r}]"))
        else:
            problems += check_values(
                ctx.doc, at, ctx.data, path, ref, [lo, hi], ctx.topo, ctx.base, ctx.interval
            )
    return problems


def check_optimize(ctx: Context) -> list[Problem]:
    spec = ctx.study.optimize
    if spec is None:
        return []
    problems = _variables(ctx, "optimize", spec.variables)
    columns = summary_column_names(ctx.topo)
    if spec.minimize not in columns:
        problems.append(ctx.problem(("optimize", "minimize"), _unknown_column(spec.minimize, columns)))
    for k, text in enumerate(spec.constraints):
        m = CONSTRAINT.match(text)
        assert m is not None  # the schema's pattern
        col, _, limit = m.groups()
        at = ("optimize", "constraints", k)
        if col not in columns:
            problems.append(ctx.problem(at, _unknown_column(col, columns)))
        try:
            ok = np.isfinite(float(limit))
        except ValueError:
            ok = False
        if not ok:
            problems.append(
                ctx.problem(
                    at, f"constraint {text!r}: expected a finite number after {m.group(2)}, got {limit!r}"
                )
            )
    return problems


def check_calibrate(ctx: Context) -> list[Problem]:
    spec = ctx.study.calibrate
    if spec is None:
        return []

    problems = _variables(ctx, "calibrate", spec.variables)
    ch, topo = spec.channel, ctx.topo
    at = ("calibrate", "channel")
    if ch.quantity in NODE_QUANTITIES:
        if ch.node is None:
            problems.append(
                ctx.problem(
                    at,
                    f"quantity {ch.quantity} is a node's: give node: ID (one of "
                    f"{', '.join(topo.node_ids[:8])})",
                )
            )
        elif ch.node not in topo.node_ids:
            problems.append(
                ctx.problem(
                    at + ("node",), f"unknown node {ch.node!r}; nodes: {', '.join(topo.node_ids[:8])}"
                )
            )
        elif "xy".index(ch.direction) >= topo.dim:
            problems.append(
                ctx.problem(at + ("direction",), f"the model is {topo.dim}-D: direction must be x")
            )
        elif topo.fixed[topo.node_ids.index(ch.node), "xy".index(ch.direction)]:
            problems.append(
                ctx.problem(
                    at + ("node",),
                    f"node {ch.node!r} is fixed in {ch.direction}: its "
                    f"{ch.quantity} is zero whatever the variables; name a free node",
                )
            )
        if ch.spring is not None:
            problems.append(
                ctx.problem(at + ("spring",), f"quantity {ch.quantity} is a node's: remove spring:")
            )
    else:
        if ch.spring is None:
            problems.append(
                ctx.problem(
                    at,
                    f"quantity {ch.quantity} is a spring's: give spring: ID (one of "
                    f"{', '.join(topo.spring_ids[:8])})",
                )
            )
        elif ch.spring not in topo.spring_ids:
            problems.append(
                ctx.problem(
                    at + ("spring",),
                    f"unknown spring {ch.spring!r}; springs: {', '.join(topo.spring_ids[:8])}",
                )
            )
        if ch.node is not None:
            problems.append(
                ctx.problem(at + ("node",), f"quantity {ch.quantity} is a spring's: remove node:")
            )
    problems += _test_data(ctx, spec.data, ch.quantity)
    return problems


def _test_data(ctx: Context, data: Any, quantity: str) -> list[Problem]:
    """``calibrate.data``: the file exists; an ISO-MME test (or a unit: given) is read, so that a channel
    pattern matching none or several channels, or an unknown unit, is found before anything runs."""
    from crashstudy.exchange.testcurve import data_block, is_isomme, read_curve
    from crashstudy.schema.yamlio import not_regular

    rel, code, unit = data_block(data)
    at: tuple[str, ...] = ("calibrate", "data") if isinstance(data, str) else ("calibrate", "data", "path")
    path = ctx.base_dir / rel
    try:
        why = "" if path.is_dir() else not_regular(path.stat().st_mode, "a regular file")
    except FileNotFoundError:
        why = "no such file"
    except (OSError, ValueError) as exc:
        why = getattr(exc, "strerror", None) or type(exc).__name__
    if why:
        return [
            ctx.problem(
                at,
                f"data file {path}: {why} (expected a CSV file with columns time, value, or an "
                "ISO-MME test: its .mme file, folder or .zip; relative to the study file)",
            )
        ]
    if not (is_isomme(path) or code or unit):
        return []
    try:
        read_curve(path, channel=code, unit=unit, quantity=quantity, system=ctx.topo.units)
    except ValueError as exc:
        fld = getattr(exc, "field", "path")
        sub = ("calibrate", "data") + (
            (fld,)
            if not isinstance(data, str) and fld in ("channel", "unit")
            else (() if isinstance(data, str) else ("path",))
        )
        if isinstance(data, str) and fld == "channel":
            return [ctx.problem(sub, f"{exc} (write data: {{path: {rel}, channel: CODE}})")]
        return [ctx.problem(sub, str(exc))]
    return []


# Every top-level field of a study file -> what checks it beyond the schema (a check of this module, or
# where it is checked). tests/test_study_blocks.py requires an entry for every field of Study.
BLOCKS: dict[str, Callable[[Context], list[Problem]] | str] = {
    "name": "schema (an id)",
    "description": "schema (free text)",
    "model": "plan._model_path and the model's own validation",
    "matrix": "axes._axes: every distinct value of every axis makes a valid model",
    "zip": "axes._axes: equal lengths, every distinct value makes a valid model",
    "design": "axes._axes: the rows' values make a valid model (sizes in closed form)",
    "optimize": check_optimize,
    "calibrate": check_calibrate,
    "set": "overrides._apply_set and the model's validation after it",
    "regression": "schema (tolerances); compare names unknown columns",
}


def check_blocks(ctx: Context) -> list[Problem]:
    """Problems of every block that has its own check here (optimize, calibrate)."""
    return [p for check in BLOCKS.values() if callable(check) for p in check(ctx)]
