"""Pydantic models of a model file (documented for users in docs/format.md).

These classes check the *shape* of each entry (types, signs, lengths). Relations between entries
(a spring naming a node that exists, 1-D vs 2-D consistency, curves through the origin) are checked
in :mod:`crashstudy.schema.checks`, which can point at the exact line of each offending field.
Pydantic objects stop at the compile step: the kernel never sees them.
"""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationInfo, field_validator, model_validator

from crashstudy.units import UnitSystemName
from crashstudy.vocabulary.codes import HISTORY_ORDER
from crashstudy.vocabulary.materials import MATERIALS

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

    x: Annotated[list[Finite], Field(min_length=2, max_length=10_000)] = Field(
        description="abscissae, strictly increasing: elongation [length] (material curve) or time [time] (load, motion)"
    )
    y: Annotated[list[Finite], Field(min_length=2, max_length=10_000)] = Field(
        description="values at x, same count: force [force], load factor [1] or displacement/velocity/acceleration"
    )

    @model_validator(mode="after")
    def _increasing(self) -> Curve:
        if len(self.x) != len(self.y):
            raise ValueError(
                f"x and y must have the same number of points (x has {len(self.x)}, y has {len(self.y)})"
            )
        for a, b in zip(self.x, self.x[1:], strict=False):
            if not b > a:
                raise ValueError(f"x must be strictly increasing (found {a} followed by {b})")
        return self


class Node(Strict):
    """A nodal mass. ``position`` [length] is ``[x]`` (1-D) or ``[x, y]``; ``mass`` [mass]."""

    position: Vector = Field(description="initial position [length]: [x] in a 1-D model, [x, y] in a 2-D one")
    mass: Positive | None = Field(
        default=None, description="nodal mass [mass] > 0; required unless fixed in every direction"
    )
    fixed: bool | Annotated[list[Axis], Field(min_length=1, max_length=2)] = Field(
        default=False, description="true (all directions), false, or the fixed directions, e.g. [y]"
    )


class LinearElastic(Strict):
    """``F = k e``; ``stiffness`` k [force/length] > 0."""

    type: Literal["linear_elastic"] = Field(description="material law: F = k e")
    stiffness: Positive = Field(description="spring rate k [force/length] > 0")


class NonlinearElastic(Strict):
    """``F = C(e)``; loads and unloads along the same curve."""

    type: Literal["nonlinear_elastic"] = Field(
        description="material law: F = C(e), same path loading and unloading"
    )
    curve: Id = Field(description="id of the curve C: force [force] vs elongation [length]")


class GeneralNonlinear(Strict):
    """LS-DYNA S06-style spring: loading/unloading curves, yield forces [force] (absent = never)."""

    type: Literal["general_nonlinear"] = Field(
        description="material law: LS-DYNA S06 loading/unloading curves with yield"
    )
    loading: Id = Field(
        description="id of the loading curve, force [force] vs elongation [length], through the origin"
    )
    unloading: Id = Field(
        description="id of the unloading curve, force vs elongation, through the origin, increasing"
    )
    tension_yield: Positive | None = Field(
        default=None, description="yield force in tension [force] > 0; absent: never yields"
    )
    compression_yield: Annotated[float, Field(lt=0, allow_inf_nan=False)] | None = Field(
        default=None, description="yield force in compression [force] < 0; absent: never yields"
    )


class Crush(Strict):
    """Crushable structure that cannot pull; ``unloading_stiffness`` [force/length] > 0."""

    type: Literal["crush"] = Field(
        description="material law: crushable structure, compression only, no tension"
    )
    loading: Id = Field(
        description="id of the crush curve, force [force] vs elongation [length]; its x < 0 part is used"
    )
    unloading_stiffness: Positive = Field(
        description="slope of elastic spring-back after crushing [force/length] > 0"
    )


class Damper(Strict):
    """Viscous damper ``F = c de/dt``; ``damping`` c [force*time/length] >= 0."""

    type: Literal["damper"] = Field(description="material law: viscous damper F = c de/dt")
    damping: NonNegative = Field(description="damping coefficient c [force*time/length] >= 0")


