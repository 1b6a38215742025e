"""One variant of a study as a model (the data a model file of that variant would hold).

The runner never needs this: it runs parameter vectors (:meth:`Plan.params`). Exporting a variant to
another program does. So the variant's vector is made exactly as the runner makes it, and each slot
an axis changed is written back at its model path (``Topology.paths``, a "set" path per slot:
``nodes.<id>.mass``, ``initial_velocity.<id>.<k>`` after an ``impact_velocity`` axis, ...); a curve's
``scale`` / ``x_scale`` factor (one slot each, applied in the kernel) multiplies the curve's points.
"""

from __future__ import annotations

import copy
from typing import Any

from crashstudy.errors import InputError, Problem
from crashstudy.schema.study import Study
from crashstudy.schema.yamlio import load_yaml
from crashstudy.study.overrides import _apply_set
from crashstudy.study.plan import Plan
from crashstudy.study.values import dict_path, set_in


def variant_data(plan: Plan, study_file: str, n: int) -> dict[str, Any]:
    """Model data of variant ``n`` of the study ``study_file`` (already loaded as ``plan``)."""
    if not 0 <= n < plan.n_variants:
        raise InputError(
            [
                Problem(
                    study_file,
                    None,
                    "--variant",
                    f"variant {n} does not exist: the study has "
                    f"{plan.n_variants} variants, numbered 0 to {plan.n_variants - 1}",
                )
            ]
        )
    sdoc = load_yaml(study_file)
    study = Study.model_validate(sdoc.data)
    data = _apply_set(copy.deepcopy(load_yaml(plan.model_file).data), study.set, sdoc)
    topo = plan.topology
    P = plan.params(n, n + 1)[:, 0]
    for path, ref in topo.paths.items():
        if ref.op == "set" and len(ref.slots) == 1 and P[ref.slots[0]] != plan.base[ref.slots[0]]:
            set_in(data, dict_path(data, path), float(P[ref.slots[0]]))
    fac = topo.blocks["cfac"].start
    for c, cid in enumerate(topo.curve_ids):
        for key, slot in (("y", fac + 2 * c), ("x", fac + 2 * c + 1)):
            if P[slot] != 1.0:
                data["curves"][cid][key] = [v * float(P[slot]) for v in data["curves"][cid][key]]
    return data
