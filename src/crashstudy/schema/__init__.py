"""Schema stage: YAML text -> validated pydantic objects, or an InputError naming file, line and field."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from pydantic import ValidationError

from crashstudy.errors import InputError
from crashstudy.schema.checks import model_problems, raw_reference_problems
from crashstudy.schema.model import Model
from crashstudy.schema.report import located, pydantic_problems
from crashstudy.yamlio import LoadedYaml, load_yaml

__all__ = ["LoadedModel", "Model", "load_model", "parse_model", "validate_model_data"]


@dataclass(frozen=True)
class LoadedModel:
    """A validated model and the document it came from (kept for line numbers and provenance)."""

    model: Model
    doc: LoadedYaml


def validate_model_data(data: Any) -> tuple[Model | None, list[tuple[tuple[Any, ...], str]] | ValidationError]:
    """Validate plain data; returns ``(model, [])``, ``(model, relational problems)`` or ``(None, error)``."""
    try:
        m = Model.model_validate(data)
    except ValidationError as exc:
        return None, exc
    return m, model_problems(m)


def parse_model(doc: LoadedYaml) -> LoadedModel:
    """Validate a loaded document as a model file; raise :class:`InputError` with every problem."""
    m, found = validate_model_data(doc.data)
    if isinstance(found, ValidationError):
        problems = pydantic_problems(found, doc, Model)
        seen = {p.field for p in problems}
        extra = [p for p in located(doc, raw_reference_problems(doc.data)) if p.field not in seen]
        raise InputError(sorted(problems + extra, key=lambda p: (p.line or 0)))
    if found:
        raise InputError(located(doc, found))
    assert m is not None
    return LoadedModel(m, doc)


def load_model(path: str) -> LoadedModel:
    """Read, parse and validate a model file."""
    return parse_model(load_yaml(path))
