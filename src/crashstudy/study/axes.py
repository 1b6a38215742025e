"""A study's axes: the ``matrix``, ``zip`` and ``design`` groups as :class:`Axis` objects, each distinct
value checked (vectorised) to make a valid model with the rest of the model as written."""

from __future__ import annotations

import copy
import difflib
from dataclasses import dataclass
from typing import Any

import numpy as np
from pydantic import ValidationError

from crashstudy.arrays.compiler import PathRef, Topology, apply_axis
from crashstudy.arrays.parameter_checks import ParameterCheck, check_parameters
from crashstudy.errors import Problem
from crashstudy.schema import validate_model_data
from crashstudy.schema.study import Study
from crashstudy.schema.yamlio import LoadedYaml
from crashstudy.study.overrides import MAX_REPORTED, _dict_path, _set_in, _study_problem

CHECK_BLOCK = 4096  # distinct axis values checked at once


@dataclass(frozen=True)
class Axis:
    """One study axis: a model path, its values and the index of the (matrix or zip) dimension."""

    path: str
    values: np.ndarray
    dim: int
    ref: PathRef


def _check(topo: Topology, base: np.ndarray, ref: PathRef, values: np.ndarray, interval: float) -> ParameterCheck:
    P = np.repeat(base[:, None], len(values), axis=1)
    apply_axis(P, ref, values)
    return check_parameters(topo, P, interval)


def _model_message(data: dict[str, Any], path: str, val: float) -> str:
    """The model validation's first message for ``val`` at ``path`` ("" if the model stays valid)."""
    trial = copy.deepcopy(data)
    if _set_in(trial, _dict_path(trial, path), val):
        return ""
    _, found = validate_model_data(trial)
    msgs = [e["msg"] for e in found.errors()] if isinstance(found, ValidationError) else [m for _, m in found]
    return msgs[0] if msgs else ""


def _check_values(doc: LoadedYaml, where: tuple[str | int, ...], data: dict[str, Any], path: str, ref: PathRef,
                  values: list[float] | np.ndarray, topo: Topology, base: np.ndarray, interval: float
                  ) -> list[Problem]:  # fmt: skip
    """Each distinct value of an axis must make a valid model, the rest of the model as written.

    Every distinct value is checked, vectorised, on the parameter vector (:func:`check_parameters`:
    the schema's rules, finite values, a step count that fits); the message of an invalid value is
    the model validation's own where it has one. At most :data:`MAX_REPORTED` values per axis are listed.
    """
    problems: list[Problem] = []
    arr = np.asarray(values, dtype=np.float64)  # a design's rows stay an array (a list took ~50 bytes a value)
    if ref.op in ("scale", "speed"):
        wrong = np.nonzero(~(arr > 0) if ref.op == "scale" else ~(arr >= 0))[0]
        what = "a scale factor > 0" if ref.op == "scale" else "a speed >= 0"
        for k in wrong[:MAX_REPORTED]:
            problems.append(_study_problem(doc, where + (int(k),), f"expected {what}, got {float(arr[k])!r}"))
        if len(wrong) > MAX_REPORTED:
            problems.append(_study_problem(doc, where, f"and {len(wrong) - MAX_REPORTED:,} more values that are not "
                                           f"{what}"))  # fmt: skip
        if problems:
            return problems
    uniq, first = np.unique(arr, return_index=True)
    bad = np.zeros(len(uniq), dtype=bool)
    for lo in range(0, len(uniq), CHECK_BLOCK):
        bad[lo : lo + CHECK_BLOCK] = _check(topo, base, ref, uniq[lo : lo + CHECK_BLOCK], interval).bad
    if not bad.any():
        return problems
    shown = np.sort(first[bad])[:MAX_REPORTED]  # the first invalid values in file order
    check = _check(topo, base, ref, arr[shown], interval)
    for c, k in enumerate(shown):
        val = float(arr[int(k)])
        msg = (_model_message(data, path, val) if ref.op == "set" else "") or check.reason(c)
        problems.append(_study_problem(doc, where + (int(k),), f"value {val!r} makes the model invalid: {msg}"))
    if bad.sum() > MAX_REPORTED:
        problems.append(_study_problem(doc, where, f"{int(bad.sum()) - MAX_REPORTED} more distinct values of "
                                       f"{path!r} make the model invalid"))  # fmt: skip
    return problems


def _axes(study: Study, doc: LoadedYaml, topo: Topology, data: dict[str, Any], base: np.ndarray,
          interval: float) -> tuple[list[Axis], list[int], list[Problem]]:  # fmt: skip
    groups: list[tuple[tuple[str | int, ...], dict[str, Any]]] = [
        (("matrix", key), {key: vals}) for key, vals in study.matrix.items()
    ] + [(("zip", g), grp) for g, grp in enumerate(study.zip)]
    if study.design is not None:  # its rows: one dimension after matrix and zip, its axes varying together
        from crashstudy.study.design import rows

        d = study.design
        groups.append((("design", "axes"), rows(
            d.method, d.n, d.seed, {path: dist.spec() for path, dist in d.axes.items()})))  # fmt: skip
    axes: list[Axis] = []
    shape: list[int] = []
    problems: list[Problem] = []
    seen: set[str] = set()
    for dim, (where, grp) in enumerate(groups):
        lengths = {len(v) for v in grp.values()}
        if len(lengths) > 1:
            problems.append(_study_problem(doc, where, f"the axes of a zip group need equal lengths, got {sorted(lengths)}"))
        shape.append(min(lengths))
        for path, vals in grp.items():
            loc = where + (path,) if where[0] in ("zip", "design") else where
            if path in seen:
                problems.append(_study_problem(doc, loc, f"axis {path!r} appears twice"))
            seen.add(path)
            ref = topo.paths.get(path)
            if ref is None:
                problems.append(_study_problem(doc, loc, _unknown_path(path, topo)))
                continue
            problems.extend(_check_values(doc, loc, data, path, ref, vals, topo, base, interval))
            axes.append(Axis(path, np.asarray(vals, dtype=np.float64), dim, ref))
    return axes, shape, problems


def _unknown_path(path: str, topo: Topology) -> str:
    if path.startswith("output."):
        return f"{path!r} cannot vary across variants (all variants share one time axis); put it in 'set'"
    close = difflib.get_close_matches(path, list(topo.paths), n=3, cutoff=0.5)
    hint = f"; closest valid paths: {', '.join(close)}" if close else ""
    return f"unknown axis {path!r}: not a numeric field of the model{hint}"

