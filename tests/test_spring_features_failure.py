"""The SPEC v2 spring option ``failure`` against closed forms, and the summary ``failure_time``: a spring
breaks at its failure elongation and the mass flies on at the speed left, on every kernel.

Every model is a single mass on one spring (1-D, and 2-D along a slanted axis where the feature has a 2-D
form), so the truth is a formula of mechanics, written here from docs/format.md, not from the kernels.
Most tests run the NumPy reference; tests/test_kernel_twins.py holds both fast kernels bitwise equal to it
on every feature."""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest

from crashstudy.kernel import choice, generated
from helpers import generated_part, run_model
from lanes import run_lanes
from models import breaking_spring
from models import one_spring as _one_spring
from spring_feature_runs import _along

# --------------------------------------------------------------------------------------------------
# failure
# --------------------------------------------------------------------------------------------------


K_BREAK, M_BREAK, V_BREAK, E_FAIL = 1.0e4, 1.0, 2.0, 0.01  # amplitude v0 / w = 0.02 m


def _breaking(direction: float, dim: int, failure: dict[str, float]) -> dict[str, Any]:
    """A linear spring (k = 1e4 N/m) under a 1 kg mass leaving (direction 1) or crushing (-1) at 2 m/s,
    run to 6 ms: 0.76 ms (76 samples) past the break at 5.24 ms; the spring that holds reaches 0.0113 m
    (6000 reference steps at dt = 1e-6 s per lane; 10 ms, 10000 steps before)."""
    return _one_spring(
        {"type": "linear_elastic", "stiffness": K_BREAK},
        M_BREAK,
        direction * V_BREAK,
        dim,
        end_time=0.006,
        dt=1.0e-6,
        interval=1.0e-5,
        failure=failure,
    )


@pytest.fixture(scope="module")
def breaking_springs() -> Callable[[int], list[Any]]:
    """dim -> the reference's outputs of (breaking in tension, breaking in compression, and in 1-D a
    spring that holds: failure at +-0.03 m): one kernel call per dimension (tests/lanes.py)."""

    @functools.cache
    def runs(dim: int) -> list[Any]:
        models = [
            _breaking(1.0, dim, {"tension": E_FAIL}),
            _breaking(-1.0, dim, {"compression": -E_FAIL}),
        ]
        if dim == 1:
            models.append(_breaking(1.0, dim, {"tension": 0.03, "compression": -0.03}))
        return run_lanes(models)[0]

    return runs


@pytest.mark.parametrize("dim", [1, 2])
def test_spring_breaks_at_its_failure_elongation_and_the_mass_flies_on_at_the_speed_left(
    dim: int, breaking_springs: Callable[[int], list[Any]]
) -> None:
    """A linear spring (k = 1e4 N/m) under a 1 kg mass at 2 m/s, breaking at |e| = 0.01 m (amplitude 0.02 m):
    ``e = (v0 / w) sin(w t)``, so it breaks at ``t_f = asin(e_f w / v0) / w`` and the mass goes on at
    ``sqrt(v0^2 - w^2 e_f^2)`` with no force; the variant stays ok, ``absorbed_energy`` is the ``k e_f^2 / 2``
    stored when it broke, ``max_elongation`` (or ``max_crush``) the failure elongation.
    Tolerances 1e-4 relative (dt = 1e-6 s, the crossing time interpolated within its step), 1e-3 for the
    energy. In tension (only a tension failure set) and in compression (only a compression failure):
    two lanes of one reference run."""
    k, m, v0, ef = K_BREAK, M_BREAK, V_BREAK, E_FAIL
    w = math.sqrt(k / m)
    t_f = math.asin(ef * w / v0) / w
    for direction, out in zip((1.0, -1.0), breaking_springs(dim)[:2], strict=True):
        assert out.status[0] == 0, direction
        assert out.spring_fail_time[0, 0] == pytest.approx(t_f, rel=1e-4), direction
        v = _along(out, "velocity", dim)
        assert v[-1] == pytest.approx(direction * math.sqrt(v0**2 - (w * ef) ** 2), rel=1e-4), direction
        after = np.arange(len(v)) * 1.0e-5 > t_f + 1.0e-5
        assert np.all(out.histories["spring_force"][after, 0, 0] == 0.0), direction
        # the force stops at the first step past the break; that step books half of F de: O(v dt / e_f) ~ 2e-4
        assert out.absorbed_energy[0, 0] == pytest.approx(0.5 * k * ef**2, rel=1e-3), direction
        extreme = out.max_elongation[0, 0] if direction > 0 else out.max_crush[0, 0]
        assert extreme == pytest.approx(ef, rel=1e-12), direction
        assert out.energy_error[0] < 1e-3, direction


def test_failure_time_is_nan_while_the_spring_holds(breaking_springs: Callable[[int], list[Any]]) -> None:
    """Amplitude 0.02 m, failure at 0.03 m: it never breaks (NaN), and the force history stays ``k e``."""
    out = breaking_springs(1)[2]
    assert np.isnan(out.spring_fail_time[0, 0])
    h = out.histories
    assert np.allclose(
        h["spring_force"][:, 0, 0], 1.0e4 * h["spring_elongation"][:, 0, 0], rtol=1e-12, atol=0
    )


def test_each_lane_of_a_shared_run_is_bitwise_its_model_run_alone() -> None:
    """tests/lanes.py's premise, on the two breaking springs (one fails in tension, the other has only a
    compression failure and crushes): each lane of one call is bit for bit its model's run alone."""
    from helpers import output_differences

    models = [_breaking(1.0, 1, {"tension": E_FAIL}), _breaking(-1.0, 1, {"compression": -E_FAIL})]
    together, _, _ = run_lanes(models, kernel="generic")
    for model, out in zip(models, together, strict=True):
        alone, _, _ = run_model(model, kernel="generic")
        assert output_differences(alone, out) == []


@pytest.mark.parametrize("kernel", ["generic", "generated"])
def test_fast_kernels_give_the_reference_numbers_for_a_breaking_spring(kernel: str) -> None:
    """A spring that breaks, on each fast kernel (the generated one runs it itself, as a part of the one
    model of :func:`models.generated_parts`): bitwise the reference's failure time, max elongation and
    velocities (the full twin cases are in test_kernel_twins)."""
    model = breaking_spring()
    ref, batch, _ = run_model(model, kernel="reference")
    assert generated.unsupported(batch) is None
    assert choice.pick(batch, (), None, kernel) == kernel
    got = generated_part("break", model) if kernel == "generated" else run_model(model, kernel=kernel)[0]
    assert np.isfinite(ref.spring_fail_time[0, 0])
    assert got.spring_fail_time[0, 0] == ref.spring_fail_time[0, 0]
    assert got.max_elongation[0, 0] == ref.max_elongation[0, 0]
    assert np.array_equal(got.histories["velocity"], ref.histories["velocity"], equal_nan=True)
