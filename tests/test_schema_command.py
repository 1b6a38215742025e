"""`crashstudy schema model|study` prints a JSON Schema that accepts every example file and rejects
what `crashstudy validate` rejects for shape reasons."""

from __future__ import annotations

import json

import jsonschema
import pytest

from crashstudy.cli.main import main
from crashstudy.schema.yamlio import load_yaml
from helpers import STUDIES


def _schema(kind: str, capsys: pytest.CaptureFixture[str]) -> dict:
    assert main(["schema", kind]) == 0
    return json.loads(capsys.readouterr().out)


def test_model_schema_accepts_every_example_model(capsys: pytest.CaptureFixture[str]) -> None:
    schema = _schema("model", capsys)
    files = sorted((STUDIES / "models").glob("*.yaml"))
    assert len(files) >= 6
    for f in files:
        jsonschema.validate(load_yaml(f).data, schema)  # YAML 1.2 numbers, as crashstudy reads them


def test_study_schema_accepts_every_example_study(capsys: pytest.CaptureFixture[str]) -> None:
    schema = _schema("study", capsys)
    files = sorted(STUDIES.glob("*.yaml"))
    assert len(files) >= 3
    for f in files:
        jsonschema.validate(load_yaml(f).data, schema)  # YAML 1.2 numbers, as crashstudy reads them


@pytest.mark.parametrize(
    ("patch", "why"),
    [
        ({"units": "inch"}, "unknown unit system"),
        ({"nodes": {"a": {"position": [0.0], "mass": -1.0}}}, "negative mass"),
        ({"stifness": 1.0}, "unknown key"),
        ({"time_step": {"safety_factor": 1.5}}, "safety_factor above 1"),
    ],
)
def test_model_schema_rejects_shape_errors(patch: dict, why: str, capsys: pytest.CaptureFixture[str]) -> None:
    schema = _schema("model", capsys)
    model = {"name": "m", "nodes": {"a": {"position": [0.0], "mass": 1.0}}, "end_time": 1.0}
    jsonschema.validate(model, schema)  # the base is valid
    with pytest.raises(jsonschema.ValidationError):
        jsonschema.validate({**model, **patch}, schema)


def _properties(node: object, where: str = "") -> list[tuple[str, dict]]:
    """Every ``(path, property schema)`` under a ``properties`` key, at any depth (``$defs`` included)."""
    found: list[tuple[str, dict]] = []
    if isinstance(node, dict):
        for key, sub in (node.get("properties") or {}).items():
            found.append((f"{where}.{key}", sub))
        for key, sub in node.items():
            found.extend(_properties(sub, f"{where}/{key}"))
    elif isinstance(node, list):
        for k, sub in enumerate(node):
            found.extend(_properties(sub, f"{where}[{k}]"))
    return found


@pytest.mark.parametrize(("kind", "at_least"), [("model", 56), ("study", 9)])
def test_every_schema_property_has_a_one_line_description(
    kind: str, at_least: int, capsys: pytest.CaptureFixture[str]
) -> None:
    """Editors show a property's ``description`` on hover: every key of a model or study file has one."""
    props = _properties(_schema(kind, capsys))
    assert len(props) >= at_least  # model: 17 top-level keys + 39 nested ones; study: 7 + 2
    missing = [p for p, sub in props if not str(sub.get("description", "")).strip()]
    assert missing == []
    multi = [p for p, sub in props if "\n" in sub["description"]]
    assert multi == []


@pytest.mark.parametrize("kind", ["model", "study"])
def test_every_numeric_schema_property_states_its_units(
    kind: str, capsys: pytest.CaptureFixture[str]
) -> None:
    """A property that holds numbers says its unit in brackets (``[force/length]``, ``[1]``, ...)."""
    numeric = [
        (p, sub)
        for p, sub in _properties(_schema(kind, capsys))
        if '"number"' in json.dumps({k: v for k, v in sub.items() if k != "description"})
    ]
    assert len(numeric) >= (22 if kind == "model" else 4)
    assert [p for p, sub in numeric if "[" not in sub["description"]] == []


def test_schema_points_nowhere_outside_the_repository(capsys: pytest.CaptureFixture[str]) -> None:
    """The emitted schemas name docs/format.md, never a file a user's clone does not have."""
    text = json.dumps(_schema("model", capsys)) + json.dumps(_schema("study", capsys))
    assert "SPEC" not in text and "shared/" not in text
    assert "docs/format.md" in text
