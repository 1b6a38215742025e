"""Expansion stage: a study file (or a lone model) -> a :class:`Plan` of numbered variants.

A plan holds the compiled topology, the base parameter vector and the study axes; it produces the
parameter matrix of any range of variants on demand (:meth:`Plan.params`), so a study of 10^6
variants is never materialised. Variants are numbered in row-major order of the axes as written:
matrix axes first, then one axis per zip group.
"""

from __future__ import annotations

import copy
import difflib
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from pydantic import ValidationError

from crashstudy.compiler import PathRef, Topology, apply_axis, compile_model
from crashstudy.errors import InputError, Problem
from crashstudy.schema import LoadedModel, parse_model, refuse_foreign, validate_model_data
from crashstudy.schema.model import Model
from crashstudy.schema.report import located, pydantic_problems
from crashstudy.schema.study import Study
from crashstudy.yamlio import LoadedYaml, load_yaml, loads_yaml

DEFAULT_SAMPLES = 1000
MAX_VARIANTS = 100_000_000  # one results.nc; its axis coordinates alone take 0.8 GB each


@dataclass(frozen=True)
class Axis:
    """One study axis: a model path, its values and the index of the (matrix or zip) dimension."""

    path: str
    values: np.ndarray
    dim: int
    ref: PathRef


@dataclass(frozen=True)
class Plan:
    """Everything needed to run a study; picklable, free of pydantic objects."""

    name: str
    topology: Topology
    base: np.ndarray  # (n_params,)
    axes: tuple[Axis, ...]
    shape: tuple[int, ...]  # size of each matrix axis / zip group
    interval: float  # history sampling interval [time]
    n_out: int  # number of history samples
    model_text: str
    study_text: str
    model_file: str
    study_file: str
    regression: dict[str, dict[str, float]]

    @property
    def n_variants(self) -> int:
        return math.prod(self.shape) if self.shape else 1

    @property
    def times(self) -> np.ndarray:
        return np.arange(self.n_out) * self.interval

    def axis_values(self, lo: int, hi: int) -> dict[str, np.ndarray]:
        """Value of every axis for variants ``lo`` .. ``hi - 1``."""
        idx = np.arange(lo, hi)
        if not self.shape:
            return {}
        multi = np.unravel_index(idx, self.shape)
        return {ax.path: ax.values[multi[ax.dim]] for ax in self.axes}

    def params(self, lo: int, hi: int) -> np.ndarray:
        """Parameter matrix (n_params, hi - lo) of variants ``lo`` .. ``hi - 1``."""
        P = np.repeat(self.base[:, None], hi - lo, axis=1)
        for ax, vals in zip(self.axes, self.axis_values(lo, hi).values()):
            apply_axis(P, ax.ref, np.asarray(vals, dtype=np.float64))
        return P


def _study_problem(doc: LoadedYaml, path: tuple[str | int, ...], msg: str) -> Problem:
    return Problem(doc.file, doc.line_of(path), ".".join(str(p) for p in path), msg)


def _dict_path(data: Any, dotted: str) -> tuple[str | int, ...]:
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


def _set_in(data: dict[str, Any], path: tuple[str | int, ...], value: Any) -> None:
    cur: Any = data
    for part in path[:-1]:
        if isinstance(cur, dict):
            cur = cur.setdefault(part, {})
        else:
            cur = cur[part]
    cur[path[-1]] = value


def _apply_set(data: dict[str, Any], overrides: dict[str, Any]) -> dict[str, Any]:
    data = copy.deepcopy(data)
    for key, value in overrides.items():
        if key == "time_step" or key.startswith("time_step."):
            # a different time-step mode replaces the model's (the modes are exclusive)
            if key != "time_step":
                value = {key.split(".", 1)[1]: value}
            data["time_step"] = value
            continue
        if isinstance(value, dict) and key in ("output", "termination") and isinstance(data.get(key), dict):
            data[key] = {**data[key], **value}
            continue
        _set_in(data, _dict_path(data, key), value)
    return data


def _check_values(
    doc: LoadedYaml, where: tuple[str | int, ...], data: dict[str, Any], path: str, ref: PathRef, values: list[float]
) -> list[Problem]:
    """Each distinct value of an axis must make a valid model (checked on the plain data)."""
    problems: list[Problem] = []
    if ref.op in ("scale", "speed"):
        for k, val in enumerate(values):
            ok = val > 0 if ref.op == "scale" else val >= 0
            if not ok:
                what = "a scale factor > 0" if ref.op == "scale" else "a speed >= 0"
                problems.append(_study_problem(doc, where + (k,), f"expected {what}, got {val!r}"))
        return problems
    dpath = _dict_path(data, path)
    seen: set[float] = set()
    for k, val in enumerate(values):
        if val in seen or len(seen) > 200:
            continue
        seen.add(val)
        trial = copy.deepcopy(data)
        _set_in(trial, dpath, val)
        _, found = validate_model_data(trial)
        msgs = [e["msg"] for e in found.errors()] if isinstance(found, ValidationError) else [m for _, m in found]
        if msgs:
            problems.append(_study_problem(doc, where + (k,), f"value {val!r} makes the model invalid: {msgs[0]}"))
    return problems


