"""LS-DYNA keyword cards: the field layouts crashstudy writes and reads, and the two card formats.

One table (:data:`LAYOUTS`) holds every card's fields as the LS-DYNA keyword manual sets them
(name, width in characters, kind: ``i`` integer, ``f`` real, ``a`` text). The writer
(:func:`card`) and the reader (:func:`read_card`) both use it, so a layout is written once.

Fixed format: each field sits in its columns, right-aligned; a blank field is "not given" (the
keyword's default, which for some fields is zero). Comma format (free format): the card's fields
separated by commas, each value no longer than its fixed width; an empty field is blank.
"""

from __future__ import annotations

from dataclasses import dataclass, field

Field = tuple[str, int, str]  # (name, width [characters], kind: "i" | "f" | "a")


def _row(kind: str, width: int, names: str) -> list[Field]:
    return [(n, width, kind) for n in names.split()]


LAYOUTS: dict[str, list[Field]] = {
    "TITLE": [("TITLE", 80, "a")],
    "CONTROL_TERMINATION": [
        ("ENDTIM", 10, "f"),
        ("ENDCYC", 10, "i"),
        ("DTMIN", 10, "f"),
        ("ENDENG", 10, "f"),
        ("ENDMAS", 10, "f"),
        ("NOSOL", 10, "i"),
    ],
    "CONTROL_TIMESTEP": [
        ("DTINIT", 10, "f"),
        ("TSSFAC", 10, "f"),
        ("ISDO", 10, "i"),
        ("TSLIMT", 10, "f"),
        ("DT2MS", 10, "f"),
        ("LCTM", 10, "i"),
        ("ERODE", 10, "i"),
        ("MS1ST", 10, "i"),
    ],
    "NODE": [("NID", 8, "i"), ("X", 16, "f"), ("Y", 16, "f"), ("Z", 16, "f"), ("TC", 8, "i"), ("RC", 8, "i")],
    "ELEMENT_MASS": [("EID", 8, "i"), ("NID", 8, "i"), ("MASS", 16, "f"), ("PID", 8, "i")],
    "PART_HEADING": [("HEADING", 70, "a")],
    "PART": _row("i", 10, "PID SECID MID EOSID HGID GRAV ADPOPT TMID"),
    "SECTION_DISCRETE": [("SECID", 10, "i"), ("DRO", 10, "i"), *_row("f", 10, "KD V0 CL FD")],
    "SECTION_DISCRETE_2": _row("f", 10, "CDL TDL"),
    "MAT_SPRING_ELASTIC": [("MID", 10, "i"), ("K", 10, "f")],
    "MAT_DAMPER_VISCOUS": [("MID", 10, "i"), ("DC", 10, "f")],
    "MAT_SPRING_ELASTOPLASTIC": [("MID", 10, "i"), *_row("f", 10, "K KT FY")],
    "MAT_SPRING_NONLINEAR_ELASTIC": [("MID", 10, "i"), ("LCD", 10, "i"), ("LCR", 10, "i")],
    "MAT_DAMPER_NONLINEAR_VISCOUS": [("MID", 10, "i"), ("LCDR", 10, "i")],
    "MAT_SPRING_GENERAL_NONLINEAR": [*_row("i", 10, "MID LCDL LCDU"), *_row("f", 10, "BETA TYI CYI")],
    "MAT_SPRING_INELASTIC": [("MID", 10, "i"), ("LCFD", 10, "i"), ("KU", 10, "f"), ("CTF", 10, "f")],
    "DEFINE_CURVE": [
        *_row("i", 10, "LCID SIDR"),
        *_row("f", 10, "SFA SFO OFFA OFFO"),
        *_row("i", 10, "DATTYP LCINT"),
    ],
    "DEFINE_CURVE_POINT": [("A", 20, "f"), ("O", 20, "f")],
    "DEFINE_TABLE": [("TBID", 10, "i"), ("SFA", 10, "f"), ("OFFA", 10, "f")],
    "DEFINE_TABLE_ROW": [("VALUE", 20, "f"), ("LCID", 20, "i")],
    "ELEMENT_DISCRETE": [
        *_row("i", 8, "EID PID N1 N2 VID"),
        ("S", 16, "f"),
        ("PF", 8, "i"),
        ("OFFSET", 16, "f"),
    ],
    "INITIAL_VELOCITY_NODE": [("NID", 10, "i"), *_row("f", 10, "VX VY VZ VXR VYR VZR"), ("ICID", 10, "i")],
    "BOUNDARY_SPC_NODE": _row("i", 10, "NID CID DOFX DOFY DOFZ DOFRX DOFRY DOFRZ"),
    "BOUNDARY_PRESCRIBED_MOTION_NODE": [
        *_row("i", 10, "NID DOF VAD LCID"),
        ("SF", 10, "f"),
        ("VID", 10, "i"),
        *_row("f", 10, "DEATH BIRTH"),
    ],
    "LOAD_NODE_POINT": [*_row("i", 10, "NID DOF LCID"), ("SF", 10, "f"), *_row("i", 10, "CID M1 M2 M3")],
    "LOAD_BODY": [
        ("LCID", 10, "i"),
        ("SF", 10, "f"),
        ("LCIDDR", 10, "i"),
        *_row("f", 10, "XC YC ZC"),
        ("CID", 10, "i"),
    ],
    "RIGIDWALL_ID": [("ID", 10, "i"), ("TITLE", 70, "a")],
    "RIGIDWALL_PLANAR": [*_row("i", 10, "NSID NSIDEX BOXID"), *_row("f", 10, "OFFSET BIRTH DEATH RWKSF")],
    "RIGIDWALL_PLANAR_2": _row("f", 10, "XT YT ZT XH YH ZH FRIC WVEL"),
    "SET_NODE_LIST": [("SID", 10, "i"), *_row("f", 10, "DA1 DA2 DA3 DA4"), ("SOLVER", 10, "a")],
    "SET_NODE_LIST_IDS": _row("i", 10, "NID1 NID2 NID3 NID4 NID5 NID6 NID7 NID8"),
    "DATABASE": [("DT", 10, "f"), *_row("i", 10, "BINARY LCUR IOOPT")],
    "DATABASE_HISTORY_NODE": _row("i", 10, "ID1 ID2 ID3 ID4 ID5 ID6 ID7 ID8"),
}


