"""Tests of crashstudy.schema.yamlio: plain data and line numbers, and rule 1, YAML 1.2 core-schema
scalars."""

from __future__ import annotations

import math

import pytest

from crashstudy.errors import Problem
from crashstudy.schema.yamlio import LoadedYaml, format_path, loads_yaml
from yamlio_checks import only_problem

MODEL = """\
name: helicopter-subfloor
units: SI
curves:
  loading: {x: [-0.5, -0.2, 0.0], y: [-76000, -57200, 0]}
  drop:
    x:
      - 0
      - 0.01
      - 0.02
    y: [0, 1, 0]
nodes:
  ground: {position: [0.0, 0.0], fixed: true}
  cabin:
    position: [0.0, 0.9]
    mass: 1500.0
springs:
  cabin:
    nodes: [ground, cabin]
    material: {type: linear_elastic, stiffness: 2.0e7}
loads:
  - {node: cabin, force: [0.0, -1000.0]}
  -
    node: ground
end_time: 0.08
"""


# --- data and line numbers ------------------------------------------------------------------


def test_model_loads_to_plain_data_with_floats_from_exponents() -> None:
    loaded = loads_yaml(MODEL, "m.yaml")
    assert loaded.file == "m.yaml" and loaded.text == MODEL
    assert loaded.data["springs"]["cabin"]["material"] == {"type": "linear_elastic", "stiffness": 2.0e7}
    assert loaded.data["curves"]["drop"]["x"] == [0, 0.01, 0.02]
    assert loaded.data["nodes"]["ground"]["fixed"] is True
    assert loaded.data["loads"][1] == {"node": "ground"}


def test_lines_of_block_and_flow_keys_and_items() -> None:
    loaded = loads_yaml(MODEL, "m.yaml")
    assert loaded.lines[()] == 1
    assert loaded.lines[("name",)] == 1
    assert loaded.lines[("springs", "cabin", "material", "stiffness")] == 19
    assert loaded.lines[("springs", "cabin", "nodes", 1)] == 18
    assert loaded.lines[("curves", "drop", "x", 2)] == 9  # block sequence item
    assert loaded.lines[("curves", "loading", "y", 2)] == 4  # flow sequence item
    assert loaded.lines[("nodes", "cabin", "mass")] == 15
    assert loaded.lines[("loads", 0)] == 21
    assert loaded.lines[("loads", 1)] == 23  # an item written on the line after its dash
    assert loaded.lines[("loads", 1, "node")] == 23
    assert loaded.lines[("end_time",)] == 24


def test_lines_of_flow_items_spread_over_lines() -> None:
    loaded = loads_yaml("curves:\n  c1: {x: [0,\n    1, 2,\n    3], y: [0, 1, 2, 3]}\n")
    assert [loaded.lines[("curves", "c1", "x", i)] for i in range(4)] == [2, 3, 3, 4]
    assert loaded.lines[("curves", "c1", "y")] == 4


def test_line_of_falls_back_to_nearest_ancestor_and_root() -> None:
    loaded = loads_yaml(MODEL, "m.yaml")
    assert loaded.line_of(("springs", "cabin", "material", "stiffness")) == 19
    assert loaded.line_of(("springs", "cabin", "material", "damping")) == 19
    assert loaded.line_of(("springs", "cabin", "nodes", 7)) == 18
    assert loaded.line_of(("no_such_key", "deeper")) == 1
    assert loaded.line_of(()) == 1
    assert LoadedYaml(data={}, text="", file="x", lines={}).line_of(("a",)) is None


def test_problem_helper_gives_dotted_field_and_line() -> None:
    loaded = loads_yaml(MODEL, "m.yaml")
    problem = loaded.problem(("springs", "cabin", "material", "stiffness"), "expected > 0")
    assert problem == Problem("m.yaml", 19, "springs.cabin.material.stiffness", "expected > 0")
    assert problem.format() == "m.yaml:19: springs.cabin.material.stiffness: expected > 0"
    assert format_path(("loads", 0, "node")) == "loads.0.node"


# --- rule 1: YAML 1.2 core-schema scalars ---------------------------------------------------


@pytest.mark.parametrize(
    ("text", "value"),
    [
        ("2.0e7", 2.0e7),
        ("1e-3", 1e-3),
        ("5E+4", 5e4),
        (".5", 0.5),
        ("-1.5e-3", -1.5e-3),
        ("+2.", 2.0),
        ("1e999", math.inf),
        (".inf", math.inf),
        ("-.Inf", -math.inf),
        ("+.INF", math.inf),
    ],
)
def test_core_schema_floats(text: str, value: float) -> None:
    loaded = loads_yaml(f"v: {text}\n")
    assert type(loaded.data["v"]) is float and loaded.data["v"] == value


def test_nan_parses_to_float_nan() -> None:
    assert math.isnan(loads_yaml("v: .nan\n").data["v"])


@pytest.mark.parametrize(
    ("text", "value"),
    [
        ("0", 0),
        ("42", 42),
        ("-17", -17),
        ("+3", 3),
        ("007", 7),
        ("0x1F", 31),
        ("0o17", 15),
        ("9" * 30, int("9" * 30)),
    ],
)
def test_core_schema_ints(text: str, value: int) -> None:
    loaded = loads_yaml(f"v: {text}\n")
    assert type(loaded.data["v"]) is int and loaded.data["v"] == value


@pytest.mark.parametrize(
    ("text", "value"),
    [
        ("true", True),
        ("True", True),
        ("TRUE", True),
        ("false", False),
        ("False", False),
        ("FALSE", False),
        ("null", None),
        ("~", None),
        ("", None),
        ("NULL", None),
    ],
)
def test_core_schema_bools_and_nulls(text: str, value: bool | None) -> None:
    assert loads_yaml(f"v: {text}\n").data["v"] is value


@pytest.mark.parametrize(
    "text",
    [
        "yes",
        "no",
        "on",
        "off",
        "Yes",
        "OFF",
        "y",
        "n",
        "2024-01-01",
        "1_000",
        "0b101",
        "1:30",
        "0x",
        "1e",
        "e3",
        ".",
        "-1-",
        "tRUE",
        "nan",
        "inf",
    ],
)
def test_yaml11_only_forms_stay_strings(text: str) -> None:
    assert loads_yaml(f"v: {text}\n").data["v"] == text


def test_quoted_numbers_stay_strings_and_keys_are_always_strings() -> None:
    loaded = loads_yaml("a: '1e-3'\nb: \"12\"\n1: one\ntrue: t\nnull: n\n1.5: x\n")
    assert loaded.data == {"a": "1e-3", "b": "12", "1": "one", "true": "t", "null": "n", "1.5": "x"}
    assert loaded.lines[("1",)] == 3


def test_explicit_plain_data_tags_are_accepted() -> None:
    loaded = loads_yaml(
        "a: !!str 12\nb: !!float 1\nc: !!int '7'\nd: !!bool 'true'\ne: !!null ''\n"
        "f: !!seq [1]\ng: !!map {k: v}\n"
    )
    assert loaded.data == {"a": "12", "b": 1.0, "c": 7, "d": True, "e": None, "f": [1], "g": {"k": "v"}}
    assert type(loaded.data["b"]) is float


def test_explicit_tag_with_a_value_of_the_wrong_form_is_an_error() -> None:
    problem = only_problem("a: 1\nb: !!int 1.5\n")
    assert (problem.line, problem.field) == (2, "b")
    assert problem.message == "expected an integer after !!int, found '1.5'"
