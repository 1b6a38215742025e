"""An LS-DYNA deck of discrete elements -> a crashstudy model (the subset :mod:`.dyna_export` writes).

Reads the blocks of :mod:`.dyna_deck` (fixed or comma format cards, :mod:`.dyna_cards` layouts),
maps each keyword back (materials through :data:`.dyna_materials.MATERIALS`) and validates the result
as a model. Keywords outside the subset are listed and refused (``skip_unsupported``: listed and
skipped). A deck written by crashstudy carries ``$crashstudy:`` comments (ids, time-step rule,
histories, criteria); without them ids are made from the deck's numbers (``n1``, ``s1``, ``curve-1``).
Every bad field is an :class:`InputError` naming the deck file, line and keyword.
"""

from __future__ import annotations

import json
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from crashstudy.errors import InputError, Problem
from crashstudy.exchange.dyna_cards import FieldError, read_card
from crashstudy.exchange.dyna_deck import Block, Card, read_deck
from crashstudy.exchange.dyna_materials import ALIASES, KEYWORDS, MATERIALS, WHY_NOT, crush_curve_in
from crashstudy.units import UNIT_SYSTEMS

SIMPLE = {"CONTROL_TERMINATION", "CONTROL_TIMESTEP", "NODE", "ELEMENT_MASS", "ELEMENT_DISCRETE", "INITIAL_VELOCITY_NODE",
          "BOUNDARY_SPC_NODE", "BOUNDARY_PRESCRIBED_MOTION_NODE", "LOAD_NODE_POINT", "DATABASE_HISTORY_NODE"}  # fmt: skip
OTHER = {"KEYWORD", "TITLE", "PART", "SECTION_DISCRETE", "DEFINE_CURVE", "DEFINE_CURVE_TITLE", "DEFINE_TABLE",
         "LOAD_BODY_X", "LOAD_BODY_Y", "LOAD_BODY_Z", "RIGIDWALL_PLANAR", "RIGIDWALL_PLANAR_ID", "SET_NODE_LIST",
         "DATABASE_NODOUT", "DATABASE_DEFORC", "DATABASE_GLSTAT"}  # fmt: skip
TC_CODES = {0: "", 1: "x", 2: "y", 3: "z", 4: "xy", 5: "yz", 6: "zx", 7: "xyz"}  #: *NODE TC: translations held
NEVER_TIME = 1.0e28  #: BIRTH/DEATH at or beyond this: "always" (LS-DYNA's default DEATH)


def _material_keyword(name: str) -> tuple[str, bool]:
    """``(canonical keyword, has a title card)`` of a material keyword name, or ``("", False)``."""
    titled = name.endswith("_TITLE")
    base = ALIASES.get(name[:-6] if titled else name, name[:-6] if titled else name)
    return (base, titled) if base in KEYWORDS else ("", False)


def supported(name: str) -> bool:
    return name in SIMPLE or name in OTHER or bool(_material_keyword(name)[0])


@dataclass
class _Reader:
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
        return [{"rate": rate, "curve": self.curve(lcid, "same", fld)} for rate, lcid in self.tables[int(tbid)]]  # type: ignore[call-overload]

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
        name = info[0] if info and info[1] == role else f"curve-{lcid}" + ("" if role in ("same", "time") else f"-{role}")
        while name in self.curves and name not in self.made.values():
            name += "-2"
        self.curves[name] = {"x": xs, "y": ys}
        self.made[key] = name
        return name


