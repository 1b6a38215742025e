"""The material table: one :class:`MaterialSpec` row per spring material (the pipeline's vocabulary).

Every Python-side dispatch on a material (the compiler's parameter slots and curves, the parameter and
curve checks, the stable-step bound, knot peaks, the preload path, the generated kernel's state rows)
reads its row here instead of spelling out material codes. The two compiled dispatches (the generic
kernel's force branch in ``kernel/compiled.py`` and the generator's emitted call in
``kernel/gen_springs.py``) stay hand-written branches; ``tests/test_material_table.py`` walks this table
and requires, for each row, a schema class, its laws in ``kernel/laws.py``, a NumPy twin, a branch in
both compiled dispatches and a twin case in ``tests/test_kernel_twins.py``.

This module imports nothing of crashstudy: schema/, arrays/ and kernel/ all read it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from crashstudy.vocabulary import codes

#: what the parameter checks require of a slot (each with its wording in the check's message)
SlotRule = Literal["> 0", ">= 0", "< 0", "below k"]
#: what the curve checks require of a curve role, besides passing through the origin
CurveRule = Literal["signed", "increasing", "non_decreasing", "compression_part"]
#: how a monotonic path from 0 to initial_elongation can bend (arrays.preload)
KinkRule = Literal["none", "curve_knots", "crush_knots", "elastic_limit"]
#: what bounds the stable step: its k (force/length) and/or its damping (force*time/length); rate_curves:
#: the steepest slope of its curves as k and the steepest force change per unit rate between them as c
StepRule = Literal[
    "stiffness",
    "damping",
    "curve_slope",
    "curve_damping",
    "curve_slopes",
    "curve_slope_or_stiffness",
    "rate_curves",
]
#: which window of the loading path can pass a knot peak (kernel.laws ``*_window``); None: no knot peaks
KnotRule = Literal["nonlinear", "crush", "general"] | None


@dataclass(frozen=True)
class Slot:
    """One per-spring parameter: the compiler's parameter block, the schema field that fills it, the value
    when an optional field is absent (None: required) and what the parameter checks require of it."""

    block: str
    field: str
    absent: float | None = None
    rule: SlotRule | None = None
    expect: str = ""  # the check's wording ("a value > 0", ...)


@dataclass(frozen=True)
class CurveRole:
    """One curve of a material: the schema field naming it and what its points must obey."""

    field: str
    rule: CurveRule | None = None


@dataclass(frozen=True)
class MaterialSpec:
    """Everything the Python side of crashstudy knows about one material (see the module docstring)."""

    name: str  # the model file's ``type``
    code: int  # the kernels' material code (vocabulary.codes)
    schema_class: str  # class in crashstudy.schema.model
    slots: tuple[Slot, ...]  # per-spring parameters, in the compiler's order
    curves: tuple[CurveRole, ...]  # curve roles: curve_a (loading / curve), curve_b (unloading)
    state_rows: int  # rows of the (S, NSTATE, V) material state it uses
    knots: KnotRule  # knot peaks of curve_a along the loading path
    by_rate: bool  # a damper: its force follows the elongation rate only (no initial_elongation)
    kinks: KinkRule  # where a monotonic preload path bends
    step: StepRule  # what bounds the stable step
    laws: tuple[str, ...]  # kernel.laws functions of its force (the generic and generated kernels call these)
    call: str  # the call the generator emits (gen_springs.pass_b_springs / pass_a), for the reader
    twin: str  # its independent NumPy twin (the reference kernel)
    reads_rate: bool = False  # its force reads the elongation rate (dampers, rate_elastic)
    # which drawn ends of its elongation curve(s) a run checks (results.curve_ends): (first, last)
    curve_ends: tuple[bool, bool] = (False, False)
    rate_curves: str | None = None  # schema field of a list of {rate, curve} (rate_elastic: Batch.rate_curve)


_K_POS = "a value > 0"
MATERIALS: tuple[MaterialSpec, ...] = (
    MaterialSpec(
        name="linear_elastic",
        code=codes.LINEAR,
        schema_class="LinearElastic",
        slots=(Slot("k", "stiffness", rule="> 0", expect=_K_POS),),
        curves=(),
        state_rows=0,
        knots=None,
        by_rate=False,
        kinks="none",
        step="stiffness",
        laws=("linear_force",),
        call="F{s} = linear_force(k, e{s})",
        twin="reference._force (k e)",
    ),
    MaterialSpec(
        name="nonlinear_elastic",
        code=codes.NONLINEAR,
        schema_class="NonlinearElastic",
        slots=(),
        curves=(CurveRole("curve", "signed"),),
        state_rows=0,
        knots="nonlinear",
        by_rate=False,
        kinks="curve_knots",
        step="curve_slope",
        laws=("nonlinear_force", "nonlinear_window"),
        call="F{s} = nonlinear_force(C(e{s}))",
        twin="material_laws.curve_eval",
        curve_ends=(True, True),
    ),
    MaterialSpec(
        name="general_nonlinear",
        code=codes.GENERAL,
        schema_class="GeneralNonlinear",
        slots=(
            Slot("ty", "tension_yield", float("inf"), "> 0", "a tension_yield > 0"),
            Slot("cy", "compression_yield", float("-inf"), "< 0", "a compression_yield < 0"),
        ),
        curves=(CurveRole("loading", "signed"), CurveRole("unloading", "increasing")),
        state_rows=8,
        knots="general",
        by_rate=False,
        kinks="curve_knots",
        step="curve_slopes",
        laws=("general_law", "general_reverse", "general_window"),
        call="F{s}, mode, ... = general_law(e{s}, mode, ..., L(e), U(e - e_t*), U(e - e_c*), yt, yc)",
        twin="material_laws.general_nonlinear",
        curve_ends=(True, True),
    ),
    MaterialSpec(
        name="crush",
        code=codes.CRUSH,
        schema_class="Crush",
        slots=(Slot("k", "unloading_stiffness", rule="> 0", expect=_K_POS),),
        curves=(CurveRole("loading", "compression_part"),),
        state_rows=2,
        knots="crush",
        by_rate=False,
        kinks="crush_knots",
        step="curve_slope_or_stiffness",
        laws=("crush_law", "crush_window", "crush_knot_force"),
        call="F{s}, emin, fstar = crush_law(e{s}, emin, fstar, L(e{s}), k)",
        twin="material_laws.crush",
        curve_ends=(True, False),
    ),
    MaterialSpec(
        name="damper",
        code=codes.DAMPER,
        schema_class="Damper",
        slots=(Slot("k", "damping", rule=">= 0", expect="a value >= 0"),),
        curves=(),
        state_rows=0,
        knots=None,
        by_rate=True,
        kinks="none",
        step="damping",
        laws=("damper_force",),
        call="F{s} = damper_force(c, edot)",
        twin="reference._force (c de/dt)",
        reads_rate=True,
    ),
    MaterialSpec(
        name="elastoplastic",
        code=codes.ELASTOPLASTIC,
        schema_class="Elastoplastic",
        slots=(
            Slot("k", "stiffness", rule="> 0", expect=_K_POS),
            Slot(
                "kt",
                "tangent_stiffness",
                rule="below k",
                expect="a tangent_stiffness >= 0 and below stiffness",
            ),
            Slot("fy", "yield_force", rule="> 0", expect="a yield_force > 0"),
        ),
        curves=(),
        state_rows=2,
        knots=None,
        by_rate=False,
        kinks="elastic_limit",
        step="stiffness",
        laws=("elastoplastic_law",),
        call="F{s}, ep, p = elastoplastic_law(e{s}, ep, p, k, kt, fy)",
        twin="material_laws.elastoplastic",
    ),
    MaterialSpec(
        name="nonlinear_damper",
        code=codes.NONLINEAR_DAMPER,
        schema_class="NonlinearDamper",
        slots=(),
        curves=(CurveRole("curve", "non_decreasing"),),
        state_rows=0,
        knots=None,
        by_rate=True,
        kinks="none",
        step="curve_damping",
        laws=(),
        call="F{s} = C(edot)",
        twin="material_laws.curve_eval",
        reads_rate=True,
    ),
    MaterialSpec(  # curve_a is its first (rate-0) curve: a preload loads along it
        name="rate_elastic",
        code=codes.RATE_ELASTIC,
        schema_class="RateElastic",
        slots=(),
        curves=(),
        state_rows=0,
        knots=None,
        by_rate=False,
        kinks="curve_knots",
        step="rate_curves",
        laws=("rate_segment",),
        call="F{s} = rate_segment(F{s}, abs(edot), r_k, r_k+1, C_k(e{s}), C_k+1(e{s})) per k",
        twin="material_laws.rate_elastic",
        reads_rate=True,
        rate_curves="curves",
        curve_ends=(True, True),
    ),
)

BY_NAME = {m.name: m for m in MATERIALS}
BY_CODE = {m.code: m for m in MATERIALS}


def spec(code: int) -> MaterialSpec:
    """The row of material code ``code``."""
    return BY_CODE[int(code)]


def codes_where(test: str) -> tuple[int, ...]:
    """Codes of the materials whose boolean-valued property ``test`` holds, in table order
    (``"by_rate"``, ``"knots"``: follows its loading curve by elongation, ``"state_rows"``: has a state)."""
    return tuple(m.code for m in MATERIALS if getattr(m, test))


MATERIAL_CODES = {m.name: m.code for m in MATERIALS}  # model file ``type`` -> code
#: materials that follow their loading curve (curve_a) by elongation and so can have knot peaks
KNOT_MATERIALS = codes_where("knots")
#: materials with a state (rows of the (S, NSTATE, V) state array)
STATE_MATERIALS = codes_where("state_rows")
#: dampers: the force follows the elongation rate only (no initial_elongation)
DAMPER_MATERIALS = codes_where("by_rate")
#: materials whose force reads the elongation rate (the kernels compute it for them)
RATE_MATERIALS = codes_where("reads_rate")
