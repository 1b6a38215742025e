"""The generated kernel's source for a two-spring model, kept in tests/golden/two_spring_kernel.py: a
sample of what the generator writes (for a reader of kernel/gen_*.py) and a check that it writes the
same text. A change of the generator that changes this text must bump ``gen_shape.GEN_VERSION`` and
regenerate the file (``python tests/test_generated_source.py``), so that the diff shows what changed.
"""

from __future__ import annotations

import ast
import re
import sys
from pathlib import Path

import pytest

GOLDEN = Path(__file__).parent / "golden" / "two_spring_kernel.py"
TWO_SPRINGS = {  # a bumper on a crush curve against a wall, the body behind it on a linear rail
    "name": "two-springs",
    "curves": {"crush": {"x": [-0.3, -0.05, 0.0, 0.1], "y": [-6.0e4, -4.0e4, 0.0, 1.0e4]}},
    "nodes": {
        "wall": {"position": [0.0], "fixed": True},
        "bumper": {"position": [0.5], "mass": 20.0},
        "body": {"position": [1.5], "mass": 800.0},
    },
    "springs": {
        "front": {"nodes": ["wall", "bumper"], "material": {"type": "nonlinear_elastic", "curve": "crush"}},
        "rail": {"nodes": ["bumper", "body"], "material": {"type": "linear_elastic", "stiffness": 2.0e6}},
    },
    "initial_velocity": {"bumper": [-10.0], "body": [-10.0]},
    "end_time": 0.1,
    "output": {"interval": 1.0e-3, "histories": ["spring_force", "kinetic_energy"]},
}


def generated_source() -> str:
    from conftest import model_batch
    from crashstudy.kernel.gen_shape import _shape
    from crashstudy.kernel.gen_source import source

    batch, plan = model_batch(TWO_SPRINGS)
    return source(_shape(batch, plan.topology.histories))


def test_generated_source_of_the_two_spring_model_is_the_golden_file() -> None:
    got = generated_source()
    assert got == GOLDEN.read_text(), (
        "the generated source changed: bump GEN_VERSION and regenerate with python tests/test_generated_source.py"
    )
    assert "# generated" not in got and "def run_blocks(" in got


def test_a_pass_compiled_in_the_running_process_is_vectorised(tmp_path: Path) -> None:
    """The step's passes are functions of their own (``_pass_b``); the process that compiles a kernel runs the
    pass's own code, optimised once by numba, while a kernel loaded from numba's cache runs the copy linked
    into ``run_blocks`` (optimised twice). Once was not enough to vectorise the frontal model's lane loop
    while numba's negative-index fix-ups (``Z[k + w]``) stayed in: that kernel ran 2x slower where it was
    compiled (gen_source._lanes_known_positive). Truth: LLVM's vector types in the optimised code of
    ``_pass_b`` alone, compiled here without a cache (~5 CPU s; without the mask: none)."""
    import importlib.util

    import numba as nb
    import yaml

    from conftest import model_batch
    from crashstudy.kernel.gen_shape import _shape
    from crashstudy.kernel.gen_source import source

    frontal = Path(__file__).parent.parent / "studies" / "models" / "frontal-9mass.yaml"
    batch, plan = model_batch(yaml.safe_load(frontal.read_text()))
    src = source(_shape(batch, plan.topology.histories))
    assert re.search(r"^def _pass_b\(Z, B, n, vi, cst\):$", src, re.M)
    path = tmp_path / "frontal_kernel.py"
    path.write_text(src.replace("cache=True", "cache=False"))
    spec = importlib.util.spec_from_file_location("frontal_kernel", path)
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    f8, i8 = nb.types.Array(nb.float64, 1, "C"), nb.types.Array(nb.int64, 1, "C")
    mod._pass_b.compile((f8, nb.int64, nb.int64, i8, f8))
    code = mod._pass_b.inspect_llvm(mod._pass_b.signatures[0])
    assert re.search(r"<\d+ x double>", code), "the lane loop of _pass_b is not vectorised"


# an elastoplastic spring 0 beside curve 0 scaled per variant (a factor curve): their rows were both named
# "fy0" (the spring's yield force, the curve's force factor), so the curve's row was never loaded
EP = {"type": "elastoplastic", "stiffness": 4.0e4, "tangent_stiffness": 1.0e4, "yield_force": 2.0e3}
EP_BESIDE_FACTOR_CURVE = {
    "name": "ep-beside-factor-curve",
    "curves": {"k0": {"x": [-0.3, -0.01, 0.0], "y": [-3000.0, -1500.0, 0.0]}},
    "nodes": {
        "a": {"position": [0.0], "fixed": True},
        "b": {"position": [1.0], "mass": 10.0},
        "c": {"position": [2.0], "mass": 5.0},
    },
    "springs": {
        "ep": {"nodes": ["a", "b"], "material": EP},
        "cr": {
            "nodes": ["b", "c"],
            "material": {"type": "crush", "loading": "k0", "unloading_stiffness": 2.0e5},
        },
    },
    "initial_velocity": {"c": [-3.0]},
    "end_time": 0.05,
    "output": {"interval": 1.0e-3},
}


def _rows_read_never_written(src: str) -> set[int]:
    """Work-array rows (``Z[k + w]``, or ``Z[_T<t>[i, c] + w]`` for each row k in column c of the constant
    table ``_T<t>``: kernel/gen_loops.py) the source reads but no statement assigns (the block's rows are
    loaded, then updated, by assignments)."""
    tables = {
        t: ast.literal_eval(rows)
        for t, rows in re.findall(r"^_T(\d+) = np\.array\((.*), dtype=np\.int64\)$", src, re.M)
    }

    def rows(text: str) -> set[int]:
        out = {int(k) for k in re.findall(r"Z\[(\d+) \+ w\]", text)}
        for t, c in re.findall(r"Z\[_T(\d+)\[i, (\d+)\] \+ w\]", text):
            out |= {row[int(c)] for row in tables[t]}
        return out

    reads = rows(src)
    writes: set[int] = set()
    for line in src.splitlines():
        target = re.match(r"\s*([^=]*?[^=!<>])=(?!=)", line)  # the targets of an assignment
        if target:
            writes |= rows(target.group(1))
    return reads - writes


