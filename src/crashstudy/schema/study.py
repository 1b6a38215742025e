"""Pydantic model of a study file (SPEC section 5, plus the ``regression:`` block of issue 5)."""

from __future__ import annotations

from typing import Annotated, Any

from pydantic import Field

from crashstudy.schema.model import Finite, Id, NonNegative, Strict

AxisValues = Annotated[list[Finite], Field(min_length=1, max_length=1_000_000)]


class Tolerance(Strict):
    """Allowed change of one summary metric between a run and its baseline: ``|new - old| <= atol + rtol |old|``."""

    rtol: NonNegative = 0.0
    atol: NonNegative = 0.0


class Study(Strict):
    """A study: one model crossed over a matrix of axis values.

    ``matrix`` axes are crossed (full factorial); each ``zip`` group varies its axes together (equal
    lengths) and is crossed with the matrix; ``set`` overrides model fields for every variant.
    """

    name: Id
    description: str = ""
    model: Annotated[str, Field(min_length=1)]
    matrix: dict[str, AxisValues] = {}
    zip: list[Annotated[dict[str, AxisValues], Field(min_length=1)]] = []
    set: dict[str, Any] = {}
    regression: dict[str, Tolerance] = {}