def import_deck(path: str, skip_unsupported: bool = False) -> tuple[dict[str, Any], list[str]]:
    """The model (as YAML data) of the deck at ``path`` and the notes for the user (skipped keywords).

    Raises :class:`InputError` with every problem found (file, line, keyword, field)."""
    deck = read_deck(path)
    notes: list[str] = []
    meta = _meta(deck.meta, notes)
    other = [b for b in deck.blocks if not supported(b.keyword)]
    if other:
        listed = [f"{b.file}:{b.line}: *{b.keyword}" for b in other]
        if not skip_unsupported:
            raise InputError([b.problem("keyword not supported by crashstudy import (it has no model equivalent); "
                                        "remove it or pass --skip-unsupported to skip it") for b in other])  # fmt: skip
        notes.append("skipped unsupported keywords:\n  " + "\n  ".join(listed))
    r = _Reader(meta, exact={float(w): float(x) for w, x in meta.get("exact", [])})
    by: dict[str, list[Block]] = {}
    for b in deck.blocks:
        if supported(b.keyword):
            by.setdefault(b.keyword, []).append(b)
    rows = {k: [(b, c, f) for b in by.get(k, []) for c in b.cards if (f := r.fields(b, c, k)) is not None]
            for k in SIMPLE}  # fmt: skip
    _read_curves(r, by)
    model: dict[str, Any] = {"name": "", "description": meta.get("description", ""), "units": "SI"}
    _title(model, by, meta, Path(path), notes)
    nodes, nid_name, dim = _nodes(r, rows, meta)
    model["curves"] = r.curves
    model["nodes"] = nodes
    model["springs"] = _springs(r, by, rows, nid_name, meta)
    _boundary(r, model, rows, by, nid_name, dim)
    _walls(r, model, by, nid_name, dim, meta)
    _controls(r, model, by, rows, meta, path)
    if r.problems:
        raise InputError(sorted(r.problems, key=lambda p: (p.file, p.line or 0)))
    return {k: v for k, v in model.items() if v not in ({}, [], None) or k in ("nodes",)}, notes


def _meta(text: str, notes: list[str]) -> dict[str, Any]:
    """The ``$crashstudy:`` record, or ``{}`` when absent or not of the shape export writes (ids from numbers)."""
    if not text:
        return {}
    try:
        meta = json.loads(text)
        shapes = {"name": str, "description": str, "units": str, "nodes": list, "springs": list, "walls": list,
                  "curves": dict, "time_step": dict, "output": dict, "termination": dict, "metrics": list,
                  "accuracy_check": bool, "exact": list}  # fmt: skip
        ok = isinstance(meta, dict) and all(isinstance(meta[k], t) for k, t in shapes.items() if k in meta)
        ok = ok and all(isinstance(n, str) for k in ("nodes", "springs") for n in meta.get(k, []))
        ok = ok and all(isinstance(w, list) and len(w) == 2 and isinstance(w[0], str) for w in meta.get("walls", []))
        ok = ok and all(isinstance(p, list) and len(p) == 2 and all(isinstance(v, float) for v in p)
                        for p in meta.get("exact", []))  # fmt: skip
        ok = ok and all(isinstance(c, list) and len(c) == 4 and [type(v) for v in c] == [str, str, int, int]
                        for c in meta.get("curves", {}).values())  # fmt: skip
    except (json.JSONDecodeError, AttributeError, TypeError):
        ok = False
    if not ok:
        notes.append("the deck's $crashstudy: comment lines are damaged: ignored (ids made from the deck's numbers)")
        return {}
    return dict(meta)


def _title(model: dict[str, Any], by: dict[str, list[Block]], meta: dict[str, Any], path: Path, notes: list[str]) -> None:
    title = by["TITLE"][0].cards[0].text.strip() if by.get("TITLE") and by["TITLE"][0].cards else ""
    name = meta.get("name") or re.sub(r"[^A-Za-z0-9_-]+", "-", re.split(r"[(,]", title)[0].strip() or path.stem)
    model["name"] = name.strip("-")[:64] or "imported"
    if not meta and title:
        model["description"] = title
    units = meta.get("units") or next((u for u in UNIT_SYSTEMS if re.search(rf"\b{re.escape(u)}\b", title)), None)
    if units is None:
        notes.append(f"no unit system named in *TITLE ({title!r}): the model says units: SI; if the deck uses "
                     f"another consistent system ({', '.join(UNIT_SYSTEMS)}), change units: in the model")  # fmt: skip
    model["units"] = units or "SI"


