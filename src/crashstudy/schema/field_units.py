"""The unit kind of a model field, read from the schema: every numeric field of :mod:`crashstudy.schema.model`
states its unit in its description (``"yield force in tension [force] > 0"``), so the unit of a study axis
is written once, beside the field it belongs to, and a field added later brings its unit with it.

Curve points are the exception: their unit follows what uses the curve (a material curve maps
elongation to force, a load curve time to a factor, a prescribed motion time to its quantity), so it is
read from the model's own text."""

from __future__ import annotations

import re
import types
import typing
from typing import Any

from pydantic import BaseModel

from crashstudy.schema.model import Model

# the bracketed unit of a description -> unit kind (a key of crashstudy.results.attributes.units_of)
KINDS = {
    "length": "length",
    "time": "time",
    "mass": "mass",
    "force": "force",
    "1": "1",
    "force/length": "stiffness",
    "force*time/length": "damping",
    "length/time": "velocity",
    "length/time^2": "acceleration",
}
_BRACKET = re.compile(r"\[([^\]]+)\]")
_MOTION = {"displacement": "length", "velocity": "velocity", "acceleration": "acceleration"}


def description_kind(description: str | None) -> str | None:
    """The unit kind of the first bracketed unit of a field description (None without one)."""
    for m in _BRACKET.finditer(description or ""):
        if m.group(1) in KINDS:
            return KINDS[m.group(1)]
    return None


def _classes(annotation: Any) -> list[type[BaseModel]]:
    """The schema classes an annotation may hold (through Annotated, unions, lists and mappings)."""
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return [annotation]
    out: list[type[BaseModel]] = []
    for arg in typing.get_args(annotation):
        out += _classes(arg)
    return out


def _skips(annotation: Any) -> int:
    """How many path parts a container annotation takes before its items (a mapping key, a list index)."""
    origin = typing.get_origin(annotation)
    if origin is typing.Annotated:
        return _skips(typing.get_args(annotation)[0])
    if origin in (typing.Union, types.UnionType):
        return max((_skips(a) for a in typing.get_args(annotation)), default=0)
    if origin in (dict, list):
        return 1 + max((_skips(a) for a in typing.get_args(annotation)[-1:]), default=0)
    return 0


def schema_kind(path: str) -> str | None:
    """The unit kind of a model field path (``springs.s.material.yield_force``, ``nodes.a.position.0``)
    from the description of the field it ends in; None when no field states one."""
    parts = path.split(".")
    classes: list[type[BaseModel]] = [Model]
    k = 0
    while k < len(parts):
        name = parts[k]
        owner = next((c for c in classes if name in c.model_fields), None)
        if owner is None:
            return None
        field = owner.model_fields[name]
        inner = _classes(field.annotation)
        if not inner:  # a number or a vector of numbers: this field states the unit
            return description_kind(field.description)
        classes = inner
        k += 1 + _skips(field.annotation)
    return None


def curve_kind(path: str, model: dict[str, Any]) -> str | None:
    """Unit kind of a point of a curve (``curves.<id>.x.<k>`` / ``.y.<k>``) by what uses the curve in
    ``model`` (the model file as loaded); None when nothing or several uses of different units do."""
    parts = path.split(".")
    if len(parts) < 3 or parts[2] not in ("x", "y"):
        return None
    cid, axis = parts[1], parts[2]
    uses: set[tuple[str, str]] = set()
    for spring in (model.get("springs") or {}).values():
        mat = (spring or {}).get("material") or {}
        for key in ("curve", "loading", "unloading"):
            if mat.get(key) == cid:
                uses.add(("velocity" if mat.get("type") == "nonlinear_damper" else "length", "force"))
        rate_curves = mat.get("curves")  # rate_elastic: a list of {rate, curve}
        if isinstance(rate_curves, list) and any(
            isinstance(rc, dict) and rc.get("curve") == cid for rc in rate_curves
        ):
            uses.add(("length", "force"))
    for load in model.get("loads") or []:
        if (load or {}).get("curve") == cid:
            uses.add(("time", "1"))
    for pm in model.get("prescribed_motion") or []:
        if (pm or {}).get("curve") == cid:
            uses.add(("time", _MOTION.get(str(pm.get("quantity")), "1")))
    kinds = {u[0] if axis == "x" else u[1] for u in uses}
    return kinds.pop() if len(kinds) == 1 else None
