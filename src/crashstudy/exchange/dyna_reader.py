"""The state of one deck import (:func:`crashstudy.exchange.dyna_import.import_deck`): the deck's curves and
tables by number, the model curves made from them, and the problems found so far; the import side of the
``Curves`` protocol of :mod:`.dyna_materials`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from crashstudy.errors import Problem
from crashstudy.exchange.dyna_cards import FieldError, read_card
from crashstudy.exchange.dyna_deck import Block, Card
from crashstudy.exchange.dyna_materials import crush_curve_in

#: the cards of each simple keyword with their fields, by keyword
Rows = dict[str, list[tuple[Block, Card, dict[str, object]]]]


@dataclass
class DeckReader:
    """State of one import: the deck's entities by number, and the problems found so far."""

    meta: dict[str, Any]
    problems: list[Problem] = field(default_factory=list)
    curves_raw: dict[int, tuple[Block, list[float], list[float]]] = field(default_factory=dict)
    tables: dict[int, list[tuple[float, int]]] = field(default_factory=dict)
    curves: dict[str, dict[str, list[float]]] = field(default_factory=dict)
    made: dict[tuple[int, str], str] = field(default_factory=dict)
    where: tuple[Block, Card | None] | None = None
    exact: dict[float, float] = field(default_factory=dict)  # values export rounded -> their exact values

    def fields(self, b: Block, c: Card, layout: str) -> dict[str, object] | None:
        try:
            return read_card(c.text, layout, self.exact)
        except FieldError as exc:
            self.problems.append(b.problem(str(exc), c))
            return None

    def fail(self, b: Block, msg: str, c: Card | None = None, fld: str = "") -> None:
        self.problems.append(b.problem(msg, c, fld))

    # --- the Curves protocol of dyna_materials ---------------------------------------------------
    def lcid(self, curve: str, role: str) -> int:  # pragma: no cover - export side only
        raise NotImplementedError

    def is_table(self, lcid: object) -> bool:
        return isinstance(lcid, int) and lcid in self.tables and lcid not in self.curves_raw

    def table(self, rows: list[dict[str, Any]]) -> int:  # pragma: no cover - export side only
        raise NotImplementedError

    def table_curves(self, tbid: object, fld: str) -> list[dict[str, Any]]:
        """``[{rate, curve}, ...]`` of the ``*DEFINE_TABLE`` ``tbid`` (each curve read as force vs elongation)."""
        if not self.is_table(tbid):
            b, c = self.where or (None, None)
            if b is not None:
                self.fail(b, f"{fld} = {tbid}: no *DEFINE_TABLE with this id in the deck", c, fld)
            return []
        rows = self.tables[int(tbid)]  # type: ignore[call-overload]
        return [{"rate": rate, "curve": self.curve(lcid, "same", fld)} for rate, lcid in rows]

    def curve(self, lcid: object, role: str, fld: str) -> str:
        """The model curve id of deck curve ``lcid`` read in the sign convention ``role``."""
        b, c = self.where or (None, None)
        if not isinstance(lcid, int) or lcid not in self.curves_raw:
            if b is not None:
                self.fail(b, f"{fld} = {lcid}: no *DEFINE_CURVE with this id in the deck", c, fld)
            return "missing"
        key = (lcid, role)
        if key in self.made:
            return self.made[key]
        _, xs, ys = self.curves_raw[lcid]
        info = self.meta.get("curves", {}).get(str(lcid))
        if info and info[1] == role and (info[2] or info[3]):
            xs, ys = xs[info[2] : len(xs) - info[3]], ys[info[2] : len(ys) - info[3]]
        if role == "crush":
            xs, ys = crush_curve_in(xs, ys)
        name = (
            info[0]
            if info and info[1] == role
            else f"curve-{lcid}" + ("" if role in ("same", "time") else f"-{role}")
        )
        while name in self.curves and name not in self.made.values():
            name += "-2"
        self.curves[name] = {"x": xs, "y": ys}
        self.made[key] = name
        return name