def _read_curves(r: _Reader, by: dict[str, list[Block]]) -> None:
    for b in by.get("DEFINE_CURVE", []) + by.get("DEFINE_CURVE_TITLE", []):
        cards = b.cards[1:] if b.keyword.endswith("_TITLE") else b.cards
        if not cards:
            r.fail(b, "no header card (LCID SIDR SFA SFO OFFA OFFO DATTYP LCINT)")
            continue
        h = r.fields(b, cards[0], "DEFINE_CURVE")
        pts = [p for c in cards[1:] if (p := r.fields(b, c, "DEFINE_CURVE_POINT")) is not None]
        if h is None:
            continue
        if h["LCID"] is None or h["DATTYP"] not in (None, 0) or len(pts) < 2:
            r.fail(b, "expected an LCID, DATTYP 0 (or blank) and at least two points (A, O)", cards[0])
            continue
        sfa = 1.0 if not h["SFA"] else float(h["SFA"])  # type: ignore[arg-type]
        sfo = 1.0 if not h["SFO"] else float(h["SFO"])  # type: ignore[arg-type]
        offa, offo = float(h["OFFA"] or 0.0), float(h["OFFO"] or 0.0)  # type: ignore[arg-type]
        xs = [sfa * float(p["A"] or 0.0) + offa for p in pts]  # type: ignore[arg-type]
        ys = [sfo * float(p["O"] or 0.0) + offo for p in pts]  # type: ignore[arg-type]
        lcid = int(h["LCID"])  # type: ignore[call-overload]
        if lcid in r.curves_raw:
            r.fail(b, f"curve {lcid} is defined twice (also at {r.curves_raw[lcid][0].file}:{r.curves_raw[lcid][0].line})",
                   cards[0], "LCID")  # fmt: skip
        r.curves_raw[lcid] = (b, xs, ys)
    for b in by.get("DEFINE_TABLE", []):
        h = r.fields(b, b.cards[0], "DEFINE_TABLE") if b.cards else None
        if h is None or h["TBID"] is None:
            r.fail(b, "expected a TBID card")
            continue
        rows = [f for c in b.cards[1:] if (f := r.fields(b, c, "DEFINE_TABLE_ROW")) is not None]
        r.tables[int(h["TBID"])] = [(float(f["VALUE"] or 0.0), int(f["LCID"] or 0)) for f in rows]  # type: ignore[arg-type, call-overload]


