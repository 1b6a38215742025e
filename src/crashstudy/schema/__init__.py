"""Schema stage: YAML text -> validated pydantic objects, or an InputError naming file, line and field."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from crashstudy.errors import InputError, Problem
from crashstudy.schema.yamlio import LoadedYaml, load_yaml

if TYPE_CHECKING:
    from pydantic import ValidationError

    from crashstudy.schema.model import Model

__all__ = [
    "LoadedModel",
    "Model",
    "file_kind",
    "load_model",
    "parse_model",
    "refuse_foreign",
    "validate_model_data",
]


def __getattr__(name: str) -> Any:
    """``Model``, imported when first asked for: pydantic and the model classes (~0.5 s) are not
    imported by a module that only needs this package's light parts (a ``--jobs`` worker
    unpickling a plan: ``arrays.parameter_checks`` -> ``schema.signs``)."""
    if name == "Model":
        from crashstudy.schema.model import Model

        return Model
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


@dataclass(frozen=True)
class LoadedModel:
    """A validated model and the document it came from (kept for line numbers and provenance)."""

    model: Model
    doc: LoadedYaml


def validate_model_data(
    data: Any,
) -> tuple[Model | None, list[tuple[tuple[Any, ...], str]] | ValidationError]:
    """Validate plain data; returns ``(model, [])``, ``(model, relational problems)`` or ``(None, error)``."""
    from pydantic import ValidationError

    from crashstudy.schema.checks import model_problems
    from crashstudy.schema.model import Model

    try:
        m = Model.model_validate(data)
    except ValidationError as exc:
        return None, exc
    return m, model_problems(m)


def refuse_foreign(doc: LoadedYaml) -> None:
    """Raise one :class:`InputError` for a mapping that has none of a model's or a study's top-level keys.

    Such a file is not ours (a configuration file, ``key: value`` lines of another program): listing
    each of its keys as "unknown" would echo the file, so nothing of it is quoted."""
    from crashstudy.schema.model import Model
    from crashstudy.schema.study import Study

    ours = {name for cls in (Model, Study) for name in cls.model_fields}
    if isinstance(doc.data, dict) and doc.data and not ours.intersection(doc.data):
        first = doc.line_of((next(iter(doc.data)),))
        raise InputError(
            [
                Problem(
                    doc.file,
                    first,
                    "",
                    f"not a crashstudy model or study file: none of its "
                    f"{len(doc.data)} top-level keys is one of ours (a model has name, nodes, springs, "
                    "...; a study has name, model, matrix, ...)",
                )
            ]
        )


def file_kind(data: Any) -> str | None:
    """``"model"`` or ``"study"`` by the top-level keys only one of the two formats has; ``None`` if neither.

    A study without its ``model:`` key is still a study (it has ``matrix``, ``zip``, ``set`` ...), so
    its error is the missing ``model:``, not every study key reported as unknown to a model."""
    from crashstudy.schema.model import Model
    from crashstudy.schema.study import Study

    if not isinstance(data, dict):
        return None
    shared = set(Model.model_fields) & set(Study.model_fields)
    model_keys = (set(Model.model_fields) - shared) & set(data)
    study_keys = (set(Study.model_fields) - shared) & set(data)
    if model_keys and study_keys:  # a mixture: what it has most of, "nodes" deciding a tie
        if len(model_keys) == len(study_keys):
            return "model" if "nodes" in data else "study"
        return "model" if len(model_keys) > len(study_keys) else "study"
    return "model" if model_keys else "study" if study_keys else None


def parse_model(doc: LoadedYaml) -> LoadedModel:
    """Validate a loaded document as a model file; raise :class:`InputError` with every problem."""
    from pydantic import ValidationError

    from crashstudy.schema.checks import raw_reference_problems
    from crashstudy.schema.model import Model
    from crashstudy.schema.report import located, pydantic_problems

    refuse_foreign(doc)
    m, found = validate_model_data(doc.data)
    if isinstance(found, ValidationError):
        problems = pydantic_problems(found, doc, Model)
        seen = {p.field for p in problems}
        extra = [p for p in located(doc, raw_reference_problems(doc.data)) if p.field not in seen]
        raise InputError(sorted(problems + extra, key=lambda p: p.line or 0))
    if found:
        raise InputError(located(doc, found))
    assert m is not None
    return LoadedModel(m, doc)


def load_model(path: str) -> LoadedModel:
    """Read, parse and validate a model file."""
    return parse_model(load_yaml(path))
