"""What the tests of crashstudy.schema.yamlio (tests/test_yamlio_*.py) share: the problems of a
refused text."""

from __future__ import annotations

import pytest

from crashstudy.errors import InputError, Problem
from crashstudy.schema.yamlio import loads_yaml


def problems_of(text: str) -> list[Problem]:
    with pytest.raises(InputError) as info:
        loads_yaml(text, "m.yaml")
    return info.value.problems


def only_problem(text: str) -> Problem:
    problems = problems_of(text)
    assert len(problems) == 1, problems
    return problems[0]