def _nodes(r: _Reader, rows: dict[str, list[tuple[Block, Card, dict[str, object]]]], meta: dict[str, Any]
           ) -> tuple[dict[str, dict[str, Any]], dict[int, str], int]:  # fmt: skip
    names = meta.get("nodes") or []
    found = [(b, c, f) for b, c, f in rows["NODE"] if f["NID"] is not None]
    seen: dict[object, Card] = {}
    for b, c, f in rows["NODE"]:
        if f["NID"] is None or f["NID"] in seen:
            r.fail(b, "NID is blank" if f["NID"] is None else f"node {f['NID']} is defined twice (also at line "
                   f"{seen[f['NID']].line} of {seen[f['NID']].file})", c, "NID")  # fmt: skip
        seen.setdefault(f["NID"], c)
    use_meta = len(names) == len(found) and sorted(int(f["NID"]) for _, _, f in found) == list(range(1, len(found) + 1))  # type: ignore[call-overload]
    nid_name = {int(f["NID"]): (names[int(f["NID"]) - 1] if use_meta else f"n{f['NID']}") for _, _, f in found}  # type: ignore[call-overload]
    xyz = {int(f["NID"]): [float(f[k] or 0.0) for k in ("X", "Y", "Z")] for _, _, f in found}  # type: ignore[call-overload, arg-type]
    held_dirs: dict[int, set[str]] = {n: set() for n in xyz}  # translations held: *NODE TC (1 x, 2 y, 3 z, 4 xy, 5 yz, 6 zx, 7 all), SPCs
    for b, c, f in found:
        held_dirs[int(f["NID"])] |= set(TC_CODES.get(int(f["TC"] or 0), ""))  # type: ignore[call-overload]
        if f["TC"] and int(f["TC"]) not in TC_CODES:  # type: ignore[call-overload]
            r.fail(b, f"TC = {f['TC']}: expected 0 to 7", c, "TC")
    for b, c, f in rows["BOUNDARY_SPC_NODE"]:
        n = int(f["NID"] or 0)  # type: ignore[call-overload]
        if n not in held_dirs or f["CID"]:
            r.fail(b, f"NID {n}, CID {f['CID']}: expected a node of the deck and CID 0 (global axes)", c, "NID")
            continue
        held_dirs[n] |= {a for a, k in (("x", "DOFX"), ("y", "DOFY"), ("z", "DOFZ")) if f[k]}
    held = {n: ("y" in d, "z" in d) for n, d in held_dirs.items()}
    if not all(p[2] == 0.0 and held[n][1] for n, p in xyz.items()):
        bad = next(n for n, p in xyz.items() if not (p[2] == 0.0 and held[n][1]))
        b, c, _ = next(t for t in found if t[2]["NID"] == bad)
        r.fail(b, f"node {bad}: crashstudy models are 1-D (along x) or 2-D (x-y plane): every node needs z = 0 and "
               "its z direction held by *BOUNDARY_SPC_NODE (DOFZ = 1)", c, "Z")  # fmt: skip
    dim = 1 if xyz and all(p[1] == 0.0 and held[n][0] for n, p in xyz.items()) else 2
    mass: dict[int, float] = {}
    for b, c, f in rows["ELEMENT_MASS"]:
        n = int(f["NID"] or 0)  # type: ignore[call-overload]
        if n not in nid_name:
            r.fail(b, f"NID {n}: no such node", c, "NID")
        mass[n] = mass.get(n, 0.0) + float(f["MASS"] or 0.0)  # type: ignore[arg-type]
    nodes: dict[str, dict[str, Any]] = {}
    for n, p in xyz.items():
        fixed = [a for a in "xy"[:dim] if a in held_dirs[n]]
        node: dict[str, Any] = {"position": p[:dim]}
        if n in mass:
            node["mass"] = mass[n]
        if fixed:
            node["fixed"] = True if len(fixed) == dim else fixed
        nodes[nid_name[n]] = node
    return nodes, nid_name, dim