def _axes(study: Study, doc: LoadedYaml, topo: Topology, data: dict[str, Any]) -> tuple[list[Axis], list[int], list[Problem]]:
    groups: list[tuple[tuple[str | int, ...], dict[str, list[float]]]] = [
        (("matrix", key), {key: vals}) for key, vals in study.matrix.items()
    ] + [(("zip", g), grp) for g, grp in enumerate(study.zip)]
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
            loc = where + (path,) if where[0] == "zip" else where
            if path in seen:
                problems.append(_study_problem(doc, loc, f"axis {path!r} appears twice"))
            seen.add(path)
            ref = topo.paths.get(path)
            if ref is None:
                problems.append(_study_problem(doc, loc, _unknown_path(path, topo)))
                continue
            problems.extend(_check_values(doc, loc, data, path, ref, vals))
            axes.append(Axis(path, np.asarray(vals, dtype=np.float64), dim, ref))
    return axes, shape, problems


def _unknown_path(path: str, topo: Topology) -> str:
    if path.startswith("output."):
        return f"{path!r} cannot vary across variants (all variants share one time axis); put it in 'set'"
    close = difflib.get_close_matches(path, list(topo.paths), n=3, cutoff=0.5)
    hint = f"; closest valid paths: {', '.join(close)}" if close else ""
    return f"unknown axis {path!r}: not a numeric field of the model{hint}"


def plan_from_model(lm: LoadedModel) -> Plan:
    """A one-variant plan for ``crashstudy simulate``."""
    return _plan(lm.model, lm.doc, None, [], [], None, {})


def _plan(m: Model, mdoc: LoadedYaml, sdoc: LoadedYaml | None, axes: list[Axis], shape: list[int],
          name: str | None, regression: dict[str, dict[str, float]]) -> Plan:  # fmt: skip
    topo, base = compile_model(m)
    end = [m.end_time] + [float(v) for ax in axes if ax.path == "end_time" for v in ax.values]
    interval = m.output.interval or max(end) / DEFAULT_SAMPLES
    n_out = int(math.floor(max(end) / interval + 1e-9)) + 1
    return Plan(
        name=name or m.name, topology=topo, base=base, axes=tuple(axes), shape=tuple(shape), interval=interval,
        n_out=n_out, model_text=mdoc.text, study_text=sdoc.text if sdoc else "", model_file=mdoc.file,
        study_file=sdoc.file if sdoc else "", regression=regression,
    )  # fmt: skip


def load_study(source: str | os.PathLike[str] | dict[str, Any]) -> Plan:
    """Read and validate a study (a path, or a dict as the YAML would load) into a :class:`Plan`."""
    if isinstance(source, dict):
        import yaml

        sdoc = loads_yaml(yaml.safe_dump(source, sort_keys=False), file="<study dict>")
        base_dir = Path.cwd()
    else:
        sdoc = load_yaml(source)
        base_dir = Path(source).resolve().parent
    refuse_foreign(sdoc)
    try:
        study = Study.model_validate(sdoc.data)
    except ValidationError as exc:
        raise InputError(pydantic_problems(exc, sdoc, Study)) from None
    model_path = (base_dir / study.model).resolve() if not os.path.isabs(study.model) else Path(study.model)
    if not model_path.is_file():
        raise InputError([_study_problem(sdoc, ("model",), f"model file not found: {model_path}")])
    mdoc = load_yaml(str(model_path))
    parse_model(mdoc)  # the model alone must be valid: its own errors point into its own file
    data = _apply_set(mdoc.data, study.set)
    m, found = validate_model_data(data)
    if isinstance(found, ValidationError) or found:
        errs = (pydantic_problems(found, LoadedYaml(data, mdoc.text, mdoc.file, {}), Model)
                if isinstance(found, ValidationError) else located(LoadedYaml(data, "", mdoc.file, {}), found))  # fmt: skip
        raise InputError([_study_problem(sdoc, ("set",), f"after 'set' the model is invalid: {p.field}: {p.message}")
                          for p in errs])  # fmt: skip
    assert m is not None
    topo, _ = compile_model(m)
    axes, shape, problems = _axes(study, sdoc, topo, data)
    if problems:
        raise InputError(problems)
    if math.prod(shape) > MAX_VARIANTS:
        raise InputError([_study_problem(sdoc, ("matrix",), f"{math.prod(shape):,} variants: at most "
                                         f"{MAX_VARIANTS:,} fit in one result file; split the study")])  # fmt: skip
    regression = {k: v.model_dump() for k, v in study.regression.items()}
    plan = _plan(m, mdoc, sdoc, axes, shape, study.name, regression)
    return plan
