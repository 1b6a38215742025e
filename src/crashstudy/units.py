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