def _springs(r: _Reader, by: dict[str, list[Block]], rows: dict[str, list[tuple[Block, Card, dict[str, object]]]],
             nid_name: dict[int, str], meta: dict[str, Any]) -> dict[str, dict[str, Any]]:  # fmt: skip
    parts: dict[int, tuple[str, dict[str, object]]] = {}
    for b in by.get("PART", []):
        for head, c in zip(b.cards[::2], b.cards[1::2], strict=False):
            f = r.fields(b, c, "PART")
            if f is not None and f["PID"] is not None:
                parts[int(f["PID"])] = (head.text.strip(), f)  # type: ignore[call-overload]
        if len(b.cards) % 2:
            r.fail(b, "a *PART has two cards: the heading and PID SECID MID ...", b.cards[-1])
    sections: dict[int, tuple[Block, Card]] = {}
    for b in by.get("SECTION_DISCRETE", []):
        if len(b.cards) % 2:
            r.fail(b, "*SECTION_DISCRETE has two cards (SECID DRO KD V0 CL FD, then CDL TDL): the second is "
                   "missing; LS-DYNA would read the next keyword's line or zeros", b.cards[-1])  # fmt: skip
        for c1, c2 in zip(b.cards[::2], b.cards[1::2], strict=False):
            f1, f2 = r.fields(b, c1, "SECTION_DISCRETE"), r.fields(b, c2, "SECTION_DISCRETE_2")
            if f1 is None or f2 is None:
                continue
            odd = [k for k in ("DRO", "KD", "V0", "CL", "FD") if f1[k]] + [k for k in ("CDL", "TDL") if f2[k]]
            if odd:
                r.fail(b, f"{', '.join(odd)} must be 0 or blank: crashstudy springs are translational (DRO 0) with no "
                       "dynamic magnification, clearance, failure deflection or displacement limits", c1, odd[0])  # fmt: skip
            sections[int(f1["SECID"] or 0)] = (b, c1)  # type: ignore[call-overload]
    mats: dict[int, tuple[Block, Card, dict[str, Any] | None]] = {}
    for kw in [k for k in by if _material_keyword(k)[0]]:
        base, titled = _material_keyword(kw)
        for b in by[kw]:
            cards = b.cards[1:] if titled else b.cards
            if len(cards) != 1:
                r.fail(b, f"expected one card after the keyword{' and title' if titled else ''}, found {len(cards)}")
                continue
            f = r.fields(b, cards[0], base)
            if f is None:
                continue
            r.where = (b, cards[0])
            row = next((m for m in MATERIALS if m.keyword == base and m.claims(f, r)), None)
            if row is None:
                r.fail(b, WHY_NOT.get(base, "these fields have no crashstudy material"), cards[0])
                continue
            mats[int(f["MID"] or 0)] = (b, cards[0], row.read(f, r))  # type: ignore[call-overload]
    names = meta.get("springs") or []
    elems = [(b, c, f) for b, c, f in rows["ELEMENT_DISCRETE"]]
    eids = [f["EID"] for _, _, f in elems]
    for b, c, f in elems:
        if f["EID"] is None or eids.count(f["EID"]) > 1:
            r.fail(b, "EID is blank" if f["EID"] is None else f"element {f['EID']} is defined twice", c, "EID")
    use_meta = len(names) == len(elems) and [f["EID"] for _, _, f in elems] == list(range(1, len(elems) + 1))
    springs: dict[str, dict[str, Any]] = {}
    for k, (b, c, f) in enumerate(elems):
        pid = int(f["PID"] or 0)  # type: ignore[call-overload]
        sid = names[k] if use_meta else f"s{f['EID']}"
        if pid not in parts:
            r.fail(b, f"PID {pid}: no *PART with this id", c, "PID")
            continue
        _, pf = parts[pid]
        mid, secid = int(pf["MID"] or 0), int(pf["SECID"] or 0)  # type: ignore[call-overload]
        if secid not in sections:
            r.fail(b, f"part {pid} names SECID {secid}: no *SECTION_DISCRETE with this id", c, "PID")
        if mid not in mats or mats[mid][2] is None:
            r.fail(b, f"part {pid} names MID {mid}: no supported spring or damper material with this id", c, "PID")
            continue
        n1, n2 = int(f["N1"] or 0), int(f["N2"] or 0)  # type: ignore[call-overload]
        if n1 not in nid_name or n2 not in nid_name:
            r.fail(b, f"N1 {n1}, N2 {n2}: both must be nodes of the deck", c, "N1")
            continue
        scale = f["S"]
        if scale is None or float(scale) != 1.0 or (f["VID"] or 0) != 0:  # type: ignore[arg-type]
            r.fail(b, f"S must be 1.0 (a blank S reads as 0 in LS-DYNA, a spring with no force) and VID 0 (along "
                   f"the nodes' axis); got S = {scale}, VID = {f['VID']}", c, "S")  # fmt: skip
        spring: dict[str, Any] = {"nodes": [nid_name[n1], nid_name[n2]], "material": mats[mid][2]}
        if f["OFFSET"]:
            spring["initial_elongation"] = float(f["OFFSET"])  # type: ignore[arg-type]
        springs[sid] = spring
    return springs


