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
from pathlib import Path
from typing import Any

from crashstudy.errors import InputError
from crashstudy.exchange.dyna_boundary import read_boundary, read_controls, read_walls
from crashstudy.exchange.dyna_deck import Block, Card, read_deck
from crashstudy.exchange.dyna_materials import ALIASES, KEYWORDS, MATERIALS, WHY_NOT
from crashstudy.exchange.dyna_reader import DeckReader, Rows
from crashstudy.units import UNIT_SYSTEMS

SIMPLE = {
    "CONTROL_TERMINATION",
    "CONTROL_TIMESTEP",
    "NODE",
    "ELEMENT_MASS",
    "ELEMENT_DISCRETE",
    "INITIAL_VELOCITY_NODE",
    "BOUNDARY_SPC_NODE",
    "BOUNDARY_PRESCRIBED_MOTION_NODE",
    "LOAD_NODE_POINT",
    "DATABASE_HISTORY_NODE",
}
OTHER = {
    "KEYWORD",
    "TITLE",
    "PART",
    "SECTION_DISCRETE",
    "DEFINE_CURVE",
    "DEFINE_CURVE_TITLE",
    "DEFINE_TABLE",
    "LOAD_BODY_X",
    "LOAD_BODY_Y",
    "LOAD_BODY_Z",
    "RIGIDWALL_PLANAR",
    "RIGIDWALL_PLANAR_ID",
    "SET_NODE_LIST",
    "DATABASE_NODOUT",
    "DATABASE_DEFORC",
    "DATABASE_GLSTAT",
}
TC_CODES = {
    0: "",
    1: "x",
    2: "y",
    3: "z",
    4: "xy",
    5: "yz",
    6: "zx",
    7: "xyz",
}  #: *NODE TC: translations held


def _material_keyword(name: str) -> tuple[str, bool]:
    """``(canonical keyword, has a title card)`` of a material keyword name, or ``("", False)``."""
    titled = name.endswith("_TITLE")
    base = ALIASES.get(name[:-6] if titled else name, name[:-6] if titled else name)
    return (base, titled) if base in KEYWORDS else ("", False)


def supported(name: str) -> bool:
    return name in SIMPLE or name in OTHER or bool(_material_keyword(name)[0])


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
            raise InputError(
                [
                    b.problem(
                        "keyword not supported by crashstudy import (it has no model equivalent); "
                        "remove it or pass --skip-unsupported to skip it"
                    )
                    for b in other
                ]
            )
        notes.append("skipped unsupported keywords:\n  " + "\n  ".join(listed))
    r = DeckReader(meta, exact={float(w): float(x) for w, x in meta.get("exact", [])})
    by: dict[str, list[Block]] = {}
    for b in deck.blocks:
        if supported(b.keyword):
            by.setdefault(b.keyword, []).append(b)
    rows = {
        k: [(b, c, f) for b in by.get(k, []) for c in b.cards if (f := r.fields(b, c, k)) is not None]
        for k in SIMPLE
    }
    _read_curves(r, by)
    model: dict[str, Any] = {"name": "", "description": meta.get("description", ""), "units": "SI"}
    _title(model, by, meta, Path(path), notes)
    nodes, nid_name, dim = _nodes(r, rows, meta)
    model["curves"] = r.curves
    model["nodes"] = nodes
    model["springs"] = _springs(r, by, rows, nid_name, meta)
    read_boundary(r, model, rows, by, nid_name, dim)
    read_walls(r, model, by, nid_name, dim, meta)
    read_controls(r, model, by, rows, meta, path)
    if r.problems:
        raise InputError(sorted(r.problems, key=lambda p: (p.file, p.line or 0)))
    return {k: v for k, v in model.items() if v not in ({}, [], None) or k in ("nodes",)}, notes


