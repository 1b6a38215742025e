"""Tests of crashstudy.schema.yamlio's refusal of bad input: rules 2-7, duplicate keys, tags, aliases,
limits, syntax, the top level and documents."""

from __future__ import annotations

from pathlib import Path

import pytest

from crashstudy.errors import InputError, Problem
from crashstudy.schema.yamlio import MAX_BYTES, load_yaml, loads_yaml
from yamlio_checks import only_problem, problems_of

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