class Elastoplastic(Strict):
    """Bilinear elastoplastic spring with isotropic hardening (LS-DYNA S03).

    ``F = K (e - e_p)`` with ``|F| <= FY + H p``, ``H = K KT / (K - KT)`` and ``p`` the accumulated
    plastic elongation (the sum of ``|de_p|``).
    """

    type: Literal["elastoplastic"] = Field(
        description="material law: bilinear elastoplastic, isotropic hardening (LS-DYNA S03)"
    )
    stiffness: Positive = Field(description="elastic stiffness K [force/length] > 0")
    tangent_stiffness: NonNegative = Field(description="slope after yield KT [force/length], 0 <= KT < K")
    yield_force: Positive = Field(
        description="initial yield force FY [force] > 0, the same in tension and compression"
    )

    @field_validator("tangent_stiffness")
    @classmethod
    def _tangent_below_stiffness(cls, kt: float, info: ValidationInfo) -> float:
        k = info.data.get("stiffness")
        if k is not None and not kt < k:
            raise ValueError(f"tangent_stiffness must be below stiffness ({k:g}), got {kt:g}")
        return kt


class NonlinearDamper(Strict):
    """Damper ``F = C(de/dt)`` (LS-DYNA S05): force [force] vs elongation rate [length/time]."""

    type: Literal["nonlinear_damper"] = Field(
        description="material law: F = C(de/dt), force vs elongation rate"
    )
    curve: Id = Field(
        description="id of the curve C: force [force] vs elongation rate [length/time], through the origin, non-decreasing"
    )


class RateCurve(Strict):
    """One curve of a ``rate_elastic`` spring and the elongation rate magnitude it holds at."""

    rate: NonNegative = Field(
        description="elongation rate magnitude |de/dt| [length/time] >= 0 of this curve"
    )
    curve: Id = Field(description="id of the curve: force [force] vs elongation [length], through the origin")


class RateElastic(Strict):
    """``F = C(e, |de/dt|)``: elastic curves at increasing rates, linear in the rate between them
    (LS-DYNA S04 with a ``*DEFINE_TABLE``); loads and unloads along them."""

    type: Literal["rate_elastic"] = Field(
        description="material law: F = C(e, |de/dt|), force curves at increasing rates"
    )
    curves: Annotated[list[RateCurve], Field(min_length=1, max_length=16)] = Field(
        description="the curves and their rates, rates strictly increasing; the first one below the first rate, "
        "the last one above the last rate, linear in the rate between"
    )

    @field_validator("curves")
    @classmethod
    def _rates_increasing(cls, curves: list[RateCurve]) -> list[RateCurve]:
        for a, b in zip(curves, curves[1:], strict=False):
            if not b.rate > a.rate:
                raise ValueError(
                    f"rates must be strictly increasing (found {a.rate:g} followed by {b.rate:g})"
                )
        return curves


Material = Annotated[
    LinearElastic
    | NonlinearElastic
    | GeneralNonlinear
    | Crush
    | Damper
    | Elastoplastic
    | NonlinearDamper
    | RateElastic,
    Field(discriminator="type"),
]
# the union above lists the classes of the material table (tests/test_material_table.py holds them equal)
MATERIAL_TYPES = tuple(m.name for m in MATERIALS)
DAMPER_TYPES = tuple(
    m.name for m in MATERIALS if m.by_rate
)  # materials whose force follows the elongation rate


class Failure(Strict):
    """Elongations [length] at which a spring breaks (force 0 for the rest of the run); each optional."""

    tension: Positive | None = Field(
        default=None, description="elongation e_t [length] > 0 beyond which the spring breaks in tension"
    )
    compression: Annotated[float, Field(lt=0, allow_inf_nan=False)] | None = Field(
        default=None, description="elongation e_c [length] < 0 beyond which the spring breaks in compression"
    )


