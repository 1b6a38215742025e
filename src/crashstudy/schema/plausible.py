"""Plausibility of a valid model's numbers against its declared ``units`` (warnings, never errors).

A consistent unit system does not change the arithmetic: a model written in SI numbers but declared
``units: mm-ms-kg-kN`` runs exactly as in SI, only its time is read as milliseconds, its gravity
constant is 1000 times smaller and its peak decelerations in g come out 1000 times too large. Such a
mismatch shows in the numbers: an ``end_time`` of a fraction of a millisecond, a gravity vector far
from standard gravity, masses of hundreds of tonnes, peak decelerations far beyond any crash. At the
low end: an impact slower than a walking pace, a crash whose body never reaches 1 g, an event far
shorter or longer than the model's first natural period. Where another unit system would make a
number plausible, the warning says which (:func:`likely_unit`): "did you mean m/s? -> 15600".
Each check here returns plain sentences for ``warning: ...`` lines; nothing is refused.
"""

from __future__ import annotations

import math

from crashstudy.schema.model import Model
from crashstudy.units import UNIT_SYSTEMS, UnitSystem

#: seconds, metres and kilograms per time, length and mass unit of each unit system
TO_SI = {"s": 1.0, "ms": 1.0e-3, "m": 1.0, "mm": 1.0e-3, "kg": 1.0, "t": 1.0e3}

END_TIME_S = (1.0e-3, 60.0)  #: plausible end times [s] of a crash or drop event
MAX_SPEED_M_S = 300.0  #: faster initial speeds [m/s] are far beyond a crash test
MAX_MASS_KG = 1.0e5  #: a heavier single node [kg] (100 t) is not a vehicle part
GRAVITY_RATIO = (0.2, 5.0)  #: |gravity| / standard gravity outside this range is suspect
MIN_STEPS = 5.0  #: end_time shorter than this many critical steps resolves no vibration at all
MAX_PEAK_G = 1000.0  #: peak deceleration [g] of a body mass far beyond any vehicle, occupant or drop test
#: slower impacts [m/s] are below a walking pace (~1.4 m/s); 1.0 keeps the 4 km/h (1.1 m/s) bumper test silent
MIN_SPEED_M_S = 1.0
MIN_PEAK_G = 1.0  #: a crash that never decelerates its body mass by 1 g is no crash
PERIOD_RATIO = (0.1, 100.0)  #: end_time / first natural period outside this range is suspect


def _hint(units: str) -> str:
    u = UNIT_SYSTEMS[units]
    return (
        f"is 'units: {units}' right? (length {u.length}, time {u.time}, mass {u.mass}, force {u.force}; "
        "SI, mm-ms-kg-kN and mm-s-t-N are the unit systems)"
    )


def likely_unit(value: float, units: str, dims: tuple[int, int], plausible: tuple[float, float]) -> str:
    """The sentence " did you mean V UNIT? In UNITS that is W OWN_UNIT" when ``value`` read in another unit
    system's unit is plausible (SI range ``plausible``), else "". ``dims``: exponents of (length, time)."""
    u = UNIT_SYSTEMS[units]

    def factor(v: UnitSystem) -> float:
        return float(TO_SI[v.length] ** dims[0] * TO_SI[v.time] ** dims[1])

    own = factor(u)
    for other in UNIT_SYSTEMS.values():
        f = factor(other)
        if f != own and plausible[0] <= abs(value) * f <= plausible[1]:
            name = other.velocity if dims == (1, -1) else other.time
            return (
                f" did you mean {value:g} {name}? In {units} that is {value * f / own:.6g} "
                f"{u.velocity if dims == (1, -1) else u.time}"
            )
    return ""


def speed_warnings(units: str, speeds: list[float], what: str, where: str = "") -> list[str]:
    """A sentence when the fastest of ``speeds`` (> 0, model units) is slower than a walking pace."""
    u = UNIT_SYSTEMS[units]
    to_si = TO_SI[u.length] / TO_SI[u.time]
    moving = [abs(v) for v in speeds if v != 0.0]
    if not moving or max(moving) * to_si >= MIN_SPEED_M_S:
        return []
    v = max(moving)
    pre = f"{where}: " if where else ""
    why = likely_unit(v, units, (1, -1), (MIN_SPEED_M_S, MAX_SPEED_M_S)) or f" {_hint(units)}"
    return [
        f"{pre}{what} {v:g} {u.velocity} is {v * to_si:.3g} m/s, slower than a walking pace "
        f"({MIN_SPEED_M_S:g} m/s):{why}"
    ]


