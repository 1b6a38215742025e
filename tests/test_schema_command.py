"""`crashstudy schema model|study` prints a JSON Schema that accepts every example file and rejects
what `crashstudy validate` rejects for shape reasons."""

from __future__ import annotations

import json

import jsonschema
import pytest
from conftest import STUDIES

from crashstudy.cli import main
from crashstudy.yamlio import load_yaml


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
