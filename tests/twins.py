"""The bitwise twin cases: ``CASES``, ``case -> (model builder, study axes)`` (the builders are
tests/twin_models.py); :func:`record_case` gives a case's batch with the per-step record of every movable
node."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from helpers import model_batch
from twin_models import (
    _KNOT_PREFIX,
    MASSES,
    TWINS,
    _bounce_many,
    full_twin_2d,
    full_twin_both_ways,
    springs_1d,
    springs_2d,
)

KNOT_MASSES = {f"nodes.{p}-body.mass": MASSES for p in _KNOT_PREFIX.values()}
# force and abscissa scales of every spring curve of :func:`knots` ``scaled`` but the unloading one
# (per-variant factors)
SCALED_KNOTS = {
    f"curves.s-{c}.{f}": v
    for c in ("crush-crush", "elastic-elastic", "general-elastic")
    for f, v in (("scale", [0.7, 0.8, 0.9, 1.0, 0.75]), ("x_scale", [1.0, 1.1, 1.2, 1.3, 1.4]))
}


# the knots' masses and curve scales, and the mount's speeds (one more than the 4 of its own case: 2.75)
KNOTS_AND_REVERSAL = {
    **{k.replace("nodes.", "nodes.k-"): v for k, v in KNOT_MASSES.items()},
    **{k.replace("curves.", "curves.k-"): v for k, v in SCALED_KNOTS.items()},
    "nodes.cr-body.mass": [900.0, 1100.0, 1200.0, 1300.0, 1500.0],
    "initial_velocity.mount-engine.0": [-2.0, -2.5, -2.75, -3.0, -3.5],
}

# force and abscissa scales of spring, time and motion curves (a constant shape and per-variant factors)
_SCALED_1D = {
    "curves.plateau.scale": [0.6, 0.7, 0.8, 0.9, 1.0],
    "curves.soft.x_scale": [1.0, 1.1, 1.2, 1.3, 1.4],
    "curves.gn-load.scale": [1.0, 0.9, 0.8, 0.7, 0.95],
    "curves.pulse.x_scale": [0.5, 0.8, 1.0, 1.5, 2.0],
    "curves.pull.x_scale": [1.0, 0.5, 2.0, 1.5, 0.8],
}


_SPEEDS = [0.5, 2.0, 4.0, 6.0, 9.0]  # m/s


def _v2_axes(dim: int) -> dict[str, list[float]]:
    """The v2 parts' speeds (b and c at +-speed along their axis, as ``impact_velocity`` would set them, but
    only them: not the knots' bodies nor the mount) and a per-variant factor on a rate_elastic curve."""
    ax = [1.0] if dim == 1 else [0.6, 0.8]
    return {
        **{
            f"initial_velocity.{p}-{n}.{d}": [sg * c * v for v in _SPEEDS]
            for p in ("fir" if dim == 1 else "fr")
            for n, sg in (("b", 1.0), ("c", -1.0))
            for d, c in enumerate(ax)
        },
        "curves.r-mid.scale": [1.0, 0.8, 1.2, 1.0, 1.5],
    }


# the knots' masses up to 10 kg (as in :func:`one_mass`): at 14 kg the nonlinear elastic spring, run to 0.3 s
# on this model's 0.5 ms step, passes its curve's last knot (-0.1 m) and crushes to zero length
_SPRINGS_2D_AXES = _v2_axes(2) | {k: [6.0, 7.0, 8.0, 9.0, 10.0] for k in KNOT_MASSES}
# the general_nonlinear knot spring (``general-s``) of :func:`springs_2d` crushed to zero length in the last
# two variants (a heavy body at 12 and 16 m/s), the other variants as in its own case
CRUSHED_2D_AXES = _SPRINGS_2D_AXES | {
    "nodes.general-body.mass": [6.0, 7.0, 8.0, 5000.0, 5000.0],
    "initial_velocity.general-body.0": [-2.4, -2.4, -2.4, -7.2, -9.6],
    "initial_velocity.general-body.1": [-3.2, -3.2, -3.2, -9.6, -12.8],
}

# case -> (model builder, study axes); tests/test_kernel_twins.py CHECKS says what each case must exercise
CASES: dict[str, tuple[Callable[[], dict[str, Any]], dict[str, list[float]]]] = {
    "full-twin-1d-every-material-both-ways-scaled-curves": (
        full_twin_both_ways,
        {
            "nodes.a.mass": TWINS["1d-all-materials"][2],
            "nodes.rev-a.mass": [8.0, 6.0, 4.0, 2.0, 1.0],
            **_SCALED_1D,
        },
    ),
    "full-twin-2d-mixed-prescribed-helicopter-rigid-and-penalty-walls": (
        full_twin_2d,
        {
            "nodes.bob.mass": TWINS["2d-mixed-prescribed"][2],
            "nodes.h-cabin.mass": [200.0, 250, 300, 350, 400],
            "rigid_walls.2.stiffness": [2e5, 5e5, 1e6, 2e6, 4e6],
        },
    ),
    "2d-v2-spring-features-rate-elastic-and-knots": (springs_2d, _SPRINGS_2D_AXES),
    "2d-crushed-to-zero": (springs_2d, CRUSHED_2D_AXES),  # the shape of the case above: no compile of its own
    "1d-knots-constant-and-scaled-crush-rebound-reversal-v2-spring-features-and-rate-elastic": (
        springs_1d,
        KNOTS_AND_REVERSAL | _v2_axes(1),
    ),
    # 40 variants of 13 different steps ending each at its own time (lane compaction)
    "early-termination": (
        _bounce_many,
        {
            "impact_velocity": list(np.linspace(4.0, 16.0, 40)),
            "nodes.body.mass": list(np.random.default_rng(3).permutation(np.linspace(60.0, 140.0, 40))),
        },
    ),
}

# cases run with the per-step record of every movable node (tests/test_metrics_record.py's record twins are these
# shapes: one compile serves both files); the others run without a record
RECORD_CASES = (
    "full-twin-1d-every-material-both-ways-scaled-curves",
    "full-twin-2d-mixed-prescribed-helicopter-rigid-and-penalty-walls",
    "2d-v2-spring-features-rate-elastic-and-knots",
    "2d-crushed-to-zero",
    "early-termination",
)
# a slow compile, started at session start on the other core beside helpers.generated_part's shape and the
# crash criteria (~46 CPU s in all): about as long as the generic kernel alone (~51 s) (tests/conftest.py)
WARM_RECORD_CASES = ("full-twin-2d-mixed-prescribed-helicopter-rigid-and-penalty-walls",)


def record_case(case: str) -> tuple[Any, Any, tuple[int, ...]]:
    """(batch, plan, record) of a twin case, ``record`` every movable node when the case is one of
    ``RECORD_CASES``, else ()."""
    build, axes = CASES[case]
    batch, plan = model_batch(build(), axes)
    topo = plan.topology
    record = tuple(n for n in range(topo.n_nodes) if not topo.fixed[n].all() or n in batch.pm_node)
    return batch, plan, record if case in RECORD_CASES else ()
