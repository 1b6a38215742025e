"""LS-DYNA keyword decks (SPEC 8c): every card of our decks read back by an independent parser (dynars'
built-in keyword library), and the *DEFINE_TABLE helpers of rate curves.

Truth: dynars' reading of each field (exact: the deck holds the shortest text that reads back as the
value)."""

from __future__ import annotations

import copy
from pathlib import Path
from typing import Any

import pytest

from dyna_models import MATERIAL_MODELS, MODELS, _col, _curve, _deck, load_model_data

# --- every card read back by an independent parser ----------------------------------------------------

MAT_FIELDS = {  # keyword -> material type and {dynars field: expected value of the material}
    "MAT_SPRING_ELASTIC": lambda m: {"K": m["stiffness"]},
    "MAT_DAMPER_VISCOUS": lambda m: {"DC": m["damping"]},
    "MAT_SPRING_ELASTOPLASTIC": lambda m: {
        "K": m["stiffness"],
        "KT": m["tangent_stiffness"],
        "FY": m["yield_force"],
    },
    "MAT_SPRING_GENERAL_NONLINEAR": lambda m: {
        "BETA": 0.0,
        "TYI": m.get("tension_yield", 1.0e30),
        "CYI": m.get("compression_yield", -1.0e30),
    },
    "MAT_SPRING_INELASTIC": lambda m: {"KU": m["unloading_stiffness"], "CTF": 1.0},
    "MAT_SPRING_NONLINEAR_ELASTIC": lambda m: {"LCR": 0},
    "MAT_DAMPER_NONLINEAR_VISCOUS": lambda m: {},
}
KEYWORD_OF = {
    "linear_elastic": "MAT_SPRING_ELASTIC",
    "damper": "MAT_DAMPER_VISCOUS",
    "elastoplastic": "MAT_SPRING_ELASTOPLASTIC",
    "general_nonlinear": "MAT_SPRING_GENERAL_NONLINEAR",
    "crush": "MAT_SPRING_INELASTIC",
    "nonlinear_elastic": "MAT_SPRING_NONLINEAR_ELASTIC",
    "nonlinear_damper": "MAT_DAMPER_NONLINEAR_VISCOUS",
    "rate_elastic": "MAT_SPRING_NONLINEAR_ELASTIC",
}
CURVE_FIELD = {
    "nonlinear_elastic": [("LCD", "curve")],
    "nonlinear_damper": [("LCDR", "curve")],
    "general_nonlinear": [("LCDL", "loading"), ("LCDU", "unloading")],
    "crush": [("LCFD", "loading")],
}


def _curve_points(deck: Path, headers: bool = True) -> dict[int, tuple[list[float], list[float]]]:
    """Each curve's points as dynars reads them: its header fields, and the (A, O) rows of a one-card
    repeated schema (in which each curve's header line reads as one extra row, dropped here)."""
    import dynars

    d = dynars.parse_deck(str(deck))
    heads = sorted((c.line, c.id) for c in d.curves() if c.keyword.startswith("DEFINE_CURVE"))  # not tables
    rows = d.table_with("DEFINE_CURVE", [[("a", "float", 20, 1), ("o", "float", 20, 1)]], repeat=True)
    a, o = _col(rows, "a"), _col(rows, "o")
    lines = deck.read_text().splitlines()
    counts = []
    for line, _ in heads:  # points of a curve: its non-comment lines up to the next keyword
        body = []
        for text in lines[line:]:
            if text.startswith("*"):
                break
            if not text.startswith("$"):
                body.append(text)
        counts.append(len(body) - 1)
    out, pos = {}, 0
    for (_, lcid), n in zip(heads, counts, strict=True):
        out[lcid] = (a[pos + 1 : pos + 1 + n], o[pos + 1 : pos + 1 + n])
        c = d.curve(lcid)
        if not headers:  # dynars gives no fields for the curves that follow a *DEFINE_TABLE
            pos += n + 1
            continue
        assert (c.field("SFA"), c.field("SFO"), c.field("SIDR")) == (1.0, 1.0, 0)
        assert (c.field("A1"), c.field("O1")) == (out[lcid][0][0], out[lcid][1][0])
        pos += n + 1
    assert pos == len(a)
    return out


