"""The values a study gives a model path: each must make a valid model (:func:`check_values`), and a
``set`` or an axis value lands at a dotted path in the model's data (:func:`dict_path`, :func:`set_in`).
Read by the study's axes (:mod:`crashstudy.study.plan`), its ``optimize``/``calibrate`` variables
(:mod:`crashstudy.study.blocks`) and one variant's model (:mod:`crashstudy.study.variant`).
"""

from __future__ import annotations

import copy
import difflib
from typing import Any

import numpy as np

from crashstudy.arrays.compiler import PathRef, Topology, apply_axis
from crashstudy.arrays.parameter_checks import ParameterCheck, check_parameters
from crashstudy.errors import Problem
from crashstudy.schema import validate_model_data
from crashstudy.schema.yamlio import LoadedYaml

CHECK_BLOCK = 4096  # distinct axis values checked at once
MAX_REPORTED = 5  # invalid values listed per axis


def study_problem(doc: LoadedYaml, path: tuple[str | int, ...], msg: str) -> Problem:
    return Problem(doc.file, doc.line_of(path), ".".join(str(p) for p in path), msg)


def dict_path(data: Any, dotted: str) -> tuple[str | int, ...]:
    out: list[str | int] = []
    cur = data
    for part in dotted.split("."):
        key: str | int = int(part) if isinstance(cur, list) and part.isdigit() else part
        out.append(key)
        try:
            cur = cur[key]  # type: ignore[index]
        except (KeyError, IndexError, TypeError):
            cur = None
    return tuple(out)


def _kind(value: Any) -> str:
    if isinstance(value, bool):
        return "true or false"
    if isinstance(value, (int, float)):
        return "a number"
    return "text" if isinstance(value, str) else "null" if value is None else type(value).__name__


def set_in(data: dict[str, Any], path: tuple[str | int, ...], value: Any) -> str | None:
    """Set ``value`` at ``path``; a path that runs into a scalar or past a list's end is refused: the reason."""
    cur: Any = data
    for depth, part in enumerate(path):
        here = ".".join(str(p) for p in path[:depth])
        if isinstance(cur, list):
            if not isinstance(part, int):
                return f"{here} is a list: expected an item number after it, got {part!r}"
            if part >= len(cur):
                return f"{here} has {len(cur)} item{'s' if len(cur) != 1 else ''} (0 .. {len(cur) - 1}): no item {part}"
        elif not isinstance(cur, dict):
            return (
                f"{here} is {_kind(cur)}, not a mapping or a list: {'.'.join(str(p) for p in path)} "
                "cannot be set"
            )
        if depth == len(path) - 1:
            cur[part] = value  # type: ignore[index]
        else:
            cur = cur[part] if isinstance(cur, list) else cur.setdefault(part, {})  # type: ignore[index]
    return None


def parameter_check(
    topo: Topology, base: np.ndarray, ref: PathRef, values: np.ndarray, interval: float
) -> ParameterCheck:
    P = np.repeat(base[:, None], len(values), axis=1)
    apply_axis(P, ref, values)
    return check_parameters(topo, P, interval)


def model_message(data: dict[str, Any], path: str, val: float) -> str:
    """The model validation's first message for ``val`` at ``path`` ("" if the model stays valid)."""
    from pydantic import ValidationError

    trial = copy.deepcopy(data)
    if set_in(trial, dict_path(trial, path), val):
        return ""
    _, found = validate_model_data(trial)
    msgs = [e["msg"] for e in found.errors()] if isinstance(found, ValidationError) else [m for _, m in found]
    return msgs[0] if msgs else ""


def check_values(
    doc: LoadedYaml,
    where: tuple[str | int, ...],
    data: dict[str, Any],
    path: str,
    ref: PathRef,
    values: list[float] | np.ndarray,
    topo: Topology,
    base: np.ndarray,
    interval: float,
) -> list[Problem]:
    """Each distinct value of an axis must make a valid model, the rest of the model as written.

    Every distinct value is checked, vectorised, on the parameter vector (:func:`check_parameters`:
    the schema's rules, finite values, a step count that fits); the message of an invalid value is
    the model validation's own where it has one. At most :data:`MAX_REPORTED` values per axis are listed.
    """
    problems: list[Problem] = []
    arr = np.asarray(
        values, dtype=np.float64
    )  # a design's rows stay an array (a list took ~50 bytes a value)
    if ref.op in ("scale", "speed"):
        wrong = np.nonzero(~(arr > 0) if ref.op == "scale" else ~(arr >= 0))[0]
        what = "a scale factor > 0" if ref.op == "scale" else "a speed >= 0"
        for k in wrong[:MAX_REPORTED]:
            problems.append(study_problem(doc, where + (int(k),), f"expected {what}, got {float(arr[k])!r}"))
        if len(wrong) > MAX_REPORTED:
            problems.append(
                study_problem(
                    doc, where, f"and {len(wrong) - MAX_REPORTED:,} more values that are not {what}"
                )
            )
        if problems:
            return problems
    uniq, first = np.unique(arr, return_index=True)
    bad = np.zeros(len(uniq), dtype=bool)
    for lo in range(0, len(uniq), CHECK_BLOCK):
        bad[lo : lo + CHECK_BLOCK] = parameter_check(
            topo, base, ref, uniq[lo : lo + CHECK_BLOCK], interval
        ).bad
    if not bad.any():
        return problems
    shown = np.sort(first[bad])[:MAX_REPORTED]  # the first invalid values in file order
    check = parameter_check(topo, base, ref, arr[shown], interval)
    for c, k in enumerate(shown):
        val = float(arr[int(k)])
        msg = (model_message(data, path, val) if ref.op == "set" else "") or check.reason(c)
        problems.append(
            study_problem(doc, where + (int(k),), f"value {val!r} makes the model invalid: {msg}")
        )
    if bad.sum() > MAX_REPORTED:
        problems.append(
            study_problem(
                doc,
                where,
                f"{int(bad.sum()) - MAX_REPORTED} more distinct values of {path!r} make the model invalid",
            )
        )
    return problems


def unknown_path(path: str, topo: Topology) -> str:
    if path.startswith("output."):
        return f"{path!r} cannot vary across variants (all variants share one time axis); put it in 'set'"
    close = difflib.get_close_matches(path, list(topo.paths), n=3, cutoff=0.5)
    hint = f"; closest valid paths: {', '.join(close)}" if close else ""
    return f"unknown axis {path!r}: not a numeric field of the model{hint}"