def fmt_float(v: float, width: int) -> tuple[str, bool]:
    """``v`` in at most ``width`` characters: the shortest text that reads back as exactly ``v``, else
    the closest that fits. Returns ``(text, exact)``."""
    v = float(v)
    if v == 0.0:
        return "0.0", True
    plain = repr(v)
    candidates = [plain] if "e" not in plain and "inf" not in plain else []
    for p in range(17):
        m, _, e = f"{v:.{p}e}".partition("e")
        candidates.append(f"{m if '.' in m else m + '.'}e{int(e)}")
        fixed = f"{v:.{p + 1}f}"
        if float(fixed) != 0.0:
            candidates.append(
                fixed.replace("0.", ".", 1)
                if fixed.startswith(("0.", "-0.")) and len(fixed) > width
                else fixed
            )
    exact = [c for c in candidates if float(c) == v]
    if candidates[0] == plain and len(plain) <= width:  # readable first: 100.0 rather than 1.e2
        return plain, True
    best = min(exact, key=len) if exact else ""
    if best and len(best) <= width:
        return best, True
    fitting = [c for c in candidates if len(c) <= width]
    return max(fitting, key=lambda c: (-abs(float(c) - v), -len(c))), False


@dataclass
class Rounded:
    """Values that did not fit their field exactly: reported to the user, and kept as pairs (written value,
    exact value) so that crashstudy's import can restore the exact one (:meth:`restore_table`)."""

    items: list[str]
    pairs: dict[float, set[float]] = field(default_factory=dict)
    written: set[float] = field(default_factory=lambda: {0.0, 1.0})  # values written exactly

    def note(self, what: str, v: float, text: str) -> None:
        self.items.append(f"{what}: {v!r} written as {text}")
        self.pairs.setdefault(float(text), set()).add(v)

    def restore_table(self) -> list[list[float]]:
        """``[[written, exact], ...]`` for the written values that stand for one exact value only and that
        no field holds exactly (so replacing them on import can change nothing else)."""
        return [[w, next(iter(xs))] for w, xs in self.pairs.items() if len(xs) == 1 and w not in self.written]


def card(layout: str, values: dict[str, object], rounded: Rounded | None = None, what: str = "") -> str:
    """One fixed-format card of ``layout``; fields not in ``values`` (or None) are left blank."""
    out = []
    fields = LAYOUTS[layout]
    last = max((i for i, (n, _, _) in enumerate(fields) if values.get(n) is not None), default=-1)
    for name, width, kind in fields[: last + 1]:
        v = values.get(name)
        if v is None:
            out.append(" " * width)
        elif kind == "a":
            out.append(str(v)[:width].ljust(width))
        elif kind == "i":
            text = str(int(v))  # type: ignore[call-overload]
            if len(text) > width:
                raise ValueError(f"{layout}.{name}: {text} does not fit {width} characters")
            out.append(text.rjust(width))
        else:
            text, exact = fmt_float(float(v), width)  # type: ignore[arg-type]
            if rounded is not None and not exact:
                rounded.note(f"{what} (*{layout} {name})", float(v), text)  # type: ignore[arg-type]
            elif rounded is not None:
                rounded.written.add(float(text))
            out.append(text.rjust(width))
    return "".join(out).rstrip()


def titles(layout: str) -> str:
    """A ``$#`` comment naming the fields of ``layout`` over their columns (as decks usually carry)."""
    parts = [n.lower().rjust(w) if k != "a" else n.lower().ljust(w) for n, w, k in LAYOUTS[layout]]
    return ("$#" + "".join(parts)[2:]).rstrip()


class FieldError(ValueError):
    """A field that is not a number of the expected kind (the message names field and text)."""


def read_card(text: str, layout: str, exact: dict[float, float] | None = None) -> dict[str, object]:
    """Fields of one card (fixed or comma format): name -> int | float | str, or None when blank. A real
    that ``exact`` lists (a value crashstudy's export had to round) is replaced by its exact value."""
    fields = LAYOUTS[layout]
    if "," in text and fields[0][2] != "a":
        parts = text.split(",")
        if len(parts) > len(fields):
            if any(p.strip() for p in parts[len(fields) :]):
                raise FieldError(f"{len(parts)} comma-separated fields, {layout} has {len(fields)}")
        parts = parts[: len(fields)]
    else:
        parts, pos = [], 0
        for _, width, _ in fields:
            parts.append(text[pos : pos + width])
            pos += width
    out: dict[str, object] = {}
    for (name, _, kind), raw in zip(fields, parts + [""] * (len(fields) - len(parts)), strict=True):
        s = raw.strip()
        if kind == "a":
            out[name] = raw.rstrip() if s else None
        elif not s:
            out[name] = None
        else:
            try:
                num = float(s.replace("D", "E").replace("d", "e"))
            except ValueError:
                raise FieldError(
                    f"field {name} is {s!r}: expected {'an integer' if kind == 'i' else 'a number'}"
                ) from None
            if kind == "i":
                if num != int(num):
                    raise FieldError(f"field {name} is {s!r}: expected an integer")
                out[name] = int(num)
            else:
                out[name] = exact.get(num, num) if exact else num
    return out