def _boundary(r: _Reader, model: dict[str, Any], rows: dict[str, list[tuple[Block, Card, dict[str, object]]]],
              by: dict[str, list[Block]], nid_name: dict[int, str], dim: int) -> None:  # fmt: skip
    iv = {}
    for b, c, f in rows["INITIAL_VELOCITY_NODE"]:
        n = int(f["NID"] or 0)  # type: ignore[call-overload]
        if n not in nid_name:
            r.fail(b, f"NID {n}: no such node", c, "NID")
            continue
        iv[nid_name[n]] = [float(f[k] or 0.0) for k in ("VX", "VY")][:dim]  # type: ignore[arg-type]
    model["initial_velocity"] = iv
    loads: dict[tuple[int, int], list[float]] = {}
    for b, c, f in rows["LOAD_NODE_POINT"]:
        n, dof, lc = int(f["NID"] or 0), int(f["DOF"] or 0), int(f["LCID"] or 0)  # type: ignore[call-overload]
        if n not in nid_name or dof not in (1, 2)[:dim] or f["CID"] or lc == 0:
            r.fail(b, f"expected a node, DOF 1{' or 2' if dim == 2 else ''}, a load curve and CID 0; got NID {n}, "
                   f"DOF {dof}, LCID {lc}", c, "DOF")  # fmt: skip
            continue
        loads.setdefault((n, lc), [0.0] * dim)[dof - 1] += float(f["SF"] if f["SF"] is not None else 1.0)  # type: ignore[arg-type]
    model["loads"] = []
    for (n, lc), force in loads.items():
        info = r.meta.get("curves", {}).get(str(lc))
        r.where = (by["LOAD_NODE_POINT"][0], None)
        ld: dict[str, Any] = {"node": nid_name[n], "force": force}
        if not (info and info[1] == "constant"):
            ld["curve"] = r.curve(lc, "time", "LCID")
        model["loads"].append(ld)
    gravity = [0.0] * dim
    for k, axis in enumerate("XYZ"):
        for b in by.get(f"LOAD_BODY_{axis}", []):
            body = r.fields(b, b.cards[0], "LOAD_BODY") if b.cards else None
            if body is None:
                continue
            f = body
            lc = int(f["LCID"] or 0)  # type: ignore[call-overload]
            ys = r.curves_raw.get(lc, (b, [], []))[2]
            if k >= dim or not ys or min(ys) != max(ys) or any(f[x] for x in ("LCIDDR", "CID")):
                r.fail(b, "a body load must be constant in time (gravity) along a direction the model uses", b.cards[0])
                continue
            gravity[k] = -float(f["SF"] if f["SF"] is not None else 1.0) * ys[0]  # type: ignore[arg-type]
    if any(gravity):
        model["gravity"] = gravity
    motion = []
    for b, c, f in rows["BOUNDARY_PRESCRIBED_MOTION_NODE"]:
        n, dof, vad = int(f["NID"] or 0), int(f["DOF"] or 0), int(f["VAD"] or 0)  # type: ignore[call-overload]
        limits = [float(f[k]) for k in ("BIRTH", "DEATH") if f[k] is not None]  # type: ignore[arg-type]
        if n not in nid_name or dof not in (1, 2)[:dim] or vad not in (0, 1, 2) or f["VID"] or \
                any(0.0 < abs(v) < NEVER_TIME for v in limits):  # fmt: skip
            r.fail(b, f"expected a node, DOF 1{' or 2' if dim == 2 else ''}, VAD 0 (velocity), 1 (acceleration) or 2 "
                   "(displacement), VID 0 and no BIRTH/DEATH times", c, "DOF")  # fmt: skip
            continue
        r.where = (b, c)
        motion.append({"node": nid_name[n], "quantity": ("velocity", "acceleration", "displacement")[vad],
                       "direction": "xy"[dof - 1], "curve": r.curve(f["LCID"], "time", "LCID"),
                       "scale": float(f["SF"] if f["SF"] is not None else 1.0)})  # type: ignore[arg-type]  # fmt: skip
    model["prescribed_motion"] = motion


