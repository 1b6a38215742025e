"""The material table (crashstudy.vocabulary.materials) against the code that must follow it.

Every row needs: its schema class (and that class in the ``Material`` union), its laws in
``kernel/laws.py``, its NumPy twin, a hand-written branch in both compiled dispatches (the generic
kernel's force branch in ``kernel/generic_force.py`` and the generator's ``gen_springs``), a branch in the
reference's force, and a case in the bitwise twin suite (tests/twins.py CASES, run by tests/test_kernel_twins.py). A material added
to the table but missing one of those fails here, by name, before any kernel runs.
"""

from __future__ import annotations

import inspect
import typing

import pytest
import yaml

from crashstudy.vocabulary import codes
from crashstudy.vocabulary.materials import MATERIAL_CODES, MATERIALS, MaterialSpec


def _code_name(row: MaterialSpec) -> str:
    """The vocabulary.codes constant that holds the row's code."""
    names = [
        n
        for n in (
            "LINEAR",
            "NONLINEAR",
            "GENERAL",
            "CRUSH",
            "DAMPER",
            "ELASTOPLASTIC",
            "NONLINEAR_DAMPER",
            "RATE_ELASTIC",
        )
        if getattr(codes, n, None) == row.code
    ]
    assert len(names) == 1, f"{row.name}: code {row.code} is not exactly one vocabulary.codes constant"
    return names[0]


def test_table_codes_and_names_are_unique() -> None:
    assert len({m.code for m in MATERIALS}) == len(MATERIALS)
    assert len(MATERIAL_CODES) == len(MATERIALS)
    assert all(m.state_rows <= codes.NSTATE for m in MATERIALS)


def test_schema_union_is_the_table() -> None:
    from crashstudy.schema import model

    union = typing.get_args(typing.get_args(model.Material)[0])
    assert {c.__name__ for c in union} == {m.schema_class for m in MATERIALS}
    for m in MATERIALS:
        cls = getattr(model, m.schema_class)
        assert typing.get_args(cls.model_fields["type"].annotation) == (m.name,)
        for slot in m.slots:
            assert slot.field in cls.model_fields, (
                f"{m.name}: slot {slot.field} is no field of {m.schema_class}"
            )
        for role in m.curves:
            assert role.field in cls.model_fields, (
                f"{m.name}: curve {role.field} is no field of {m.schema_class}"
            )


@pytest.mark.parametrize("row", MATERIALS, ids=lambda m: m.name)
def test_every_row_has_laws_twin_branches_and_a_twin_case(row: MaterialSpec) -> None:
    from crashstudy.arrays import material_laws as twins
    from crashstudy.kernel import compiled, gen_springs, generic_force, laws, reference

    for law in row.laws:
        assert hasattr(laws, law), f"{row.name}: law {law} not in kernel/laws.py"
    module, _, name = row.twin.partition(".")
    twin_module = {"material_laws": twins, "reference": reference}[module]
    assert hasattr(twin_module, name.split(" ")[0]), f"{row.name}: twin {row.twin} not found"
    const = _code_name(row)
    generic = inspect.getsource(generic_force) + inspect.getsource(compiled)
    assert f"kind == {const}" in generic, (
        f"{row.name}: no branch in the generic kernel's force dispatch (generic_force.force, compiled._run)"
    )
    emitted = inspect.getsource(gen_springs.pass_b_springs)
    assert f"k == codes.{const}" in emitted or (
        const == "GENERAL" and "mat[s] == codes.GENERAL" in emitted
    ), f"{row.name}: no branch in the generator's dispatch (gen_springs.pass_b_springs)"
    assert f"kind == {const}" in inspect.getsource(reference._force), (
        f"{row.name}: no branch in reference._force"
    )
    assert row.name in _twin_case_materials(), (
        f"{row.name}: no case in the bitwise twin suite (tests/test_kernel_twins.py)"
    )


def _twin_case_materials() -> set[str]:
    """The material types of every model of the bitwise twin suite's cases."""
    from twins import CASES

    seen: set[str] = set()
    for build, _ in CASES.values():
        model = build()
        model = yaml.safe_load(model) if isinstance(model, str) else model
        seen |= {sp["material"]["type"] for sp in model["springs"].values()}
    return seen
