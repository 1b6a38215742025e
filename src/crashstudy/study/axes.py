"""A study's axes: the ``matrix``, ``zip`` and ``design`` groups as :class:`Axis` objects, each distinct
value checked (vectorised) to make a valid model with the rest of the model as written."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from crashstudy.arrays.compiler import PathRef, Topology
from crashstudy.errors import Problem
from crashstudy.schema.yamlio import LoadedYaml
from crashstudy.study.values import check_values, study_problem, unknown_path

if TYPE_CHECKING:
    from crashstudy.schema.study import Study


@dataclass(frozen=True)
class Axis:
    """One study axis: a model path, its values and the index of the (matrix or zip) dimension."""

    path: str
    values: np.ndarray
    dim: int
    ref: PathRef


def _axes(
    study: Study, doc: LoadedYaml, topo: Topology, data: dict[str, Any], base: np.ndarray, interval: float
) -> tuple[list[Axis], list[int], list[Problem]]:
    groups: list[tuple[tuple[str | int, ...], dict[str, Any]]] = [
        (("matrix", key), {key: vals}) for key, vals in study.matrix.items()
    ] + [(("zip", g), grp) for g, grp in enumerate(study.zip)]
    if study.design is not None:  # its rows: one dimension after matrix and zip, its axes varying together
        from crashstudy.study.design import rows

        d = study.design
        groups.append(
            (
                ("design", "axes"),
                rows(d.method, d.n, d.seed, {path: dist.spec() for path, dist in d.axes.items()}),
            )
        )
    axes: list[Axis] = []
    shape: list[int] = []
    problems: list[Problem] = []
    seen: set[str] = set()
    for dim, (where, grp) in enumerate(groups):
        lengths = {len(v) for v in grp.values()}
        if len(lengths) > 1:
            problems.append(
                study_problem(
                    doc, where, f"the axes of a zip group need equal lengths, got {sorted(lengths)}"
                )
            )
        shape.append(min(lengths))
        for path, vals in grp.items():
            loc = where + (path,) if where[0] in ("zip", "design") else where
            if path in seen:
                problems.append(study_problem(doc, loc, f"axis {path!r} appears twice"))
            seen.add(path)
            ref = topo.paths.get(path)
            if ref is None:
                problems.append(study_problem(doc, loc, unknown_path(path, topo)))
                continue
            problems.extend(check_values(doc, loc, data, path, ref, vals, topo, base, interval))
            axes.append(Axis(path, np.asarray(vals, dtype=np.float64), dim, ref))
    return axes, shape, problems
