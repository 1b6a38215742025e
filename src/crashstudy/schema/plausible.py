"""Plausibility of a valid model's numbers against its declared ``units`` (warnings, never errors).

A consistent unit system does not change the arithmetic: a model written in SI numbers but declared
``units: mm-ms-kg-kN`` runs exactly as in SI, only its time is read as milliseconds, its gravity
constant is 1000 times smaller and its peak decelerations in g come out 1000 times too large. Such a
mismatch shows in the numbers: an ``end_time`` of a fraction of a millisecond, a gravity vector far
from standard gravity, masses of hundreds of tonnes, peak decelerations far beyond any crash.
Each check here returns plain sentences for ``warning: ...`` lines; nothing is refused.
"""

from __future__ import annotations

import math

from crashstudy.schema.model import Model
from crashstudy.units import UNIT_SYSTEMS

#: seconds, metres and kilograms per time, length and mass unit of each unit system
TO_SI = {"s": 1.0, "ms": 1.0e-3, "m": 1.0, "mm": 1.0e-3, "kg": 1.0, "t": 1.0e3}

END_TIME_S = (1.0e-3, 60.0)  #: plausible end times [s] of a crash or drop event
MAX_SPEED_M_S = 300.0  #: faster initial speeds [m/s] are far beyond a crash test
MAX_MASS_KG = 1.0e5  #: a heavier single node [kg] (100 t) is not a vehicle part
GRAVITY_RATIO = (0.2, 5.0)  #: |gravity| / standard gravity outside this range is suspect
MIN_STEPS = 5.0  #: end_time shorter than this many critical steps resolves no vibration at all
MAX_PEAK_G = 1000.0  #: peak deceleration [g] of a body mass far beyond any vehicle, occupant or drop test


def _hint(units: str) -> str:
    u = UNIT_SYSTEMS[units]
    return (f"is 'units: {units}' right? (length {u.length}, time {u.time}, mass {u.mass}, force {u.force}; "
            "SI, mm-ms-kg-kN and mm-s-t-N are the unit systems)")  # fmt: skip


def unit_warnings(m: Model, dt_crit: float | None = None, where: str = "") -> list[str]:
    """Sentences about numbers of ``m`` that contradict its unit system (empty when plausible).

    ``dt_crit``: the model's critical time step, if known; ``where``: prefix naming the file."""
    u = UNIT_SYSTEMS[m.units]
    t, length, mass = TO_SI[u.time], TO_SI[u.length], TO_SI[u.mass]
    pre = f"{where}: " if where else ""
    out: list[str] = []
    end_s = m.end_time * t
    if not END_TIME_S[0] <= end_s <= END_TIME_S[1]:
        out.append(f"{pre}end_time {m.end_time:g} {u.time} is {end_s:.3g} s; crash and drop events last "
                   f"{END_TIME_S[0] * 1e3:g} ms to {END_TIME_S[1]:g} s: {_hint(m.units)}")  # fmt: skip
    if m.gravity is not None:
        gmag = math.sqrt(sum(c * c for c in m.gravity))
        if gmag > 0 and not GRAVITY_RATIO[0] <= gmag / u.g <= GRAVITY_RATIO[1]:
            out.append(f"{pre}gravity {gmag:g} {u.acceleration} is {gmag / u.g:.3g} times standard gravity "
                       f"({u.g:g} {u.acceleration} in {m.units}): {_hint(m.units)}")  # fmt: skip
    speeds = [math.sqrt(sum(c * c for c in v)) for v in m.initial_velocity.values()]
    if speeds and max(speeds) * length / t > MAX_SPEED_M_S:
        out.append(f"{pre}initial velocity {max(speeds):g} {u.velocity} is {max(speeds) * length / t:.3g} m/s, "
                   f"beyond any crash: {_hint(m.units)}")  # fmt: skip
    heavy = [
        (nid, n.mass) for nid, n in m.nodes.items() if n.mass is not None and n.mass * mass > MAX_MASS_KG
    ]
    if heavy:
        nid, mm = heavy[0]
        out.append(f"{pre}node {nid!r} has mass {mm:g} {u.mass} = {mm * mass:.3g} kg: {_hint(m.units)}")
    if dt_crit is not None and math.isfinite(dt_crit) and dt_crit > 0 and m.end_time < MIN_STEPS * dt_crit:
        out.append(f"{pre}end_time {m.end_time:g} {u.time} is only {m.end_time / dt_crit:.3g} critical steps "
                   f"(dt_crit {dt_crit:.3g} {u.time}): the stiffest spring-mass pair does not complete one "
                   f"vibration; {_hint(m.units)}")  # fmt: skip
    return out


def body_node(m: Model) -> str | None:
    """The heaviest node that moves freely (not fixed, no prescribed motion): the vehicle or occupant body.

    Its peak deceleration is what a crash limits; a light node between stiff springs (a bumper beam)
    or a node whose motion is prescribed (kinematic spikes) may legitimately peak at thousands of g."""
    driven = {pm.node for pm in m.prescribed_motion}
    free = [(n.mass, nid) for nid, n in m.nodes.items()
            if n.mass is not None and n.fixed is False and nid not in driven]  # fmt: skip
    return max(free)[1] if free else None


def peak_g_warnings(units: str, node: str, peak_g: float, variant: int) -> list[str]:
    """A sentence when the body node's largest peak deceleration ``peak_g`` [g] is beyond any crash."""
    if not math.isfinite(peak_g) or peak_g <= MAX_PEAK_G:
        return []
    return [f"peak deceleration {peak_g:,.0f} g of node {node!r}, the heaviest free mass (variant {variant}), is "
            f"far beyond any crash (vehicle bodies and occupants stay below ~{MAX_PEAK_G:g} g): "
            f"{_hint(units)}"]  # fmt: skip
