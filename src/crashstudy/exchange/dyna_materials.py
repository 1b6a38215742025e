"""Spring materials <-> LS-DYNA ``*MAT_SPRING_*`` / ``*MAT_DAMPER_*`` cards: one row per material.

Each row of :data:`MATERIALS` maps one crashstudy material ``type`` to its keyword: ``write`` gives the
material card's fields (``MID`` aside) and ``read`` the material back from them. Curves go through a
:class:`Curves` helper that knows each material's sign convention (``role``):

- ``"same"``: force [force] vs elongation [length] (or vs elongation rate), compression (negative) points
  first, as crashstudy's curves are (S04 ``LCD``, S05 ``LCDR``, S06 ``LCDL``/``LCDU``);
- ``"crush"``: S08 ``LCFD`` lies in the positive quadrant (crush distance, crush force) and ``CTF = 1``
  makes the spring act in compression only: crashstudy's compression branch mirrored through the origin.

A new material is one row (``claims`` tells rows that share a keyword apart, e.g. S04 with a
``*DEFINE_TABLE`` instead of a curve).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol

NEVER = 1.0e30  #: yield force written for "never yields" (S06 TYI / CYI have no blank meaning infinite)


class Curves(Protocol):
    """Curve ids on the deck side. Export: ``lcid`` (curve id -> LCID), ``table`` ([{rate, curve}] -> TBID of a
    ``*DEFINE_TABLE``). Import: ``curve`` (LCID -> curve id), ``is_table``, ``table_curves`` (TBID -> [{rate, curve}]).
    ``rate_elastic`` is S04 whose LCD names a ``*DEFINE_TABLE`` (one curve per rate)."""

    def lcid(self, curve: str, role: str) -> int: ...

    def curve(self, lcid: object, role: str, field: str) -> str: ...

    def is_table(self, lcid: object) -> bool: ...

    def table(self, rows: list[dict[str, Any]]) -> int: ...

    def table_curves(self, tbid: object, field: str) -> list[dict[str, Any]]: ...


Mat = dict[str, Any]


@dataclass(frozen=True)
class MaterialMap:
    """One material: crashstudy ``type`` <-> LS-DYNA ``keyword`` (card fields other than MID)."""

    type: str
    keyword: str
    write: Callable[[Mat, Curves], dict[str, object]]
    read: Callable[[dict[str, object], Curves], Mat]
    claims: Callable[[dict[str, object], Curves], bool] = lambda fields, curves: True


def _num(v: object, default: float = 0.0) -> float:
    return default if v is None else float(v)  # type: ignore[arg-type]


def _yield_out(v: float | None, sign: float) -> float:
    return sign * NEVER if v is None else v


def _yield_in(v: object) -> float | None:
    return None if v is None or abs(float(v)) >= NEVER or float(v) == 0.0 else float(v)  # type: ignore[arg-type]


MATERIALS: tuple[MaterialMap, ...] = (
    MaterialMap(
        "linear_elastic",
        "MAT_SPRING_ELASTIC",
        lambda m, c: {"K": m["stiffness"]},
        lambda f, c: {"type": "linear_elastic", "stiffness": _num(f["K"])},
    ),
    MaterialMap(
        "damper",
        "MAT_DAMPER_VISCOUS",
        lambda m, c: {"DC": m["damping"]},
        lambda f, c: {"type": "damper", "damping": _num(f["DC"])},
    ),
    MaterialMap(
        "elastoplastic",
        "MAT_SPRING_ELASTOPLASTIC",
        lambda m, c: {"K": m["stiffness"], "KT": m["tangent_stiffness"], "FY": m["yield_force"]},
        lambda f, c: {
            "type": "elastoplastic",
            "stiffness": _num(f["K"]),
            "tangent_stiffness": _num(f["KT"]),
            "yield_force": _num(f["FY"]),
        },
    ),
    MaterialMap(
        "nonlinear_elastic",
        "MAT_SPRING_NONLINEAR_ELASTIC",
        lambda m, c: {"LCD": c.lcid(m["curve"], "same"), "LCR": 0},
        lambda f, c: {"type": "nonlinear_elastic", "curve": c.curve(f["LCD"], "same", "LCD")},
        lambda f, c: not c.is_table(f["LCD"]) and not f["LCR"],
    ),
    MaterialMap(
        "rate_elastic",
        "MAT_SPRING_NONLINEAR_ELASTIC",
        lambda m, c: {"LCD": c.table(m["curves"]), "LCR": 0},
        lambda f, c: {"type": "rate_elastic", "curves": c.table_curves(f["LCD"], "LCD")},
        lambda f, c: c.is_table(f["LCD"]) and not f["LCR"],
    ),
    MaterialMap(
        "nonlinear_damper",
        "MAT_DAMPER_NONLINEAR_VISCOUS",
        lambda m, c: {"LCDR": c.lcid(m["curve"], "same")},
        lambda f, c: {"type": "nonlinear_damper", "curve": c.curve(f["LCDR"], "same", "LCDR")},
    ),
    MaterialMap(
        "general_nonlinear",
        "MAT_SPRING_GENERAL_NONLINEAR",
        lambda m, c: {
            "LCDL": c.lcid(m["loading"], "same"),
            "LCDU": c.lcid(m["unloading"], "same"),
            "BETA": 0.0,
            "TYI": _yield_out(m.get("tension_yield"), 1.0),
            "CYI": _yield_out(m.get("compression_yield"), -1.0),
        },
        lambda f, c: {
            "type": "general_nonlinear",
            "loading": c.curve(f["LCDL"], "same", "LCDL"),
            "unloading": c.curve(f["LCDU"], "same", "LCDU"),
            **{
                k: v
                for k, v in (
                    ("tension_yield", _yield_in(f["TYI"])),
                    ("compression_yield", _yield_in(f["CYI"])),
                )
                if v is not None
            },
        },
        lambda f, c: not f["BETA"],
    ),
    MaterialMap(
        "crush",
        "MAT_SPRING_INELASTIC",
        lambda m, c: {"LCFD": c.lcid(m["loading"], "crush"), "KU": m["unloading_stiffness"], "CTF": 1.0},
        lambda f, c: {
            "type": "crush",
            "loading": c.curve(f["LCFD"], "crush", "LCFD"),
            "unloading_stiffness": _num(f["KU"]),
        },
        lambda f, c: f["CTF"] in (None, 0.0, 1.0),
    ),
)

BY_TYPE = {m.type: m for m in MATERIALS}
KEYWORDS = tuple(dict.fromkeys(m.keyword for m in MATERIALS))
ALIASES = {
    "MAT_S01": "MAT_SPRING_ELASTIC",
    "MAT_S02": "MAT_DAMPER_VISCOUS",
    "MAT_S03": "MAT_SPRING_ELASTOPLASTIC",
    "MAT_S04": "MAT_SPRING_NONLINEAR_ELASTIC",
    "MAT_S05": "MAT_DAMPER_NONLINEAR_VISCOUS",
    "MAT_S06": "MAT_SPRING_GENERAL_NONLINEAR",
    "MAT_S08": "MAT_SPRING_INELASTIC",
}
WHY_NOT = {  # fields of a known keyword that crashstudy cannot follow
    "MAT_SPRING_INELASTIC": "CTF = -1 (tension only) has no crashstudy material: crush acts in compression only",
    "MAT_SPRING_GENERAL_NONLINEAR": "BETA must be 0 (independent yield per direction, as crashstudy's "
    "general_nonlinear): BETA != 0 hardens kinematically or isotropically",
    "MAT_SPRING_NONLINEAR_ELASTIC": "LCR (a rate scale curve) has no crashstudy equivalent; leave it 0",
}


def crush_curve_out(x: list[float], y: list[float]) -> tuple[list[float], list[float]]:
    """crashstudy crush curve -> S08 positive-quadrant curve: its x <= 0 part mirrored, origin first."""
    pts = [(0.0 - a, 0.0 - b) for a, b in zip(x, y, strict=True) if a <= 0.0]  # 0.0 - : no -0.0
    pts.sort()
    return [p[0] for p in pts], [p[1] for p in pts]


def crush_curve_in(x: list[float], y: list[float]) -> tuple[list[float], list[float]]:
    """S08 positive-quadrant curve -> crashstudy compression branch (x <= 0, most compressed first)."""
    pts = sorted((0.0 - a, 0.0 - b) for a, b in zip(x, y, strict=True))
    return [p[0] for p in pts], [p[1] for p in pts]
