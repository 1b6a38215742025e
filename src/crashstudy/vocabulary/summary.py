"""The summary variables of a result (one value per variant and item): each name with its dimensions after
``variant``, its unit kind and long name. The results write them (``results/tables.py``, ``results/store.py``)
and a study's ``optimize``/``calibrate`` blocks may name them as columns (``study/blocks.py``): both read them
here, so neither imports the other.
"""

from __future__ import annotations

#: ``past_curve_end``'s values (results.curve_ends checks the springs' extremes against their curves)
CURVE_END_MEANING = (
    "0: within the curve's x range; 1: compressed past its first point; 2: stretched past its last "
    "point; 3: both (the force there is extrapolated along the end segment)"
)
SUMMARY_META = {  # name: (dims after variant, unit kind, long name)
    "peak_force": (("spring",), "force", "largest |spring force| over every time step"),
    "max_crush": (("spring",), "length", "largest shortening of the spring, max(-elongation)"),
    "max_elongation": (("spring",), "length", "largest stretch of the spring, max(elongation)"),
    "failure_time": (("spring",), "time", "time the spring broke at a failure elongation (NaN while intact)"),
    "absorbed_energy": (
        ("spring",),
        "energy",
        "work done on the spring up to the end, plus its energy at t = 0",
    ),
    "peak_deceleration": (("node",), "acceleration", "largest acceleration magnitude over every time step"),
    "peak_deceleration_g": (("node",), "g", "peak_deceleration in standard gravities"),
    "peak_wall_force": (
        ("wall",),
        "force",
        "largest rigid wall contact force: the reaction to the forces pushing "
        "the held nodes into the wall (impacts are wall_impulse)",
    ),
    "wall_impulse": (
        ("wall",),
        "impulse",
        "impact impulse of the rigid wall: the momentum its impacts removed",
    ),
    "energy_error": (
        (),
        "1",
        "max |KE + IE + E_wall - KE0 - IE0 - W_ext| / max(KE0 + |IE0| + |W_ext|, tiny), IE "
        "including IE0 (energy stored at t = 0)",
    ),
    "dt": ((), "time", "time step used"),
    "dt_crit": ((), "time", "critical time step bound (nodal, whole assembly)"),
    "t_end": ((), "time", "last time computed (early termination may end a run before end_time)"),
    "final_kinetic_energy": ((), "energy", "kinetic energy at the end"),
    "final_internal_energy": ((), "energy", "internal energy at the end"),
    "error_estimate": ((), "1", "estimated relative error of the peaks (accuracy_check: re-run at dt/2)"),
    "past_curve_end": (
        ("spring",),
        "1",
        "whether the spring went past an end of its material curve: " + CURVE_END_MEANING,
    ),
}
