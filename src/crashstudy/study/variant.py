"""One variant of a study as a model (the data a model file of that variant would hold).

The runner never needs this (it works on parameter vectors, :meth:`Plan.params`); exporting a variant
to another program does. The model file with the study's ``set:`` applied, then each axis value of
variant ``n`` (numbered as :mod:`crashstudy.study.plan` says) applied the way :func:`apply_axis` applies
it to the parameter vector: ``set`` replaces the value at the path, ``scale`` multiplies a curve's
values (``curves.<id>.scale``) or abscissae (``x_scale``), ``speed`` rescales every initial velocity.
"""

from __future__ import annotations

import copy
import math
from typing import Any

from crashstudy.errors import InputError, Problem
from crashstudy.schema.study import Study
from crashstudy.schema.yamlio import load_yaml
from crashstudy.study.plan import Plan, _apply_set, _dict_path, _set_in


def variant_data(plan: Plan, study_file: str, n: int) -> dict[str, Any]:
    """Model data of variant ``n`` of the study ``study_file`` (already loaded as ``plan``)."""
    if not 0 <= n < plan.n_variants:
        raise InputError([Problem(study_file, None, "--variant", f"variant {n} does not exist: the study has "
                                  f"{plan.n_variants} variants, numbered 0 to {plan.n_variants - 1}")])  # fmt: skip
    sdoc = load_yaml(study_file)
    study = Study.model_validate(sdoc.data)
    data = _apply_set(copy.deepcopy(load_yaml(plan.model_file).data), study.set, sdoc)
    for ax in plan.axes:
        value = float(plan.axis_values(n, n + 1)[ax.path][0])
        parts = ax.path.split(".")  # curve ids hold no '.' (schema.model.Id)
        if ax.ref.op == "speed":
            for node, v in data.get("initial_velocity", {}).items():
                size = math.sqrt(sum(c * c for c in v))
                data["initial_velocity"][node] = [c * (value / size) if size > 0 else 0.0 for c in v]
        elif ax.ref.op == "scale":
            curve = data["curves"][parts[1]]
            key = "y" if parts[2] == "scale" else "x"
            curve[key] = [c * value for c in curve[key]]
        else:
            _set_in(data, _dict_path(data, ax.path), value)
    return data