def _meta(text: str, notes: list[str]) -> dict[str, Any]:
    """The ``$crashstudy:`` record, or ``{}`` when absent or not of the shape export writes (ids from numbers)."""
    if not text:
        return {}
    try:
        meta = json.loads(text)
        shapes = {
            "name": str,
            "description": str,
            "units": str,
            "nodes": list,
            "springs": list,
            "walls": list,
            "curves": dict,
            "time_step": dict,
            "output": dict,
            "termination": dict,
            "metrics": list,
            "accuracy_check": bool,
            "exact": list,
        }
        ok = isinstance(meta, dict) and all(isinstance(meta[k], t) for k, t in shapes.items() if k in meta)
        ok = ok and all(isinstance(n, str) for k in ("nodes", "springs") for n in meta.get(k, []))
        ok = ok and all(
            isinstance(w, list) and len(w) == 2 and isinstance(w[0], str) for w in meta.get("walls", [])
        )
        ok = ok and all(
            isinstance(p, list) and len(p) == 2 and all(isinstance(v, float) for v in p)
            for p in meta.get("exact", [])
        )
        ok = ok and all(
            isinstance(c, list) and len(c) == 4 and [type(v) for v in c] == [str, str, int, int]
            for c in meta.get("curves", {}).values()
        )
    except (json.JSONDecodeError, AttributeError, TypeError):
        ok = False
    if not ok:
        notes.append(
            "the deck's $crashstudy: comment lines are damaged: ignored (ids made from the deck's numbers)"
        )
        return {}
    return dict(meta)


def _title(
    model: dict[str, Any], by: dict[str, list[Block]], meta: dict[str, Any], path: Path, notes: list[str]
) -> None:
    title = by["TITLE"][0].cards[0].text.strip() if by.get("TITLE") and by["TITLE"][0].cards else ""
    name = meta.get("name") or re.sub(
        r"[^A-Za-z0-9_-]+", "-", re.split(r"[(,]", title)[0].strip() or path.stem
    )
    model["name"] = name.strip("-")[:64] or "imported"
    if not meta and title:
        model["description"] = title
    units = meta.get("units") or next(
        (u for u in UNIT_SYSTEMS if re.search(rf"\b{re.escape(u)}\b", title)), None
    )
    if units is None:
        notes.append(
            f"no unit system named in *TITLE ({title!r}): the model says units: SI; if the deck uses "
            f"another consistent system ({', '.join(UNIT_SYSTEMS)}), change units: in the model"
        )
    model["units"] = units or "SI"


def _read_curves(r: DeckReader, by: dict[str, list[Block]]) -> None:
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
            r.fail(
                b,
                f"curve {lcid} is defined twice (also at {r.curves_raw[lcid][0].file}:{r.curves_raw[lcid][0].line})",
                cards[0],
                "LCID",
            )
        r.curves_raw[lcid] = (b, xs, ys)
    for b in by.get("DEFINE_TABLE", []):
        h = r.fields(b, b.cards[0], "DEFINE_TABLE") if b.cards else None
        if h is None or h["TBID"] is None:
            r.fail(b, "expected a TBID card")
            continue
        rows = [f for c in b.cards[1:] if (f := r.fields(b, c, "DEFINE_TABLE_ROW")) is not None]
        r.tables[int(h["TBID"])] = [(float(f["VALUE"] or 0.0), int(f["LCID"] or 0)) for f in rows]  # type: ignore[arg-type, call-overload]


def _nodes(
    r: DeckReader, rows: Rows, meta: dict[str, Any]
) -> tuple[dict[str, dict[str, Any]], dict[int, str], int]:
    names = meta.get("nodes") or []
    found = [(b, c, f) for b, c, f in rows["NODE"] if f["NID"] is not None]
    seen: dict[object, Card] = {}
    for b, c, f in rows["NODE"]:
        if f["NID"] is None or f["NID"] in seen:
            r.fail(
                b,
                "NID is blank"
                if f["NID"] is None
                else f"node {f['NID']} is defined twice (also at line "
                f"{seen[f['NID']].line} of {seen[f['NID']].file})",
                c,
                "NID",
            )
        seen.setdefault(f["NID"], c)
    nids = [int(f["NID"]) for _, _, f in found]  # type: ignore[call-overload]
    use_meta = len(names) == len(found) and sorted(nids) == list(range(1, len(found) + 1))
    nid_name = {
        n: (names[n - 1] if use_meta else f"n{f['NID']}") for n, (_, _, f) in zip(nids, found, strict=True)
    }
    xyz = {int(f["NID"]): [float(f[k] or 0.0) for k in ("X", "Y", "Z")] for _, _, f in found}  # type: ignore[call-overload, arg-type]
    held_dirs: dict[int, set[str]] = {
        n: set() for n in xyz
    }  # translations held: *NODE TC (1 x, 2 y, 3 z, 4 xy, 5 yz, 6 zx, 7 all), SPCs
    for b, c, f in found:
        held_dirs[int(f["NID"])] |= set(TC_CODES.get(int(f["TC"] or 0), ""))  # type: ignore[call-overload]
        if f["TC"] and int(f["TC"]) not in TC_CODES:  # type: ignore[call-overload]
            r.fail(b, f"TC = {f['TC']}: expected 0 to 7", c, "TC")
    for b, c, f in rows["BOUNDARY_SPC_NODE"]:
        n = int(f["NID"] or 0)  # type: ignore[call-overload]
        if n not in held_dirs or f["CID"]:
            r.fail(
                b, f"NID {n}, CID {f['CID']}: expected a node of the deck and CID 0 (global axes)", c, "NID"
            )
            continue
        held_dirs[n] |= {a for a, k in (("x", "DOFX"), ("y", "DOFY"), ("z", "DOFZ")) if f[k]}
    held = {n: ("y" in d, "z" in d) for n, d in held_dirs.items()}
    if not all(p[2] == 0.0 and held[n][1] for n, p in xyz.items()):
        bad = next(n for n, p in xyz.items() if not (p[2] == 0.0 and held[n][1]))
        b, c, _ = next(t for t in found if t[2]["NID"] == bad)
        r.fail(
            b,
            f"node {bad}: crashstudy models are 1-D (along x) or 2-D (x-y plane): every node needs z = 0 and "
            "its z direction held by *BOUNDARY_SPC_NODE (DOFZ = 1)",
            c,
            "Z",
        )
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


