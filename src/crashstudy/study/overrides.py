"""A study's ``set``: the model edits it makes (dotted paths into the model's data), each refused with
the study file's line and the reason when the path cannot be set."""

from __future__ import annotations

import copy
import difflib
from typing import Any

from crashstudy.errors import InputError, Problem
from crashstudy.schema.yamlio import LoadedYaml
from crashstudy.study.values import MAX_REPORTED, dict_path, set_in, study_problem


def _unknown_set_keys(overrides: dict[str, Any], sdoc: LoadedYaml) -> list[Problem]:
    """Keys of ``set`` whose first part is no model field: the first :data:`MAX_REPORTED`, then how many
    more (checked before the model is copied and validated: 499,000 such keys took 21 s to refuse)."""
    from crashstudy.schema.model import Model

    unknown = [k for k in overrides if k.split(".", 1)[0] not in Model.model_fields]
    fields = list(Model.model_fields)
    problems = []
    for key in unknown[:MAX_REPORTED]:
        close = difflib.get_close_matches(key.split(".", 1)[0], fields, n=3, cutoff=0.6)
        hint = f"; closest: {', '.join(close)}" if close else f"; expected one of {', '.join(fields)}"
        problems.append(
            study_problem(
                sdoc,
                ("set", key),
                f"unknown model field {key.split('.', 1)[0]!r} (set: "
                f"takes model fields or dotted paths into them){hint}",
            )
        )
    if len(unknown) > MAX_REPORTED:
        problems.append(
            study_problem(
                sdoc,
                ("set",),
                f"and {len(unknown) - MAX_REPORTED:,} more keys under set: that are not model fields",
            )
        )
    return problems


def _apply_set(data: dict[str, Any], overrides: dict[str, Any], sdoc: LoadedYaml) -> dict[str, Any]:
    problems = _unknown_set_keys(overrides, sdoc)
    if problems:
        raise InputError(problems)
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
        why = set_in(data, dict_path(data, key), value)
        if why:
            problems.append(study_problem(sdoc, ("set", key), why))
    if problems:
        raise InputError(problems)
    return data


def _set_problem(sdoc: LoadedYaml, overrides: dict[str, Any], p: Problem) -> Problem:
    """A problem of the model after ``set``: at the study's ``set`` line, or inside a ``metrics`` list that
    ``set`` gives (its entry's own line and field path: ``set.metrics.0.node``)."""
    head = p.field.split(".")[0]
    if head == "metrics" and "metrics" in overrides:
        path = ("set", *(int(k) if k.isdigit() else k for k in p.field.split(".")))
        return study_problem(sdoc, path, f"after 'set' the model is invalid: {p.message}")
    return study_problem(sdoc, ("set",), f"after 'set' the model is invalid: {p.field}: {p.message}")
