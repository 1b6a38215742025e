"""What a result file says about its plan besides the numbers: the unit of every variable and study
axis, the plan's fingerprint (a resumed partial file must come from the same plan), and the model
facts that ``plot`` and ``compare`` read instead of the YAML."""

from __future__ import annotations

import hashlib
import json
from typing import Any

import numpy as np

from crashstudy import __version__
from crashstudy.study.plan import Plan
from crashstudy.units import UNIT_SYSTEMS


def units_of(plan: Plan) -> dict[str, str]:
    """The unit of each unit kind (``SUMMARY_META``, ``HISTORY_META``, :func:`axis_unit`) in the plan's system."""
    u = UNIT_SYSTEMS[plan.topology.units]
    return {
        "length": u.length,
        "time": u.time,
        "velocity": u.velocity,
        "acceleration": u.acceleration,
        "force": u.force,
        "energy": u.energy,
        "mass": u.mass,
        "1": "1",
        "g": "g",
        "stiffness": f"{u.force}/{u.length}",
        "damping": f"{u.force}*{u.time}/{u.length}",
        "impulse": f"{u.force}*{u.time}",
        "curve": "curve units (x: length or time, y: force or motion)",
    }


def axis_unit(path: str, plan: Plan) -> str:
    """Unit kind (a key of the units table) of the model field a study axis varies: the unit its schema
    field states (:mod:`crashstudy.schema.field_units`), for a curve point that of the curve's use."""
    from crashstudy.schema.field_units import curve_kind, schema_kind

    parts = path.split(".")
    if path == "impact_velocity":
        return "velocity"
    if parts[0] == "curves":
        if parts[-1] in ("scale", "x_scale"):
            return "1"
        import yaml

        model = yaml.safe_load(plan.model_text) or {}
        return curve_kind(path, model if isinstance(model, dict) else {}) or "curve"
    return schema_kind(path) or "1"


def plan_fingerprint(plan: Plan) -> str:
    """Hash of everything that determines the results of a plan."""
    h = hashlib.sha256()
    h.update(plan.model_text.encode())
    h.update(plan.study_text.encode())
    h.update(plan.base.tobytes())
    for ax in plan.axes:
        h.update(ax.path.encode())
        h.update(ax.values.tobytes())
    h.update(__version__.encode())
    return h.hexdigest()[:32]


def model_facts(p: Plan) -> dict[str, str]:
    """JSON attributes for plot, compare and the warnings after a run (they never re-read the YAML): free
    nodes (not fixed in every direction, not driven), node masses of the model, the ``regression:``
    tolerances, and the body (:func:`body_facts`)."""
    topo = p.topology
    driven = set(np.asarray(topo.pm_node).tolist())
    free = [n for k, n in enumerate(topo.node_ids) if not bool(np.all(topo.fixed[k])) and k not in driven]
    mass = {
        n: float(p.base[topo.paths[f"nodes.{n}.mass"].slots[0]])
        for n in topo.node_ids
        if f"nodes.{n}.mass" in topo.paths
    }
    return {
        "free_nodes": json.dumps(free),
        "node_mass": json.dumps(mass),
        "regression": json.dumps(p.regression),
        "body": json.dumps(body_facts(p)),
    }


def body_facts(p: Plan) -> dict[str, Any]:
    """What the peak-deceleration check after a run needs of the model: ``node``, the heaviest node that
    moves freely (fixed in no direction, no prescribed motion: the vehicle or occupant body; None when
    there is none), ``initial_speeds`` (the model's initial speed of each node given one) and
    ``prescribed_motion`` (whether the model drives a node)."""
    topo = p.topology
    driven = set(np.asarray(topo.pm_node).tolist())
    free = [
        (float(p.base[topo.paths[f"nodes.{n}.mass"].slots[0]]), n)
        for k, n in enumerate(topo.node_ids)
        if not bool(np.any(topo.fixed[k])) and k not in driven
    ]
    dim = topo.fixed.shape[1]
    speeds = [
        float(np.linalg.norm([p.base[topo.paths[f"initial_velocity.{n}.{d}"].slots[0]] for d in range(dim)]))
        for n in topo.node_ids
        if f"initial_velocity.{n}.0" in topo.paths
    ]
    return {
        "node": max(free)[1] if free else None,
        "initial_speeds": speeds,
        "prescribed_motion": bool(driven),
    }