def _springs(
    r: DeckReader, by: dict[str, list[Block]], rows: Rows, nid_name: dict[int, str], meta: dict[str, Any]
) -> dict[str, dict[str, Any]]:
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
            r.fail(
                b,
                "*SECTION_DISCRETE has two cards (SECID DRO KD V0 CL FD, then CDL TDL): the second is "
                "missing; LS-DYNA would read the next keyword's line or zeros",
                b.cards[-1],
            )
        for c1, c2 in zip(b.cards[::2], b.cards[1::2], strict=False):
            f1, f2 = r.fields(b, c1, "SECTION_DISCRETE"), r.fields(b, c2, "SECTION_DISCRETE_2")
            if f1 is None or f2 is None:
                continue
            odd = [k for k in ("DRO", "KD", "V0", "CL", "FD") if f1[k]] + [k for k in ("CDL", "TDL") if f2[k]]
            if odd:
                r.fail(
                    b,
                    f"{', '.join(odd)} must be 0 or blank: crashstudy springs are translational (DRO 0) with no "
                    "dynamic magnification, clearance, failure deflection or displacement limits",
                    c1,
                    odd[0],
                )
            sections[int(f1["SECID"] or 0)] = (b, c1)  # type: ignore[call-overload]
    mats: dict[int, tuple[Block, Card, dict[str, Any] | None]] = {}
    for kw in [k for k in by if _material_keyword(k)[0]]:
        base, titled = _material_keyword(kw)
        for b in by[kw]:
            cards = b.cards[1:] if titled else b.cards
            if len(cards) != 1:
                r.fail(
                    b,
                    f"expected one card after the keyword{' and title' if titled else ''}, found {len(cards)}",
                )
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
            r.fail(
                b, "EID is blank" if f["EID"] is None else f"element {f['EID']} is defined twice", c, "EID"
            )
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
            r.fail(
                b,
                f"part {pid} names MID {mid}: no supported spring or damper material with this id",
                c,
                "PID",
            )
            continue
        n1, n2 = int(f["N1"] or 0), int(f["N2"] or 0)  # type: ignore[call-overload]
        if n1 not in nid_name or n2 not in nid_name:
            r.fail(b, f"N1 {n1}, N2 {n2}: both must be nodes of the deck", c, "N1")
            continue
        scale = f["S"]
        if scale is None or float(scale) != 1.0 or (f["VID"] or 0) != 0:  # type: ignore[arg-type]
            r.fail(
                b,
                f"S must be 1.0 (a blank S reads as 0 in LS-DYNA, a spring with no force) and VID 0 (along "
                f"the nodes' axis); got S = {scale}, VID = {f['VID']}",
                c,
                "S",
            )
        spring: dict[str, Any] = {"nodes": [nid_name[n1], nid_name[n2]], "material": mats[mid][2]}
        if f["OFFSET"]:
            spring["initial_elongation"] = float(f["OFFSET"])  # type: ignore[arg-type]
        springs[sid] = spring
    return springs
