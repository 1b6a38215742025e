"""THE reader of a test curve (``calibrate.data``, ``plot --test``, ``correlate --test``): a CSV of
``time,value`` in the model's units, or one channel of an ISO-MME test (its ``.mme`` file, folder or
``.zip``: :mod:`crashstudy.exchange.isomme`) converted into the model's units (docs/format.md, calibrate).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from crashstudy.exchange.isomme import IsoMmeError, read_test
from crashstudy.units import si_per_unit

DATA_MAX = 256 * 2**20  # bytes of a CSV test curve: a measured channel of ~10^7 rows

#: units a test channel may carry -> (kind, value of one of it in SI); spelled as ISO/TS 13499 does
UNITS: dict[str, tuple[str, float]] = {
    "m/(s*s)": ("acceleration", 1.0),
    "m/s**2": ("acceleration", 1.0),
    "m/s^2": ("acceleration", 1.0),
    "m/s2": ("acceleration", 1.0),
    "mm/(s*s)": ("acceleration", 1e-3),
    "mm/(ms*ms)": ("acceleration", 1e3),
    "g": ("acceleration", 9.80665),
    "G": ("acceleration", 9.80665),
    "m/s": ("velocity", 1.0),
    "km/h": ("velocity", 1.0 / 3.6),
    "mm/s": ("velocity", 1e-3),
    "mm/ms": ("velocity", 1.0),
    "m": ("length", 1.0),
    "mm": ("length", 1e-3),
    "cm": ("length", 1e-2),
    "N": ("force", 1.0),
    "kN": ("force", 1e3),
    "daN": ("force", 10.0),
    "s": ("time", 1.0),
    "ms": ("time", 1e-3),
}
#: what each model quantity is measured in
QUANTITY_KIND = {
    "acceleration": "acceleration",
    "velocity": "velocity",
    "displacement": "length",
    "spring_force": "force",
    "spring_elongation": "length",
    "force": "force",
    "elongation": "length",
}


#: a test curve cannot be used (the message names the file, a line, what was expected; ``field``: path,
#: channel or unit)
DataFileError = IsoMmeError


@dataclass(frozen=True)
class TestCurve:
    """A test curve in the model's units: times, values (NaN where the test has NOVALUE), and what it is."""

    time: np.ndarray
    value: np.ndarray
    label: str  # the file, and the channel code for ISO-MME
    unit: str  # the unit the file gave (converted from)


def is_isomme(path: Path) -> bool:
    return path.suffix.lower() in (".mme", ".zip") or path.is_dir()


def unit_entry(unit: str) -> tuple[str, float] | None:
    """(kind, SI value) of ``unit``, spaces ignored (pyisomme writes ``m / s2``), or None if unknown."""
    return UNITS.get(unit.replace(" ", ""))


def known_unit(unit: str, quantity: str | None) -> str:
    """'' when ``unit`` is a known unit (of ``quantity``'s kind when given), else what is wrong."""
    entry = unit_entry(unit)
    if entry is None:
        return f"unknown unit {unit[:30]!r}; known: {', '.join(UNITS)}"
    kind = QUANTITY_KIND.get(quantity or "", None)
    if kind is not None and entry[0] != kind:
        return f"unit {unit!r} is a unit of {entry[0]}; the model's {quantity} needs a unit of {kind}"
    return ""


def read_curve(
    path: Path,
    *,
    channel: str | None = None,
    unit: str | None = None,
    quantity: str | None = None,
    system: str = "SI",
) -> TestCurve:
    """The test curve at ``path`` in the units of ``system``. A CSV's ``channel`` is its value column
    (default ``value``); its values are in model units unless ``unit`` names theirs. An ISO-MME test needs ``channel`` (16 characters, ``?``
    wildcards, exactly one match); its unit (or ``unit``, which overrides it) must be known and of
    ``quantity``'s kind. Raises :class:`DataFileError` (file, line, field, what was expected)."""
    path = Path(path)
    if is_isomme(path):
        return _isomme(path, channel, unit, quantity, system)
    t, y = _csv(path, channel or "value")
    if unit is None:
        return TestCurve(t, y, str(path), "")
    return TestCurve(t, y * _factor(str(path), unit, quantity, system), str(path), unit)


def _factor(where: str, unit: str, quantity: str | None, system: str) -> float:
    why = known_unit(unit, quantity)
    if why:
        raise DataFileError(where, f"{why} (give unit: to say what the values are in)", "unit")
    kind, si = UNITS[unit.replace(" ", "")]
    return si / si_per_unit(system, kind)


def _isomme(
    path: Path, channel: str | None, unit: str | None, quantity: str | None, system: str
) -> TestCurve:
    if not channel:
        raise DataFileError(
            str(path), "an ISO-MME test needs channel: CODE (16 characters, '?' any one)", "channel"
        )
    test = read_test(path)
    ch = test.find(channel)
    t = test.times(ch)
    given = unit or ch.unit
    factor = _factor(f"{ch.where} (channel {ch.code}, Unit {ch.unit!r})", given, quantity, system)
    return TestCurve(t / si_per_unit(system, "time"), ch.values * factor, f"{path} {ch.code}", given)


def _csv(path: Path, column: str) -> tuple[np.ndarray, np.ndarray]:
    import io

    import pandas as pd

    from crashstudy.safefs import PlantedEntryError, open_regular

    try:
        with open_regular(path, DATA_MAX, what=str(path), follow=True) as fh:
            raw = fh.read()
    except FileNotFoundError:
        raise DataFileError(
            str(path), "no such file (expected a CSV time,value or an ISO-MME test)"
        ) from None
    except PlantedEntryError as exc:
        raise DataFileError("", str(exc)) from None
    try:
        df = pd.read_csv(io.BytesIO(raw))
    except (ValueError, UnicodeDecodeError, pd.errors.ParserError) as exc:
        raise DataFileError(
            str(path),
            f"not a CSV table ({type(exc).__name__}); expected a header line "
            "'time,value' and rows of two numbers",
        ) from None
    if not {"time", column} <= set(df.columns):
        field = "path" if column == "value" else "channel"
        raise DataFileError(
            f"{path}, line 1",
            f"expected the header 'time,{column}' (columns time and {column}); "
            f"that line has {len(df.columns)} column(s) with other names",
            field,
        )
    try:
        t, y = df["time"].to_numpy(dtype=float), df[column].to_numpy(dtype=float)
    except (ValueError, TypeError):
        raise DataFileError(str(path), f"expected numbers in columns time and {column}") from None
    return t, y


def data_block(data: object) -> tuple[str, str | None, str | None]:
    """(path, channel, unit) of a study's ``calibrate.data``: a path, or ``{path, channel, unit}``."""
    if isinstance(data, str):
        return data, None, None
    if isinstance(data, dict):
        return str(data["path"]), data.get("channel"), data.get("unit")
    return str(data.path), data.channel, data.unit  # type: ignore[attr-defined]  # the schema's TestData
