"""Pydantic models of a model file (SPEC sections 2, 3, 3b, 4, 6).

These classes check the *shape* of each entry (types, signs, lengths). Relations between entries
(a spring naming a node that exists, 1-D vs 2-D consistency, curves through the origin) are checked
in :mod:`crashstudy.schema.checks`, which can point at the exact line of each offending field.
Pydantic objects stop at the compile step: the kernel never sees them.
"""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from crashstudy.units import UnitSystemName

Id = Annotated[str, Field(pattern=r"^[A-Za-z0-9_-]+$", min_length=1, max_length=64)]
Finite = Annotated[float, Field(allow_inf_nan=False)]
Positive = Annotated[float, Field(gt=0, allow_inf_nan=False)]
NonNegative = Annotated[float, Field(ge=0, allow_inf_nan=False)]
Vector = Annotated[list[Finite], Field(min_length=1, max_length=2)]
Axis = Literal["x", "y"]


class Strict(BaseModel):
    """Base: unknown keys are errors; numbers must be numbers (no numeric strings); no NaN/inf."""

    model_config = ConfigDict(extra="forbid", strict=True, allow_inf_nan=False, frozen=True)


class Curve(Strict):
    """Tabulated curve ``y(x)``: ``x`` strictly increasing, at least two points.

    Units: a material curve maps elongation [length] to force [force]; a load or prescribed-motion
    curve maps time [time] to a dimensionless factor (load) or displacement/velocity/acceleration.
    """

    x: Annotated[list[Finite], Field(min_length=2, max_length=10_000)]
    y: Annotated[list[Finite], Field(min_length=2, max_length=10_000)]

    @model_validator(mode="after")
    def _increasing(self) -> Curve:
        if len(self.x) != len(self.y):
            raise ValueError(f"x and y must have the same number of points (x has {len(self.x)}, y has {len(self.y)})")
        for a, b in zip(self.x, self.x[1:]):
            if not b > a:
                raise ValueError(f"x must be strictly increasing (found {a} followed by {b})")
        return self


class Node(Strict):
    """A nodal mass. ``position`` [length] is ``[x]`` (1-D) or ``[x, y]``; ``mass`` [mass]."""

    position: Vector
    mass: Positive | None = None
    fixed: bool | Annotated[list[Axis], Field(min_length=1, max_length=2)] = False


class LinearElastic(Strict):
    """``F = k e``; ``stiffness`` k [force/length] > 0."""

    type: Literal["linear_elastic"]
    stiffness: Positive


class NonlinearElastic(Strict):
    """``F = C(e)``; loads and unloads along the same curve."""

    type: Literal["nonlinear_elastic"]
    curve: Id


class GeneralNonlinear(Strict):
    """LS-DYNA S06-style spring: loading/unloading curves, yield forces [force] (absent = never)."""

    type: Literal["general_nonlinear"]
    loading: Id
    unloading: Id
    tension_yield: Positive | None = None
    compression_yield: Annotated[float, Field(lt=0, allow_inf_nan=False)] | None = None


class Crush(Strict):
    """Crushable structure that cannot pull; ``unloading_stiffness`` [force/length] > 0."""

    type: Literal["crush"]
    loading: Id
    unloading_stiffness: Positive


class Damper(Strict):
    """Viscous damper ``F = c de/dt``; ``damping`` c [force*time/length] >= 0."""

    type: Literal["damper"]
    damping: NonNegative


Material = Annotated[
    LinearElastic | NonlinearElastic | GeneralNonlinear | Crush | Damper,
    Field(discriminator="type"),
]
MATERIAL_TYPES = ("linear_elastic", "nonlinear_elastic", "general_nonlinear", "crush", "damper")


class Spring(Strict):
    """Massless discrete element between two nodes."""

    nodes: Annotated[list[Id], Field(min_length=2, max_length=2)]
    material: Material


class Load(Strict):
    """Concentrated force [force] on a node, constant or scaled by a time curve (zero outside it)."""

    node: Id
    force: Vector
    curve: Id | None = None


class PrescribedMotion(Strict):
    """A node's displacement [length], velocity [length/time] or acceleration along x or y."""

    node: Id
    quantity: Literal["displacement", "velocity", "acceleration"]
    direction: Axis
    curve: Id
    scale: Finite = 1.0


class RigidWall(Strict):
    """A stonewall: plane through ``point`` [length] with outward ``normal``; ``nodes`` default all."""

    id: Id
    point: Vector
    normal: Vector
    nodes: list[Id] | None = None


class TimeStep(Strict):
    """Exactly one of ``safety_factor`` (0 < s <= 1), ``dt`` [time] or ``tolerance`` (relative)."""

    safety_factor: Annotated[float, Field(gt=0, le=1, allow_inf_nan=False)] | None = None
    dt: Positive | None = None
    tolerance: Annotated[float, Field(gt=0, lt=1, allow_inf_nan=False)] | None = None

    @model_validator(mode="after")
    def _exactly_one(self) -> TimeStep:
        given = [k for k in ("safety_factor", "dt", "tolerance") if getattr(self, k) is not None]
        if len(given) != 1:
            raise ValueError(
                "give exactly one of safety_factor, dt or tolerance"
                + (f" (got {', '.join(given)})" if given else "")
            )
        return self

    @property
    def mode(self) -> str:
        return next(k for k in ("safety_factor", "dt", "tolerance") if getattr(self, k) is not None)


HISTORY_NAMES = (
    "position", "displacement", "velocity", "acceleration",
    "spring_force", "spring_elongation",
    "kinetic_energy", "internal_energy", "external_work", "wall_energy", "wall_force",
)  # fmt: skip


class Output(Strict):
    """History sampling: ``interval`` [time] (default end_time/1000) and which histories to keep."""

    interval: Positive | None = None
    histories: Literal["all", "none"] | Annotated[list[str], Field(min_length=1)] = "all"

    @field_validator("histories")
    @classmethod
    def _known(cls, v: object) -> object:
        if isinstance(v, list):
            bad = [h for h in v if h not in HISTORY_NAMES]
            if bad:
                raise ValueError(f"unknown history {bad[0]!r}; expected 'all', 'none' or names from {list(HISTORY_NAMES)}")
        return v


class Termination(Strict):
    """Optional early end of a run once the crash is over (an extension of SPEC section 2).

    ``kinetic_energy_fraction``: stop when the kinetic energy falls below this fraction of the
    initial kinetic energy *and* every spring is unloading or separated (the force magnitude is
    not increasing). ``min_time`` [time]: never stop before it.
    """

    kinetic_energy_fraction: Annotated[float, Field(gt=0, lt=1, allow_inf_nan=False)] = 1.0e-3
    min_time: NonNegative = 0.0


class Model(Strict):
    """A whole model file. See SPEC section 2 for the meaning of every key."""

    name: Id
    description: str = ""
    units: UnitSystemName = "SI"
    curves: dict[Id, Curve] = {}
    nodes: Annotated[dict[Id, Node], Field(min_length=1)]
    springs: dict[Id, Spring] = {}
    initial_velocity: dict[Id, Vector] = {}
    gravity: Vector | None = None
    loads: list[Load] = []
    prescribed_motion: list[PrescribedMotion] = []
    rigid_walls: list[RigidWall] = []
    end_time: Positive
    time_step: TimeStep = TimeStep(tolerance=1.0e-3)
    output: Output = Output()
    termination: Termination | None = None
    accuracy_check: bool = False  # re-run at half the step; report a Richardson error estimate per variant