def _check_with_dynars(deck: Path, data: dict[str, Any]) -> None:
    import dynars

    from crashstudy.exchange.dyna_materials import crush_curve_out

    d = dynars.parse_deck(str(deck))
    assert d.validate([dynars.Rule.references_resolve(), dynars.Rule.duplicate_ids()]).is_clean
    m = load_model_data(data)
    dim = len(next(iter(m.nodes.values())).position)
    node = d.table("NODE")
    assert _col(node, "nid") == list(range(1, len(m.nodes) + 1))
    for k, axis in enumerate("xyz"):
        assert _col(node, axis) == [([*n.position, 0.0, 0.0])[k] for n in m.nodes.values()]
    mass = d.table("ELEMENT_MASS")
    assert _col(mass, "MASS") == [n.mass for n in m.nodes.values() if n.mass is not None]
    spc = d.table("BOUNDARY_SPC_NODE")
    for i, n in enumerate(m.nodes.values()):
        fixed = {"x", "y"} if n.fixed is True else set() if n.fixed is False else set(n.fixed)
        assert _col(spc, "DOFX")[i] == int("x" in fixed)
        assert _col(spc, "DOFY")[i] == int("y" in fixed or dim == 1)
        assert all(_col(spc, k)[i] == 1 for k in ("DOFZ", "DOFRX", "DOFRY", "DOFRZ"))
    sec = d.table(
        "SECTION_DISCRETE"
    )  # both cards: CDL/TDL read as 0 from the second, not from the next keyword
    assert _col(sec, "SECID") == list(range(1, len(m.springs) + 1))
    assert set(_col(sec, "DRO")) <= {0} and set(_col(sec, "CDL")) <= {0.0} and set(_col(sec, "TDL")) <= {0.0}
    el = d.table("ELEMENT_DISCRETE")
    ids = {n: i + 1 for i, n in enumerate(m.nodes)}
    assert _col(el, "S") == [1.0] * len(m.springs)
    assert _col(el, "OFFSET") == [s.initial_elongation for s in m.springs.values()]
    assert _col(el, "N1") == [ids[s.nodes[0]] for s in m.springs.values()]
    assert _col(el, "N2") == [ids[s.nodes[1]] for s in m.springs.values()]
    points = _curve_points(deck)
    for k, (sid, s) in enumerate(m.springs.items(), start=1):
        mat = s.material.model_dump(exclude_none=True)
        kw = KEYWORD_OF[mat["type"]]
        part = d.part(k)
        assert part.field("HEADING").strip() == sid and part.field("SECID") == k and part.field("MID") == k
        entity = d.material(k)
        assert entity.keyword == kw
        for name, value in MAT_FIELDS[kw](mat).items():
            assert entity.field(name) == value, (sid, name)
        for fld, key in CURVE_FIELD.get(mat["type"], []):
            c = m.curves[mat[key]]
            want = crush_curve_out(list(c.x), list(c.y)) if mat["type"] == "crush" else (list(c.x), list(c.y))
            assert points[entity.field(fld)] == want, (sid, fld)
    assert d.table("CONTROL_TERMINATION")["ENDTIM"].tolist() == [m.end_time]
    for db in ("NODOUT", "DEFORC", "GLSTAT"):
        assert _col(d.table(f"DATABASE_{db}"), "DT") == [m.output.interval or m.end_time / 1000]
    hist = d.table("DATABASE_HISTORY_NODE")
    assert sorted(v for k in hist for v in _col(hist, k) if v) == list(range(1, len(m.nodes) + 1))
    iv = d.table("INITIAL_VELOCITY_NODE")
    moving = {ids[n]: [*v, 0.0][:2] for n, v in m.initial_velocity.items() if any(v)}
    assert dict(zip(_col(iv, "NID"), zip(_col(iv, "VX"), _col(iv, "VY"), strict=True), strict=True)) == {
        k: tuple(v) for k, v in moving.items()
    }
    if m.gravity is not None:
        for k, g in enumerate(m.gravity):
            body = d.table(f"LOAD_BODY_{'XY'[k]}")
            assert _col(body, "SF") == ([-g] if g else [])
    loads = d.table("LOAD_NODE_POINT")
    assert sorted(zip(_col(loads, "NID"), _col(loads, "DOF"), _col(loads, "SF"), strict=True)) == sorted(
        (ids[ld.node], k + 1, f) for ld in m.loads for k, f in enumerate(ld.force) if f
    )
    # dynars' table of these two wants cards we do not write (optional ones, the _ID variant): read each occurrence
    pm = d.keywords("BOUNDARY_PRESCRIBED_MOTION_NODE")
    assert [tuple(kw.field(k) for k in ("NID", "DOF", "VAD", "SF")) for kw in pm] == [
        (
            ids[q.node],
            "xy".index(q.direction) + 1,
            {"velocity": 0, "acceleration": 1, "displacement": 2}[q.quantity],
            q.scale,
        )
        for q in m.prescribed_motion
    ]
    walls = d.keywords("RIGIDWALL_PLANAR")
    assert [kw.field("TITLE") for kw in walls] == [w.id for w in m.rigid_walls]
    sets = d.table("SET_NODE_LIST")
    for kw, w in zip(walls, m.rigid_walls, strict=True):
        p, nv = [*w.point, 0.0][:2], [*w.normal, 0.0][:2]
        assert [kw.field(k) for k in ("XT", "YT", "ZT")] == [*p, 0.0]
        assert [kw.field(k) for k in ("XH", "YH", "ZH")] == [p[0] + nv[0], p[1] + nv[1], 0.0]
        if w.nodes is not None:
            row = _col(sets, "SID").index(kw.field("NSID"))
            assert [v for k in range(1, 9) if (v := _col(sets, f"NID{k}")[row])] == [ids[n] for n in w.nodes]


