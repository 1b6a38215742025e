"""Tests of crashstudy.schema.yamlio: rule 8, reading files (the text kept verbatim, errors with the
path), and rule 9, any text or bytes give data or an InputError, nothing else."""

from __future__ import annotations

from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from crashstudy.errors import InputError, Problem
from crashstudy.schema.yamlio import load_yaml, loads_yaml

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