def _walls(r: _Reader, model: dict[str, Any], by: dict[str, list[Block]], nid_name: dict[int, str], dim: int,
           meta: dict[str, Any]) -> None:  # fmt: skip
    sets: dict[int, list[int]] = {}
    for b in by.get("SET_NODE_LIST", []):
        h = r.fields(b, b.cards[0], "SET_NODE_LIST") if b.cards else None
        if h is not None:
            sets[int(h["SID"] or 0)] = [int(v) for c in b.cards[1:] if (f := r.fields(b, c, "SET_NODE_LIST_IDS"))  # type: ignore[call-overload]
                                        for v in f.values() if v]  # fmt: skip
    known = {w[0]: w[1] for w in meta.get("walls", [])}
    walls: list[dict[str, Any]] = []
    for b in by.get("RIGIDWALL_PLANAR", []) + by.get("RIGIDWALL_PLANAR_ID", []):
        cards = b.cards
        wid = f"wall-{len(walls) + 1}"
        if b.keyword.endswith("_ID") and cards:
            h = r.fields(b, cards[0], "RIGIDWALL_ID")
            wid = str(h["TITLE"]).strip() if h and h["TITLE"] else f"wall-{h['ID'] if h else len(walls) + 1}"
            cards = cards[1:]
        if len(cards) != 2:
            r.fail(b, f"expected two cards (NSID ... RWKSF, then XT ... WVEL), found {len(cards)}")
            continue
        f1, f2 = r.fields(b, cards[0], "RIGIDWALL_PLANAR"), r.fields(b, cards[1], "RIGIDWALL_PLANAR_2")
        if f1 is None or f2 is None:
            continue
        odd = [k for k in ("NSIDEX", "BOXID", "OFFSET", "RWKSF") if f1[k]] + [k for k in ("FRIC", "WVEL") if f2[k]]
        odd += [k for k in ("BIRTH", "DEATH") if f1[k] and abs(float(f1[k])) < NEVER_TIME]  # type: ignore[arg-type]
        tail = [float(f2[k] or 0.0) for k in ("XT", "YT", "ZT")]  # type: ignore[arg-type]
        normal = [float(f2[k] or 0.0) - t for k, t in zip(("XH", "YH", "ZH"), tail, strict=True)]  # type: ignore[arg-type]
        if odd or tail[2] != 0.0 or normal[2] != 0.0 or (dim == 1 and (tail[1] or normal[1])):
            r.fail(b, "crashstudy walls are stonewalls in the model's plane: NSIDEX, BOXID, OFFSET, RWKSF, FRIC, "
                   "WVEL, BIRTH and DEATH blank or 0, z components 0" + (f" (found {', '.join(odd)})" if odd else ""),
                   cards[0])  # fmt: skip
            continue
        exact = known.get(wid)
        if exact is not None and len(exact) == dim and all(abs(a - b2) <= 1e-9 * max(1.0, abs(b2))
                                                           for a, b2 in zip(normal, exact, strict=False)):  # fmt: skip
            normal = list(exact)
        wall: dict[str, Any] = {"id": wid, "point": tail[:dim], "normal": normal[:dim]}
        nsid = int(f1["NSID"] or 0)  # type: ignore[call-overload]
        if nsid:
            if nsid not in sets or any(n not in nid_name for n in sets[nsid]):
                r.fail(b, f"NSID {nsid}: no *SET_NODE_LIST of deck nodes with this id", cards[0], "NSID")
                continue
            wall["nodes"] = [nid_name[n] for n in sets[nsid]]
        walls.append(wall)
    model["rigid_walls"] = walls


def _controls(r: _Reader, model: dict[str, Any], by: dict[str, list[Block]],
              rows: dict[str, list[tuple[Block, Card, dict[str, object]]]], meta: dict[str, Any], path: str) -> None:  # fmt: skip
    ends = [f["ENDTIM"] for _, _, f in rows["CONTROL_TERMINATION"] if f["ENDTIM"]]
    if not ends:
        r.problems.append(Problem(path, None, "*CONTROL_TERMINATION", "no ENDTIM: the deck must give the end time"))
    else:
        model["end_time"] = float(ends[-1])  # type: ignore[arg-type]
    if "time_step" in meta:
        model["time_step"] = meta["time_step"]
    else:
        ts = [f for _, _, f in rows["CONTROL_TIMESTEP"] if f["TSSFAC"]]
        if ts and 0.0 < float(ts[-1]["TSSFAC"]) <= 1.0:  # type: ignore[arg-type]
            model["time_step"] = {"safety_factor": float(ts[-1]["TSSFAC"])}  # type: ignore[arg-type]
    if "output" in meta:
        model["output"] = meta["output"]
    else:
        dts = [f["DT"] for b in by.get("DATABASE_NODOUT", []) if b.cards and (f := r.fields(b, b.cards[0], "DATABASE"))]
        if dts and dts[0]:
            model["output"] = {"interval": float(dts[0])}  # type: ignore[arg-type]
    for key in ("termination", "metrics", "accuracy_check"):
        if meta.get(key) not in (None, [], False):
            model[key] = meta[key]