@pytest.mark.parametrize(
    "case", [*MODELS, *MATERIAL_MODELS], ids=[p.stem for p in MODELS] + list(MATERIAL_MODELS)
)
def test_every_card_of_our_decks_read_back_by_dynars(case: Path | str, tmp_path: Path) -> None:
    pytest.importorskip("dynars")
    deck, data = _deck(case if isinstance(case, Path) else copy.deepcopy(MATERIAL_MODELS[case]), tmp_path)
    _check_with_dynars(deck, data)


def test_define_table_for_rate_curves_written_and_read_back(tmp_path: Path) -> None:
    """The table helpers a rate_elastic row (S04 with a *DEFINE_TABLE) will use: written with its curves
    right after it, read back by dynars and by the importer."""
    import dynars

    from crashstudy.exchange.dyna_deck import read_deck
    from crashstudy.exchange.dyna_export import _Deck
    from crashstudy.exchange.dyna_import import _read_curves
    from crashstudy.exchange.dyna_reader import DeckReader

    m = copy.deepcopy(MATERIAL_MODELS["nonlinear_elastic"])
    m["curves"]["fast"] = _curve([-0.1, 0.0, 0.1], [-3000.0, 0.0, 2500.0])
    d = _Deck(load_model_data(m))
    tbid = d.table([{"rate": 0.0, "curve": "c"}, {"rate": 2.5, "curve": "fast"}])
    deck = tmp_path / "t.k"
    deck.write_text("\n".join(["*KEYWORD", *d.curve_cards, "*END"]) + "\n")
    parsed = dynars.parse_deck(str(deck))
    assert _col(parsed.table("DEFINE_TABLE"), "TBID") == [tbid]
    table = parsed.table_with(
        "DEFINE_TABLE", [[("VALUE", "float", 20, 1), ("LCID", "int", 20, 1)]], repeat=True
    )
    table = {k: _col(table, k)[1:] for k in ("VALUE", "LCID")}  # row 0: the TBID card
    assert table["VALUE"] == [0.0, 2.5]
    assert _curve_points(deck, headers=False)[table["LCID"][1]] == (
        m["curves"]["fast"]["x"],
        m["curves"]["fast"]["y"],
    )
    by: dict[str, list[Any]] = {}
    for b in read_deck(str(deck)).blocks:
        by.setdefault(b.keyword, []).append(b)
    r = DeckReader({})
    _read_curves(r, by)
    assert r.is_table(tbid) and not r.is_table(table["LCID"][0])
    rows = r.table_curves(tbid, "LCD")
    assert [row["rate"] for row in rows] == [0.0, 2.5]
    assert [r.curves[row["curve"]] for row in rows] == [m["curves"]["c"], m["curves"]["fast"]]
