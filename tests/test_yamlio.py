"""Tests of crashstudy.schema.yamlio: core-schema scalars, line numbers, and refusal of bad input."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from crashstudy.errors import InputError, Problem
from crashstudy.schema.yamlio import MAX_BYTES, LoadedYaml, format_path, load_yaml, loads_yaml

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


def problems_of(text: str) -> list[Problem]:
    with pytest.raises(InputError) as info:
        loads_yaml(text, "m.yaml")
    return info.value.problems


def only_problem(text: str) -> Problem:
    problems = problems_of(text)
    assert len(problems) == 1, problems
    return problems[0]


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


# --- rule 2: duplicate keys ------------------------------------------------------------------


def test_duplicate_key_names_key_and_both_lines() -> None:
    text = "springs:\n  cabin:\n    nodes: [a, b]\n  floor: {}\n  cabin:\n    nodes: [b, c]\n"
    problem = only_problem(text)
    assert problem == Problem("m.yaml", 5, "springs.cabin", "duplicate key 'cabin' (first at line 2)")


def test_every_duplicate_key_is_reported_at_once() -> None:
    problems = problems_of("a: 1\nb: {x: 1, x: 2}\na: 3\n")
    assert [(p.line, p.field, p.message) for p in problems] == [
        (2, "b.x", "duplicate key 'x' (first at line 2)"),
        (3, "a", "duplicate key 'a' (first at line 1)"),
    ]


def test_keys_equal_as_text_are_duplicates_even_if_quoted() -> None:
    assert only_problem("1: a\n'1': b\n").message == "duplicate key '1' (first at line 1)"


# --- rule 3: tags ----------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("value", "tag"),
    [
        ("!!python/object/apply:os.system ['echo hi']", "!!python/object/apply:os.system"),
        ("!!python/object:collections.OrderedDict {}", "!!python/object:collections.OrderedDict"),
        ("!!python/name:os.system ''", "!!python/name:os.system"),
        ("!custom 3", "!custom"),
        ("!!binary aGVsbG8=", "!!binary"),
        ("!!timestamp 2024-01-01", "!!timestamp"),
        ("!!set {a, b}", "!!set"),
    ],
)
def test_unsafe_or_unknown_tags_are_refused_with_tag_and_line(value: str, tag: str) -> None:
    problem = only_problem(f"name: x\nspring:\n  k: {value}\n")
    assert (problem.line, problem.field) == (3, "spring.k")
    assert problem.message.startswith(f"unsupported tag {tag}")


def test_tagged_key_is_refused() -> None:
    problem = only_problem("a: 1\n!!python/name:os.system x: 2\n")
    assert problem.line == 2 and "unsupported tag !!python/name:os.system" in problem.message


def test_tag_on_top_level_mapping_is_refused() -> None:
    problem = only_problem("!!python/object:crashstudy.Model\nname: x\n")
    assert problem.line == 1 and problem.message.startswith(
        "unsupported tag !!python/object:crashstudy.Model"
    )


def test_merge_keys_are_refused_with_advice() -> None:
    problem = only_problem("base: &b {k: 1}\nother:\n  <<: *b\n  c: 2\n")
    assert (problem.line, problem.field) == (3, "other.<<")
    assert problem.message.startswith("merge keys ('<<') are not supported")


# --- rule 4: aliases -------------------------------------------------------------------------


def billion_laughs(levels: int) -> str:
    lines = ['a0: &a0 "lol"']
    for level in range(1, levels + 1):
        refs = ", ".join([f"*a{level - 1}"] * 10)
        lines.append(f"a{level}: &a{level} [{refs}]")
    return "\n".join(lines) + "\n"


@pytest.mark.parametrize("levels", [9, 10])
def test_billion_laughs_is_refused_without_expanding(levels: int) -> None:
    problem = only_problem(billion_laughs(levels))  # returns at once: aliases are counted, never expanded
    assert problem.message.startswith(
        "document too large: more than 1,000,000 values once aliases are expanded"
    )
    assert problem.line == 7  # a6 is the first level that expands past the limit (1,111,111 values)


def test_small_alias_tree_loads_as_independent_copies_with_lines() -> None:
    loaded = loads_yaml(
        "steel: &steel {type: linear_elastic, stiffness: 2.0e7}\n"
        "springs:\n  a: {material: *steel}\n  b:\n    material: *steel\n"
    )
    a, b = loaded.data["springs"]["a"]["material"], loaded.data["springs"]["b"]["material"]
    assert a == b == {"type": "linear_elastic", "stiffness": 2.0e7}
    a["stiffness"] = 1.0
    assert b["stiffness"] == 2.0e7
    assert loaded.lines[("springs", "b", "material")] == 5
    assert loaded.lines[("springs", "b", "material", "stiffness")] == 1  # where the value is written


def test_too_many_aliases_are_refused() -> None:
    text = "a: &a 1\nb: [" + ", ".join(["*a"] * 1001) + "]\n"
    assert only_problem(text).message.startswith("more than 1000 aliases")


def test_recursive_alias_is_refused() -> None:
    problem = only_problem("a: 1\nb: &b\n  c: *b\n")
    assert problem.line == 3 and "recursive data is not allowed" in problem.message


def test_undefined_alias_and_redefined_anchor_are_errors() -> None:
    assert only_problem("a: 1\nb: *nope\n") == Problem(
        "m.yaml", 2, "", "alias *nope names no anchor &nope defined before it"
    )
    assert only_problem("a: &x 1\nb: &x 2\n").message == "anchor &x defined twice (first at line 1)"


# --- rule 5: limits --------------------------------------------------------------------------


def nested(levels: int) -> str:
    return "a: " + "[" * (levels - 1) + "1" + "]" * (levels - 1) + "\n"


def test_nesting_of_64_levels_loads_and_65_is_refused() -> None:
    assert loads_yaml(nested(64)).data["a"] is not None
    problem = only_problem(nested(65))
    assert problem.message == "nesting deeper than 64 levels" and problem.line == 1


def test_deep_block_nesting_is_refused_at_its_line() -> None:
    text = "".join("  " * i + f"k{i}:\n" for i in range(70))
    assert only_problem(text) == Problem("m.yaml", 65, "", "nesting deeper than 64 levels")


def test_nesting_through_aliases_is_refused() -> None:
    deep = "[" * 40 + "1" + "]" * 40
    text = f"a: &a {deep}\nb: [[[[[[[[[[[[[[[[[[[[[[[[[[[[*a]]]]]]]]]]]]]]]]]]]]]]]]]]]]\n"
    problem = only_problem(text)
    assert problem.message == "nesting deeper than 64 levels" and problem.line == 1


def test_document_over_20_mb_is_refused(tmp_path: Path) -> None:
    text = "a: " + "x" * MAX_BYTES + "\n"
    assert only_problem(text).message.startswith("document too large")
    big = tmp_path / "big.yaml"
    big.write_text(text)
    with pytest.raises(InputError) as info:
        load_yaml(big)
    assert info.value.problems[0].line is None
    assert info.value.problems[0].message.startswith("document too large")


def test_integer_of_more_than_30_digits_is_number_too_large() -> None:
    problem = only_problem("name: x\nmass: " + "1" * 31 + "\n")
    assert (problem.line, problem.field) == (2, "mass")
    assert problem.message.startswith("number too large: an integer of 31 digits (at most 30)")


def test_integer_beyond_python_str_conversion_limit_is_input_error() -> None:
    problem = only_problem("mass: -" + "7" * 5000 + "\n")
    assert problem.message.startswith("number too large")


def test_long_zero_padded_integer_is_fine() -> None:
    assert loads_yaml("n: " + "0" * 100 + "5\n").data["n"] == 5


# --- rules 6 and 7: syntax, top level, documents -----------------------------------------------


def test_syntax_error_gives_yaml_line_and_problem() -> None:
    problem = only_problem("name: x\nnodes:\n  a: 1\n b: 2\n")
    assert problem.line == 4 and problem.field == ""
    assert problem.message.startswith("invalid YAML: expected <block end>, but found '<block mapping start>'")
    assert "while parsing a block mapping at line 1" in problem.message
    assert "\n" not in problem.message


def test_unclosed_flow_sequence_is_syntax_error() -> None:
    problem = only_problem("a: [1, 2\nb: 3\n")
    assert problem.line == 2 and "expected ',' or ']'" in problem.message


def test_tab_indentation_is_syntax_error() -> None:
    problem = only_problem("a:\n\tb: 1\n")
    assert problem.line == 2 and problem.message.startswith("invalid YAML: found character '\\t'")


@pytest.mark.parametrize(
    ("text", "line", "found"),
    [
        ("", 1, "an empty document"),
        ("# only a comment\n", 1, "an empty document"),
        ("---\n", 1, "an empty document"),
        ("~\n", 1, "plain text"),
        ("- a\n- b\n", 1, "a list"),
        ("\n\njust text\n", 3, "plain text"),
    ],
)
def test_top_level_must_be_a_mapping(text: str, line: int, found: str) -> None:
    problem = only_problem(text)
    assert problem == Problem(
        "m.yaml",
        line,
        "",
        f"expected a mapping at top level (key: value lines), found {found}"
        " (is this a crashstudy model or study file?)",
    )


def test_explicit_document_markers_around_one_document_are_fine() -> None:
    assert loads_yaml("---\na: 1\n...\n").data == {"a": 1}


def test_multiple_documents_are_refused() -> None:
    problem = only_problem("a: 1\n---\nb: 2\n")
    assert problem.line == 2 and problem.message.startswith("expected a single YAML document")


def test_control_character_is_refused_with_its_line() -> None:
    problem = only_problem("a: 1\nb: x\x00y\n")
    assert problem.line == 2 and problem.message.startswith("unacceptable character #x0000")


# --- rule 8: reading files ---------------------------------------------------------------------


def test_load_yaml_reads_file_keeps_text_verbatim_and_path_as_given(tmp_path: Path) -> None:
    path = tmp_path / "model.yaml"
    path.write_bytes(b"name: x\r\nend_time: 1e-3\r\n")
    loaded = load_yaml(path)
    assert loaded.file == str(path) and loaded.text == "name: x\r\nend_time: 1e-3\r\n"
    assert loaded.data == {"name": "x", "end_time": 1e-3}
    assert loaded.lines[("end_time",)] == 2


def test_load_yaml_uses_given_text_without_opening_the_file() -> None:
    loaded = load_yaml("does/not/exist.yaml", text="a: 1\n")
    assert loaded.file == "does/not/exist.yaml" and loaded.data == {"a": 1}


def test_load_yaml_reports_errors_with_the_path(tmp_path: Path) -> None:
    path = tmp_path / "bad.yaml"
    path.write_text("a: 1\na: 2\n")
    with pytest.raises(InputError) as info:
        load_yaml(path)
    assert info.value.problems[0].format() == f"{path}:2: a: duplicate key 'a' (first at line 1)"


def test_missing_file_is_input_error_with_path(tmp_path: Path) -> None:
    path = tmp_path / "missing.yaml"
    with pytest.raises(InputError) as info:
        load_yaml(path)
    assert info.value.problems == [Problem(str(path), None, "", "file not found")]


def test_directory_is_input_error(tmp_path: Path) -> None:
    with pytest.raises(InputError) as info:
        load_yaml(tmp_path)
    assert info.value.problems == [Problem(str(tmp_path), None, "", "is a directory, expected a YAML file")]


@pytest.mark.parametrize(
    ("error", "reason"),
    [
        (PermissionError(13, "Permission denied"), "permission denied"),
        (OSError(5, "Input/output error"), "cannot read the file (Input/output error)"),
    ],
)
def test_unreadable_file_is_input_error(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, error: OSError, reason: str
) -> None:
    path = tmp_path / "secret.yaml"
    path.write_text("a: 1\n")

    def refuse(*args: object, **kwargs: object) -> None:
        raise error

    monkeypatch.setattr("builtins.open", refuse)  # works as root too, where chmod 0 would not
    with pytest.raises(InputError) as info:
        load_yaml(path)
    assert info.value.problems == [Problem(str(path), None, "", reason)]


def test_non_utf8_file_is_input_error(tmp_path: Path) -> None:
    path = tmp_path / "latin1.yaml"
    path.write_bytes("name: x\ndescription: Stoßdämpfer\n".encode("latin-1"))
    with pytest.raises(InputError) as info:
        load_yaml(path)
    (problem,) = info.value.problems
    assert (problem.file, problem.line) == (str(path), None)
    assert problem.message == "not UTF-8 text: byte 0xdf on line 2 cannot be decoded; save the file as UTF-8"


# --- rule 9: nothing but InputError ------------------------------------------------------------

YAMLISH = st.lists(
    st.sampled_from(
        [
            "a",
            "b",
            ":",
            " ",
            "  ",
            "\n",
            "- ",
            "[",
            "]",
            "{",
            "}",
            ",",
            "&x ",
            "*x",
            "!!",
            "!t ",
            "'",
            '"',
            "#",
            "1",
            "1e-3",
            "9" * 40,
            ".inf",
            "~",
            "?",
            "|",
            ">",
            "---",
            "...",
            "<<",
            "\t",
            "%YAML 1.2",
            "\\",
            "\x00",
            "\ufeff",
            "é",
        ]
    ),
    max_size=40,
).map("".join)


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.one_of(st.text(max_size=200), YAMLISH))
def test_any_text_gives_data_or_input_error(text: str) -> None:
    try:
        loaded = loads_yaml(text)
    except InputError as exc:
        assert exc.problems and all("\n" not in p.message for p in exc.problems)
    else:
        assert isinstance(loaded.data, dict) and loaded.lines[()] == 1


@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.binary(max_size=200))
def test_any_bytes_in_a_file_give_data_or_input_error(tmp_path: Path, raw: bytes) -> None:
    path = tmp_path / "random.yaml"
    path.write_bytes(raw)
    try:
        load_yaml(path)
    except InputError as exc:
        assert exc.problems and exc.problems[0].file == str(path)


def test_a_file_that_gives_no_data_without_waiting_is_an_input_error(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """/proc/kmsg is a 'regular' file whose non-blocking read has nothing to give (None): that was a
    TypeError traceback in yamlio._read (issue 24 item 10). Simulated with a FIFO that has a writer but no
    data, passed off as a regular file: an InputError naming the file, no traceback."""
    import os

    import crashstudy.schema.yamlio as yamlio

    fifo = tmp_path / "kmsg"
    os.mkfifo(fifo)
    writer = os.open(fifo, os.O_RDWR | os.O_NONBLOCK)  # a writer that never writes
    try:
        monkeypatch.setattr(yamlio, "not_regular", lambda mode: "")
        with pytest.raises(InputError) as exc:
            load_yaml(str(fifo))
    finally:
        os.close(writer)
    (p,) = exc.value.problems
    assert p.file == str(fifo) and "gives no data without waiting" in p.message
