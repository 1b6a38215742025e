"""Consistent unit systems (docs/format.md, units).

Every number in a model file is in the file's ``units`` system; outputs carry the unit names.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

UnitSystemName = Literal["SI", "mm-ms-kg-kN", "mm-s-t-N"]


@dataclass(frozen=True)
class UnitSystem:
    """Names of the base and derived units of one consistent system, and standard gravity in it."""

    name: str
    length: str
    time: str
    mass: str
    force: str
    energy: str
    g: float

    @property
    def velocity(self) -> str:
        return f"{self.length}/{self.time}"

    @property
    def acceleration(self) -> str:
        return f"{self.length}/{self.time}^2"


UNIT_SYSTEMS: dict[str, UnitSystem] = {
    "SI": UnitSystem("SI", "m", "s", "kg", "N", "J", 9.80665),
    "mm-ms-kg-kN": UnitSystem("mm-ms-kg-kN", "mm", "ms", "kg", "kN", "J", 9.80665e-3),
    "mm-s-t-N": UnitSystem("mm-s-t-N", "mm", "s", "t", "N", "mJ", 9806.65),
}


#: each base unit name of :data:`UNIT_SYSTEMS` in SI (1 of it is this many m, s, kg, N or J)
SI_VALUE: dict[str, float] = {
    "m": 1.0,
    "mm": 1e-3,
    "s": 1.0,
    "ms": 1e-3,
    "kg": 1.0,
    "t": 1e3,
    "N": 1.0,
    "kN": 1e3,
    "J": 1.0,
    "mJ": 1e-3,
}


def si_per_unit(system: str, kind: str) -> float:
    """How many SI units one ``kind`` unit (length, time, velocity, acceleration, force, mass, energy) of
    ``system`` is: a value in the system times this is the value in SI."""
    u = UNIT_SYSTEMS[system]
    length, time = SI_VALUE[u.length], SI_VALUE[u.time]
    derived = {
        "velocity": length / time,
        "acceleration": length / time**2,
        "length": length,
        "time": time,
        "force": SI_VALUE[u.force],
        "mass": SI_VALUE[u.mass],
        "energy": SI_VALUE[u.energy],
    }
    return derived[kind]