def unit_warnings(
    m: Model, dt_crit: float | None = None, where: str = "", period: float | None = None
) -> list[str]:
    """Sentences about numbers of ``m`` that contradict its unit system (empty when plausible).

    ``dt_crit``: the model's critical time step, if known; ``period``: its first natural period
    (:func:`crashstudy.arrays.vibration.first_period`), if known; ``where``: prefix naming the file."""
    u = UNIT_SYSTEMS[m.units]
    t, length, mass = TO_SI[u.time], TO_SI[u.length], TO_SI[u.mass]
    pre = f"{where}: " if where else ""
    out: list[str] = []
    end_s = m.end_time * t
    if not END_TIME_S[0] <= end_s <= END_TIME_S[1]:
        likely = likely_unit(m.end_time, m.units, (0, 1), END_TIME_S)
        why = (f"{likely};" if likely else "") + f" {_hint(m.units)}"
        out.append(
            f"{pre}end_time {m.end_time:g} {u.time} is {end_s:.3g} s; crash and drop events last "
            f"{END_TIME_S[0] * 1e3:g} ms to {END_TIME_S[1]:g} s:{why}"
        )
    if m.gravity is not None:
        gmag = math.sqrt(sum(c * c for c in m.gravity))
        if gmag > 0 and not GRAVITY_RATIO[0] <= gmag / u.g <= GRAVITY_RATIO[1]:
            out.append(
                f"{pre}gravity {gmag:g} {u.acceleration} is {gmag / u.g:.3g} times standard gravity "
                f"({u.g:g} {u.acceleration} in {m.units}): {_hint(m.units)}"
            )
    speeds = [math.sqrt(sum(c * c for c in v)) for v in m.initial_velocity.values()]
    if speeds and max(speeds) * length / t > MAX_SPEED_M_S:
        out.append(
            f"{pre}initial velocity {max(speeds):g} {u.velocity} is {max(speeds) * length / t:.3g} m/s, "
            f"beyond any crash: {_hint(m.units)}"
        )
    if not (m.loads or m.prescribed_motion or (m.gravity is not None and any(m.gravity))):
        out += speed_warnings(m.units, speeds, "initial velocity", where)  # the only source of motion
    heavy = [
        (nid, n.mass) for nid, n in m.nodes.items() if n.mass is not None and n.mass * mass > MAX_MASS_KG
    ]
    if heavy:
        nid, mm = heavy[0]
        out.append(f"{pre}node {nid!r} has mass {mm:g} {u.mass} = {mm * mass:.3g} kg: {_hint(m.units)}")
    if dt_crit is not None and math.isfinite(dt_crit) and dt_crit > 0 and m.end_time < MIN_STEPS * dt_crit:
        out.append(
            f"{pre}end_time {m.end_time:g} {u.time} is only {m.end_time / dt_crit:.3g} critical steps "
            f"(dt_crit {dt_crit:.3g} {u.time}): the stiffest spring-mass pair does not complete one "
            f"vibration; {_hint(m.units)}"
        )
    elif period is not None and 0 < period < math.inf:
        ratio = m.end_time / period
        if not PERIOD_RATIO[0] <= ratio <= PERIOD_RATIO[1]:
            side = "shorter" if ratio < 1 else "longer"
            out.append(
                f"{pre}end_time {m.end_time:g} {u.time} is {ratio:.3g} times the model's first natural period "
                f"({period:.3g} {u.time}, springs at their steepest slope): far {side} than a crash of this "
                f"structure; check end_time and the masses and stiffnesses against 'units: {m.units}' "
                f"(length {u.length}, time {u.time}, mass {u.mass}, force {u.force})"
            )
    return out


def peak_g_warnings(
    units: str,
    node: str,
    peak_g: float,
    variant: int,
    speeds: list[float] | None = None,
    prescribed: bool = False,
) -> list[str]:
    """A sentence when the body node's largest peak deceleration ``peak_g`` [g] is beyond any crash, or,
    for a model set moving by its initial velocity alone (``speeds``: its initial speeds, None when not
    known; ``prescribed``: it drives a node), below 1 g (naming the likely cause). The body node is the
    results' ``body`` attribute (:func:`crashstudy.results.attributes.body_facts`)."""
    if not math.isfinite(peak_g):
        return []
    if peak_g > MAX_PEAK_G:
        return [
            f"peak deceleration {peak_g:,.0f} g of node {node!r}, the heaviest free mass (variant {variant}), is "
            f"far beyond any crash (vehicle bodies and occupants stay below ~{MAX_PEAK_G:g} g): "
            f"{_hint(units)}"
        ]
    if speeds is None or peak_g >= MIN_PEAK_G or not any(speeds) or prescribed:
        return []
    slow = speed_warnings(units, speeds, "its initial velocity")
    why = (
        ("likely cause: " + slow[0])
        if slow
        else (
            f"likely cause: forces too small or masses too large for 'units: {units}' (a curve in kN in an N model, "
            "a mass in kg in a t model?)"
        )
    )
    return [
        f"peak deceleration {peak_g:.3g} g of node {node!r}, the heaviest free mass (largest of all variants), "
        f"is below {MIN_PEAK_G:g} g: no crash decelerates a body that gently; {why}"
    ]
