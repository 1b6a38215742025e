"""A curve scaled per variant (``curves.<id>.scale``, ``x_scale``) is one constant shape and per-variant
factors: ``F = scale * curve(e / x_scale)`` (issue 25 item 1), and the kernels' per-variant set-up.

Truths: the closed form of a linear spring (peak force ``v sqrt(k m)`` with ``k = scale * k0 / x_scale``,
central differences converge to it as dt^2: tolerance 2e-4 at dt = T / 2000); the NumPy reference kernel
for bitwise equality (the twin cases ``scaled-*`` in test_kernel_twins cover every curve use); the
generated source for what stays in registers.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

import numpy as np
import pytest
import yaml

from crashstudy.kernel import driver
from crashstudy.kernel.gen_shape import _shape
from crashstudy.kernel.gen_source import source
from crashstudy.study.plan import load_study
from helpers import generated_part, model_batch, run_model
from models import SCALED_K0, SCALED_M, SCALED_V0, SCALES
from models import scaled_spring as _spring

K0, M, V0 = SCALED_K0, SCALED_M, SCALED_V0  # N/m, kg, m/s


@pytest.mark.parametrize("kernel", ["reference", "generated"])
def test_a_scaled_curve_is_scale_times_the_curve_of_x_over_x_scale(kernel: str) -> None:
    k = K0 * np.array(SCALES["curves.c.scale"]) / np.array(SCALES["curves.c.x_scale"])
    dt = float(2 * np.pi * np.sqrt(M / k.max()) / 2000)
    if kernel == "generated":  # a part of the one model of models.generated_parts, run with these scales
        out = generated_part("scaled", _spring(dt), every_variant=True)
    else:
        out, _, _ = run_model(_spring(dt), kernel=kernel, variants=SCALES)
    assert np.all(out.status == 0)
    np.testing.assert_allclose(out.peak_force[0], V0 * np.sqrt(k * M), rtol=2e-4)


def test_the_generated_kernel_keeps_a_scaled_curves_shape_and_reads_three_factors_per_variant(
    tmp_path: Path,
) -> None:
    """The study's scale axes leave the curve's points alone: the kernel's shape has the curve as a factor
    curve, its coefficients are registers and no per-variant knot or slope is read."""
    (tmp_path / "m.yaml").write_text(yaml.safe_dump(_spring(1e-4), sort_keys=False))
    plan = load_study(
        {"name": "s", "model": str(tmp_path / "m.yaml"), "matrix": SCALES | {"impact_velocity": [2.0, 3.0]}}
    )
    assert plan.varying_curves == frozenset({-1})  # curve 0, scaled only
    batch, _ = model_batch(_spring(1e-4), SCALES)
    shape = _shape(batch, (), plan.varying_curves)
    assert shape["const"] == [] and shape["fac"] == [0]
    src = source(shape)
    # the block set-up copies the factors through a constant table: (work row, factor, curve) per line
    table = re.search(r"= cfac\[_T(\d+)\[i, 1\], _T\1\[i, 2\], q\]", src)
    assert table is not None, "the kernel reads no per-variant curve factor"
    rows = re.search(rf"^_T{table[1]} = np\.array\((.*), dtype=np\.int64\)$", src, re.M)
    assert rows is not None
    assert [tuple(r[1:]) for r in ast.literal_eval(rows[1])] == [
        (0, 0),
        (1, 0),
        (2, 0),
    ]  # ys, xs, ys/xs of curve 0
    assert not any(f"{a}[" in src for a in ("cx", "cy", "cds", "cs0")), (
        "a per-variant curve coefficient is read"
    )


def test_scale_axes_give_the_points_times_the_factors() -> None:
    batch, _ = model_batch(_spring(1e-4), SCALES)
    ys, xs = np.array(SCALES["curves.c.scale"]), np.array(SCALES["curves.c.x_scale"])
    assert np.array_equal(batch.cy, np.array([-K0, 0.0, K0])[:, None] * ys)
    assert np.array_equal(batch.cx, np.array([-1.0, 0.0, 1.0])[:, None] * xs)
    assert np.array_equal(batch.cs0[0], K0 * (ys / xs)) and np.all(batch.by == batch.by[:, :1])


def test_blocks_are_run_in_a_few_calls_per_thread_not_one_call_per_block(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Each call of a compiled kernel unboxes its argument records; 10^6 short variants are ~4000 blocks."""
    calls: list[tuple[int, int]] = []
    monkeypatch.setattr(driver, "_THREADS", [2])
    starts = driver.block_starts(1_000_000, 256)
    driver.run_blocks(lambda lo, hi, st: calls.append((int(lo), int(hi))), starts)
    assert len(calls) <= 2 * driver.PER_THREAD
    covered = sorted(b for lo, hi in calls for b in range(lo, hi))
    assert covered == list(range(len(starts) - 1))


def test_fewer_variants_than_full_blocks_are_split_over_the_threads_and_keep_their_numbers(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """40 variants on 2 threads are two blocks of 20, not one block on one core; every variant's numbers are
    bitwise those of the same batch run as one block (truth: the one-block run; a block's variants are
    independent)."""
    from crashstudy.kernel.compiled import run_compiled

    monkeypatch.setattr(driver, "_THREADS", [2])
    assert driver.block_starts(40, 256).tolist() == [0, 20, 40]
    assert driver.block_starts(20, 256).tolist() == [0, 20]  # under 2 x MIN_LANES: one block
    assert driver.block_starts(600, 256).tolist() == [0, 256, 512, 600]  # full blocks: as before
    scale = np.linspace(0.5, 2.0, 40).tolist()
    batch, plan = model_batch(_spring(1e-4), {"curves.c.scale": scale, "curves.c.x_scale": scale[::-1]})
    hist = plan.topology.histories
    split = run_compiled(batch, hist, plan.n_out)
    monkeypatch.setattr(driver, "MIN_LANES", 10**9)  # one block of 40
    assert driver.block_starts(40, 256).tolist() == [0, 40]
    whole = run_compiled(batch, hist, plan.n_out)
    for name in ("peak_force", "max_crush", "max_elongation", "absorbed_energy", "final_energy", "status"):
        np.testing.assert_array_equal(getattr(split, name), getattr(whole, name), err_msg=name)
    assert np.all(split.status == 0) and len(np.unique(split.peak_force[0])) > 30  # the variants differ