class Spring(Strict):
    """Massless discrete element between two nodes."""

    nodes: Annotated[list[Id], Field(min_length=2, max_length=2)] = Field(
        description="ids of the two different nodes it joins; elongation e > 0 when they move apart"
    )
    material: Material = Field(description="force law, chosen by 'type'")
    initial_elongation: Finite = Field(
        default=0.0,
        description="elongation e0 [length] at t = 0 (preload or a free length that differs from the drawn one); "
        "not for dampers",
    )
    failure: Failure | None = Field(
        default=None, description="elongations at which the spring breaks; absent: never"
    )


class Load(Strict):
    """Concentrated force [force] on a node, constant or scaled by a time curve (zero outside it)."""

    node: Id = Field(description="id of the loaded node")
    force: Vector = Field(description="force vector [force], one component per dimension")
    curve: Id | None = Field(
        default=None, description="id of a time curve scaling the force (zero outside it); absent: constant"
    )


class PrescribedMotion(Strict):
    """A node's displacement [length], velocity [length/time] or acceleration along x or y."""

    node: Id = Field(description="id of the driven node (must not be fixed in this direction)")
    quantity: Literal["displacement", "velocity", "acceleration"] = Field(
        description="what the curve gives: displacement [length], velocity [length/time], acceleration [length/time^2]"
    )
    direction: Axis = Field(description="driven direction: x or y (only x in a 1-D model)")
    curve: Id = Field(description="id of the time curve (x: time [time]; zero outside its range)")
    scale: Finite = Field(default=1.0, description="factor on the curve's values [1]")


class RigidWall(Strict):
    """A stonewall: plane through ``point`` [length] with outward ``normal``; ``nodes`` default all."""

    id: Id = Field(description="wall id (names the wall in results)")
    point: Vector = Field(description="a point of the wall plane [length]")
    normal: Vector = Field(
        description="direction the wall faces (nodes stay on this side) [1], any length but not zero"
    )
    nodes: list[Id] | None = Field(
        default=None, description="ids of the nodes the wall stops; absent: every node"
    )
    stiffness: Positive | None = Field(
        default=None,
        description="contact stiffness [force/length] > 0: a penalty "
        "wall (force = stiffness x penetration); absent: a rigid wall",
    )


class TimeStep(Strict):
    """Exactly one of ``safety_factor`` (0 < s <= 1), ``dt`` [time] or ``tolerance`` (relative)."""

    safety_factor: Annotated[float, Field(gt=0, le=1, allow_inf_nan=False)] | None = Field(
        default=None, description="dt = safety_factor * dt_crit, 0 < s <= 1 [1]"
    )
    dt: Positive | None = Field(default=None, description="fixed time step [time]; must not exceed dt_crit")
    tolerance: Annotated[float, Field(gt=0, lt=1, allow_inf_nan=False)] | None = Field(
        default=None,
        description="target relative error of the peaks, 0 < tol < 1 [1]; dt is chosen to meet it",
    )

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


ISO_MME_PREFIX = r"^[0-9A-Z]{12}$"  #: an ISO/TS 13499 code's test object, position and locations
HISTORY_NAMES = (
    *HISTORY_ORDER,
    "filtered_acceleration",
)  # the last: computed from the per-step record (metrics)


class Output(Strict):
    """History sampling: ``interval`` [time] (default end_time/1000) and which histories to keep."""

    interval: Positive | None = Field(
        default=None, description="history sampling interval [time]; absent: end_time / 1000"
    )
    histories: Literal["all", "none"] | Annotated[list[str], Field(min_length=1)] = Field(
        default="all", description="histories to keep: all, none (summaries only) or a list of history names"
    )

    @field_validator("histories")
    @classmethod
    def _known(cls, v: object) -> object:
        if isinstance(v, list):
            bad = [h for h in v if h not in HISTORY_NAMES]
            if bad:
                raise ValueError(
                    f"unknown history {bad[0]!r}; expected 'all', 'none' or names from {list(HISTORY_NAMES)}"
                )
        return v


CRITERION_NAMES = ("peak_g", "hic15", "hic36", "clip3ms", "clip3ms_cumulative", "olc", "dri", "delta_v")
Criterion = Literal["peak_g", "hic15", "hic36", "clip3ms", "clip3ms_cumulative", "olc", "dri", "delta_v"]
CFC = Literal[60, 180, 600, 1000]