def _twin_shapes() -> list[str]:
    from twins import CASES

    return ["ep-beside-factor-curve", *CASES]


@pytest.mark.parametrize("case", _twin_shapes())
def test_every_work_array_row_the_generated_kernel_reads_is_assigned(case: str) -> None:
    """Each row of a generated kernel (kernel/gen_rows.py) is a name handed out once: a row read but never
    assigned is a number the kernel takes from nowhere (the work array is not cleared between blocks)."""
    from conftest import model_batch
    from crashstudy.kernel.gen_shape import _shape
    from crashstudy.kernel.gen_source import source
    from crashstudy.vocabulary.codes import HISTORY_ORDER
    from twins import record_case

    if case == "ep-beside-factor-curve":
        batch, plan = model_batch(EP_BESIDE_FACTOR_CURVE, {"curves.k0.scale": [0.8, 1.0, 1.2]})
        record: tuple[int, ...] = ()
    else:
        batch, plan, record = record_case(case)
    for histories in ((), tuple(HISTORY_ORDER)):
        shape = _shape(batch, histories, plan.varying_curves, record=record)
        assert case != "ep-beside-factor-curve" or shape["fac"] == [0]
        assert _rows_read_never_written(source(shape)) == set(), f"{case}, histories {histories}"


# one 1-D and one 2-D shape (the other twin shapes take ~1 s each and emit the same statements)
@pytest.mark.parametrize(
    "case",
    [
        "full-twin-1d-every-material-both-ways-scaled-curves",
        "full-twin-2d-mixed-prescribed-helicopter-rigid-and-penalty-walls",
    ],
)
def test_a_pass_assigns_each_lane_local_once(case: str) -> None:
    """numba's SSA reconstruction walks a whole function once for each variable assigned more than once;
    the step's passes reused ``kc``, ``th``, ``e``, ``a``... once per spring or node (39 such variables in
    the knots shape's ``_pass_b``: ~1.3 CPU s of its ~14 s compile). gen_locals.single_definitions renames
    them. Truth: numba's own IR of each pass (its frontend, no compile): only the pass's counters
    (``nbad``, ``nhit``, ``nstop``, ``nrev``) and the lane index of pass A's two lane loops are assigned
    twice."""
    import collections

    from numba.core import compiler, ir

    from crashstudy.kernel.gen_shape import _shape
    from crashstudy.kernel.gen_source import source
    from crashstudy.vocabulary.codes import HISTORY_ORDER
    from twins import record_case

    batch, plan, record = record_case(case)
    src = source(_shape(batch, tuple(HISTORY_ORDER), plan.varying_curves, record=record))
    ns: dict[str, object] = {}
    exec(compile(src.replace("cache=True", "cache=False"), case, "exec"), ns)
    for name in ("_pass_a", "_pass_b", "_pass_k"):
        if name not in ns:
            continue
        blocks = compiler.run_frontend(ns[name].py_func).blocks.values()  # type: ignore[attr-defined]
        defs = collections.Counter(
            s.target.name
            for b in blocks
            for s in b.body
            if isinstance(s, ir.Assign) and s.target.name[0] != "$"
        )
        twice = {v for v, k in defs.items() if k > 1} - {"nbad", "nhit", "nstop", "nrev", "w", "w_"}
        assert twice == set(), f"{case} {name}: assigned more than once: {sorted(twice)}"


# a lane body as the passes have it: straight-line redefinitions, a branch that assigns (kept), an augmented
# counter, a row of Z read and written, a local carried from the lane before (``carry``)
LANE_BODY = """def f(Z, B):
    hits = 0
    carry = 0.0
    for w_ in range(B):
        w = w_ & 2147483647
        a = Z[0 + w] * 2.0
        b = a + carry
        a = b - 1.0  # the second a
        if a > 1.0:
            c = a * 3.0
        else:
            c = 0.5
        hits += 1 if c > 1.0 else 0
        Z[8 + w] = a + c
        th, a = a * 0.5, Z[8 + w] - 1.0
        Z[16 + w] = th + a
        carry = th
    return hits, carry
"""


def test_renamed_locals_compute_the_same_numbers() -> None:
    """Truth: the lane body as written, run by Python, against the same body after
    gen_locals.single_definitions (the renames the passes get), on the same random work array."""
    import numpy as np

    from crashstudy.kernel.gen_locals import single_definitions

    renamed = "\n".join(single_definitions(LANE_BODY.splitlines()))
    assert "a_r1 = b - 1.0" in renamed and "th, a_r2 = a_r1 * 0.5" in renamed, renamed
    assert "carry_r" not in renamed and "c_r" not in renamed  # carried; assigned in a branch
    got = []
    for text in (LANE_BODY, renamed):
        ns: dict[str, object] = {}
        exec(text, ns)
        Z = np.random.default_rng(5).uniform(-2.0, 4.0, 24)
        got.append((ns["f"](Z, 8), Z.tobytes()))  # type: ignore[operator]
    assert got[0] == got[1]


if __name__ == "__main__":  # regenerate the golden file
    sys.path.insert(0, str(Path(__file__).parent))
    GOLDEN.write_text(generated_source())
    print(f"wrote {GOLDEN}")
