"""Codes and names the kernels share with the rest of crashstudy (one copy of each table).

The ground floor: schema/, arrays/ and kernel/ import it; it imports nothing of crashstudy.
"""

from __future__ import annotations

from typing import Literal

#: a kernel named by a caller: "compiled" lets kernel.choice pick the fastest (CRASHSTUDY_KERNEL may name one)
KernelName = Literal["compiled", "reference", "generic", "generated"]

# material codes seen by the kernels (spring ``material`` array); each material's row, its name among
# them, is in vocabulary.materials (MATERIALS, MATERIAL_CODES, KNOT_MATERIALS, STATE_MATERIALS)
LINEAR, NONLINEAR, GENERAL, CRUSH, DAMPER, ELASTOPLASTIC, NONLINEAR_DAMPER, RATE_ELASTIC = (
    0,
    1,
    2,
    3,
    4,
    5,
    6,
    7,
)
# rows of the (S, NSTATE, V) material state array (the most any material uses: MaterialSpec.state_rows)
NSTATE = 8

# prescribed-motion quantities
PM_DISPLACEMENT, PM_VELOCITY, PM_ACCELERATION = 0, 1, 2
PM_CODES = {"displacement": PM_DISPLACEMENT, "velocity": PM_VELOCITY, "acceleration": PM_ACCELERATION}

# failure codes (status); 0 = ok
OK, UNSTABLE, CRUSHED_TO_ZERO, INVALID = 0, 1, 2, 3

# the histories a kernel can record: dims between time and variant, in the kernels' order
HISTORY_SHAPES = {
    "position": ("node", "axis"),
    "displacement": ("node", "axis"),
    "velocity": ("node", "axis"),
    "acceleration": ("node", "axis"),
    "spring_force": ("spring",),
    "spring_elongation": ("spring",),
    "kinetic_energy": (),
    "internal_energy": (),
    "external_work": (),
    "wall_energy": (),
    "wall_force": ("wall",),
}
HISTORY_ORDER = tuple(HISTORY_SHAPES)
# the four energies, written together (final_energy rows, h_energy columns)
ENERGIES = ("kinetic_energy", "internal_energy", "external_work", "wall_energy")

TINY_LENGTH = 1e-12  # a 2-D spring shorter than this fraction of its initial length has collapsed
UNSTABLE_ENERGY = 1.0  # an energy balance error above this fraction of KE0 + IE0 + |W_ext| (+ a round-off
# floor of 1e-9 of the springs' k L0^2 and the initial m v0^2) is an instability
WALL_PASSIVITY = 1e-9  # walls that have given back more than this fraction of that limit: an instability
# fail_item of an UNSTABLE variant: which test failed (-1, as allocated: the energy balance)
UNSTABLE_BALANCE, UNSTABLE_WALLS = -1, -2  # UNSTABLE_WALLS: the rigid walls gave back energy
TIME_EPS = 1e-9  # relative to a time curve's span: t = n dt carries round-off, a knot at end_time is inside
