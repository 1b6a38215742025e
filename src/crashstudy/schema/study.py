"""Pydantic model of a study file (documented for users in docs/format.md and docs/studies.md)."""

from __future__ import annotations

from typing import Annotated, Any

from pydantic import Field

from crashstudy.schema.model import Finite, Id, NonNegative, Strict

AxisValues = Annotated[list[Finite], Field(min_length=1, max_length=1_000_000)]


class Tolerance(Strict):
    """Allowed change of one summary metric between a run and its baseline: ``|new - old| <= atol + rtol |old|``."""

    rtol: NonNegative = Field(default=0.0, description="allowed relative change [1] >= 0")
    atol: NonNegative = Field(default=0.0, description="allowed absolute change [the metric's units] >= 0")


class Study(Strict):
    """A study: one model crossed over a matrix of axis values.

    ``matrix`` axes are crossed (full factorial); each ``zip`` group varies its axes together (equal
    lengths) and is crossed with the matrix; ``set`` overrides model fields for every variant.
    """

    name: Id = Field(description="study name: letters, digits, '-', '_' (names the result folder)")
    description: str = Field(default="", description="free text, stored with the results")
    model: Annotated[str, Field(min_length=1)] = Field(
        description="path of the model file, relative to this study file (or absolute)"
    )
    matrix: dict[str, AxisValues] = Field(default=        {}, description="axis path -> values [units of that model field]; all axes crossed (full factorial)"
    )
    zip: list[Annotated[dict[str, AxisValues], Field(min_length=1)]] = Field(default=        [], description="groups of axis path -> values [model units] that vary together; each group crossed with the matrix"
    )
    set: dict[str, Any] = Field(default={}, description="model field or dotted path -> value, applied to every variant")
    regression: dict[str, Tolerance] = Field(default=        {}, description="summary column (or metric name) -> tolerance used by crashstudy compare"
    )