class Metric(Strict):
    """Crash criteria of one node, from its acceleration at every time step (docs/format.md, metrics)."""

    node: Id = Field(
        description="id of the node whose acceleration is judged (e.g. an occupant or the cabin)"
    )
    direction: Axis | Vector | None = Field(
        default=None,
        description=(
            "direction of travel: x, y or a vector [1] (deceleration positive against it); absent: the node's "
            "initial velocity direction (x when it has none)"
        ),
    )
    cfc: CFC = Field(
        default=180, description="SAE J211-1 channel frequency class of the filter: 60, 180, 600 or 1000"
    )
    criteria: Annotated[list[Criterion], Field(min_length=1)] = Field(
        description="criteria to compute: peak_g, hic15, hic36, clip3ms, clip3ms_cumulative, olc, dri, delta_v"
    )


class Termination(Strict):
    """Optional early end of a run once the crash is over.

    With ``f = kinetic_energy_fraction`` a variant stops once the sum of the spring force magnitudes
    is below ``f`` times the sum of their peaks *and* either the kinetic energy is below
    ``f (KE0 + IE0 + max |W_ext|)`` or, with no loads, gravity or prescribed motion, every spring is
    opening. ``min_time`` [time]: never stop before it.
    """

    kinetic_energy_fraction: Annotated[float, Field(gt=0, lt=1, allow_inf_nan=False)] = Field(
        default=1.0e-3,
        description="stop threshold f, 0 < f < 1 [1]: spring forces and kinetic energy below f of their peaks",
    )
    min_time: NonNegative = Field(default=0.0, description="never stop before this time [time]")


class Model(Strict):
    """A crashstudy model file: nodes, springs, curves, loads and run settings (docs/format.md)."""

    name: Id = Field(
        description="model name: letters, digits, '-', '_' (names the result folder of simulate)"
    )
    description: str = Field(default="", description="free text, stored with the results")
    units: UnitSystemName = Field(
        default="SI", description="unit system of every number: SI, mm-ms-kg-kN or mm-s-t-N"
    )
    curves: dict[Id, Curve] = Field(default={}, description="id -> tabulated curve (material or time curve)")
    nodes: Annotated[dict[Id, Node], Field(min_length=1)] = Field(
        description="id -> nodal mass (at least one)"
    )
    springs: dict[Id, Spring] = Field(
        default={}, description="id -> massless spring or damper between two nodes"
    )
    initial_velocity: dict[Id, Vector] = Field(
        default={}, description="node id -> initial velocity [length/time]"
    )
    gravity: Vector | None = Field(
        default=None, description="body acceleration on every mass [length/time^2]; absent: none"
    )
    loads: list[Load] = Field(default=[], description="concentrated forces on nodes")
    prescribed_motion: list[PrescribedMotion] = Field(
        default=[], description="nodes driven along x or y by a time curve"
    )
    rigid_walls: list[RigidWall] = Field(default=[], description="stonewalls that nodes cannot cross")
    end_time: Positive = Field(description="simulated duration [time] > 0, from t = 0")
    time_step: TimeStep = Field(
        default=TimeStep(tolerance=1.0e-3),
        description="one of safety_factor, dt or tolerance; default tolerance 1e-3",
    )
    output: Output = Field(
        default=Output(), description="history sampling interval and which histories to keep"
    )
    termination: Termination | None = Field(
        default=None, description="optional early end once the crash is over"
    )
    metrics: list[Metric] = Field(
        default=[], description="crash criteria of nodes (HIC, 3 ms clip, OLC, ...)"
    )
    iso_mme: dict[Id, Annotated[str, Field(pattern=ISO_MME_PREFIX)]] = Field(
        default={},
        description=(
            "node or spring id -> the first 12 characters of its ISO-MME channel codes (export --isomme), e.g. "
            "10VEHCCG0000; absent: 10NODEnnnn00 / 10SPRGnnnn00 by position (docs/isomme.md)"
        ),
    )
    accuracy_check: bool = Field(
        default=False, description="re-run each variant at dt/2 and report a Richardson error estimate [1]"
    )
