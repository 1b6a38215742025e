"""Pydantic model of a study file (documented for users in docs/format.md and docs/studies.md)."""

from __future__ import annotations

import re
from typing import Annotated, Any, Literal

from pydantic import Field, model_validator

from crashstudy.schema.model import Finite, Id, NonNegative, Strict

AxisValues = Annotated[list[Finite], Field(min_length=1, max_length=1_000_000)]


class Tolerance(Strict):
    """Allowed change of one summary metric between a run and its baseline: ``|new - old| <= atol + rtol |old|``."""

    rtol: NonNegative = Field(default=0.0, description="allowed relative change [1] >= 0")
    atol: NonNegative = Field(default=0.0, description="allowed absolute change [the metric's units] >= 0")


Pair = Annotated[list[Finite], Field(min_length=2, max_length=2)]


def why_invalid(name: str, p: list[float]) -> str | None:
    """What is wrong with the parameters of a distribution (None when they are valid)."""
    if name == "uniform" and not p[0] < p[1]:
        return f"uniform: [low, high] needs low < high, got {p}"
    if name in ("normal", "lognormal", "truncnormal") and not p[1] > 0:
        return f"{name}: the standard deviation (second number) must be > 0, got {p[1]}"
    if name == "truncnormal" and not p[2] < p[3]:
        return f"truncnormal: [mean, sd, low, high] needs low < high, got {p}"
    return None


class Distribution(Strict):
    """One axis of a sampled design: exactly one distribution with its parameters."""

    uniform: Pair | None = Field(default=None, description="[low, high] in the axis's units")
    normal: Pair | None = Field(default=None, description="[mean, standard deviation] in the axis's units")
    lognormal: Pair | None = Field(
        default=None, description="[mu, sigma]: exp of a normal with mean mu and standard deviation sigma [1]"
    )
    truncnormal: Annotated[list[Finite], Field(min_length=4, max_length=4)] | None = Field(
        default=None,
        description="[mean, standard deviation, low, high]: a normal cut to [low, high], axis units",
    )

    @model_validator(mode="after")
    def _one(self) -> Distribution:
        given = [(k, list(v)) for k, v in self.model_dump().items() if v is not None]
        if len(given) != 1:
            raise ValueError("give exactly one of uniform, normal, lognormal, truncnormal")
        why = why_invalid(*given[0])
        if why:
            raise ValueError(why)
        return self

    def spec(self) -> tuple[str, list[float]]:
        return next((k, list(v)) for k, v in self.model_dump().items() if v is not None)


class Design(Strict):
    """Sampled rows of axis values (docs/design.md), crossed with matrix and zip."""

    method: Literal["lhs", "sobol", "halton", "random", "saltelli", "morris"] = Field(
        default="lhs",
        description="sampling: lhs, sobol, halton, random; saltelli / morris for crashstudy sensitivity",
    )
    n: int = Field(
        ge=1, le=1_000_000, description="rows (saltelli: base points, n (2d+2) rows; morris: trajectories)"
    )
    seed: int = Field(
        default=0, ge=0, description="seed of the random numbers: the same seed gives the same rows"
    )
    axes: dict[str, Distribution] = Field(min_length=1, description="axis path -> its distribution")


Bounds = Annotated[list[Finite], Field(min_length=2, max_length=2)]
#: a constraint of ``optimize:``: COLUMN (<= | >=) NUMBER; groups column, operator, number
CONSTRAINT = re.compile(r"^\s*(\S+)\s*(<=|>=)\s*(\S+)\s*$")
Constraint = Annotated[str, Field(pattern=CONSTRAINT.pattern)]


class Optimize(Strict):
    """``crashstudy optimize``: minimise a summary column over bounded variables (docs/optimize.md)."""

    minimize: str = Field(
        min_length=1, description="summary column to minimise, e.g. peak_deceleration_g.cabin"
    )
    constraints: list[Constraint] = Field(
        default=[], description="'COLUMN <= NUMBER' or 'COLUMN >= NUMBER' on summary columns [their units]"
    )
    variables: dict[str, Bounds] = Field(min_length=1, description="axis path -> [low, high] in its units")
    budget: int = Field(default=2000, ge=10, le=10_000_000, description="model evaluations at most [1]")
    seed: int = Field(default=0, ge=0, description="seed of the optimiser's random numbers [1]")


class Channel(Strict):
    """The measured quantity: a node's motion along an axis, or a spring's force or elongation."""

    quantity: Literal["acceleration", "velocity", "displacement", "spring_force", "spring_elongation"] = (
        Field(description="history to fit (node quantities need node and direction, spring ones need spring)")
    )
    node: str | None = Field(default=None, description="node id (acceleration, velocity, displacement)")
    spring: str | None = Field(default=None, description="spring id (spring_force, spring_elongation)")
    direction: Literal["x", "y"] = Field(default="x", description="axis of a node quantity")


class TestData(Strict):
    """A test curve: a CSV (time, value) or one channel of an ISO-MME test (docs/format.md, calibrate)."""

    path: str = Field(
        min_length=1,
        description="CSV file, or ISO-MME test (.mme, its folder or a .zip), relative to the study",
    )
    channel: str | None = Field(
        default=None,
        description="ISO-MME channel code, 16 characters, '?' matches any one; "
        "exactly one channel must match",
    )
    unit: str | None = Field(
        default=None,
        description="unit of the values (g, m/(s*s), m/s, km/h, mm, m, N, kN, ...), "
        "overriding the file's; converted into the model's units",
    )


class Calibrate(Strict):
    """``crashstudy calibrate``: fit variables to a measured channel by least squares, or by the ISO/TS 18571
    rating (docs/optimize.md, docs/correlation.md)."""

    data: Annotated[str, Field(min_length=1)] | TestData = Field(
        description="the test curve: a CSV path (time, value in model units), or {path, channel, unit}; relative to the study"
    )
    channel: Channel = Field(description="what the data measured")
    variables: dict[str, Bounds] = Field(min_length=1, description="axis path -> [low, high] in its units")
    objective: Literal["rms", "iso18571"] = Field(
        default="rms",
        description="rms: least squares of the residuals; iso18571: maximise the ISO/TS 18571 rating R",
    )
    budget: int = Field(
        default=600, ge=10, le=1_000_000, description="model evaluations at most (iso18571) [1]"
    )


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
    matrix: dict[str, AxisValues] = Field(
        default={},
        description="axis path -> values [units of that model field]; all axes crossed (full factorial)",
    )
    zip: list[Annotated[dict[str, AxisValues], Field(min_length=1)]] = Field(
        default=[],
        description="groups of axis path -> values [model units] that vary together; each group crossed with the matrix",
    )
    design: Design | None = Field(
        default=None, description="sampled rows of axis values, crossed with matrix and zip"
    )
    optimize: Optimize | None = Field(
        default=None, description="what crashstudy optimize minimises, under which constraints"
    )
    calibrate: Calibrate | None = Field(
        default=None, description="what crashstudy calibrate fits to which data"
    )
    set: dict[str, Any] = Field(
        default={}, description="model field or dotted path -> value, applied to every variant"
    )
    regression: dict[str, Tolerance] = Field(
        default={}, description="summary column (or metric name) -> tolerance used by crashstudy compare"
    )
