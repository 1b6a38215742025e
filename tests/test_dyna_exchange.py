"""LS-DYNA keyword decks (SPEC 8c): ``export --dyna`` then ``import`` gives the same results; every card
of our decks read back by an independent parser (dynars' built-in keyword library); decks written by hand
from the manual's layouts (fixed width, comma format, an include) simulate to closed forms; bad decks
exit 2 naming file, line and keyword.

Truths: the original model's own run (bitwise, or 1e-12 where a study axis scales a curve), dynars'
reading of each field (exact: the deck holds the shortest text that reads back as the value), closed
forms of a single mass on a linear spring, a viscous damper and a constant-force crush (relative 1e-3,
the central-difference error at the steps used).
"""

from __future__ import annotations

import copy
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

from conftest import run_model
from crashstudy.exchange.dyna_cards import fmt_float
from crashstudy.exchange.dyna_export import export_deck
from crashstudy.exchange.dyna_import import import_deck
from crashstudy.schema import load_model, parse_model
from crashstudy.schema.yamlio import loads_yaml
from helpers import output_differences

MODELS = sorted((Path(__file__).resolve().parents[1] / "studies" / "models").glob("*.yaml"))


def _curve(x: list[float], y: list[float]) -> dict[str, list[float]]:
    return {"x": x, "y": y}


def _two_node(material: dict[str, Any], curves: dict[str, Any] | None = None, **extra: Any) -> dict[str, Any]:
    """A 2-D model: a fixed node and a 2 kg mass on one inclined spring, moving in at 3 m/s."""
    m: dict[str, Any] = {
        "name": f"one-{material['type']}",
        "units": "SI",
        "curves": curves or {},
        "nodes": {"a": {"position": [0.0, 0.0], "fixed": True}, "b": {"position": [0.3, 0.1], "mass": 2.0}},
        "springs": {"s": {"nodes": ["a", "b"], "material": material}},
        "initial_velocity": {"b": [-3.0, -1.0]},
        "end_time": 0.06,
        "output": {"interval": 5.0e-4},
    }
    m.update(extra)
    return m


ELASTIC = _curve([-0.2, -0.05, 0.0, 0.05, 0.2], [-9000.0, -1500.0, 0.0, 1200.0, 7000.0])
MATERIAL_MODELS = {
    "linear_elastic": _two_node(
        {"type": "linear_elastic", "stiffness": 2.0e4},
        loads=[{"node": "b", "force": [10.0, -5.0]}],
        time_step={"safety_factor": 0.5},
    ),
    "damper": _two_node({"type": "damper", "damping": 60.0}, gravity=[0.0, -9.80665]),
    "elastoplastic": _two_node(
        {"type": "elastoplastic", "stiffness": 2.0e4, "tangent_stiffness": 2.0e3, "yield_force": 150.0},
        rigid_walls=[{"id": "floor", "point": [0.0, 0.07], "normal": [0.1, 1.0], "nodes": ["b"]}],
    ),
    "nonlinear_elastic": _two_node(
        {"type": "nonlinear_elastic", "curve": "c"},
        {"c": ELASTIC, "pulse": _curve([0.01, 0.02, 0.03], [0.0, 1.0, 0.5])},
        loads=[{"node": "b", "force": [0.0, -400.0], "curve": "pulse"}],
    ),
    "nonlinear_damper": _two_node(
        {"type": "nonlinear_damper", "curve": "c"},
        {"c": _curve([-5.0, 0.0, 1.0, 5.0], [-900.0, 0.0, 100.0, 300.0])},
    ),
    "general_nonlinear": _two_node(
        {"type": "general_nonlinear", "loading": "l", "unloading": "u", "compression_yield": -1000.0},
        {"l": ELASTIC, "u": _curve([-0.01, 0.0, 0.01], [-800.0, 0.0, 800.0])},
    ),
    "crush": _two_node(
        {"type": "crush", "loading": "c", "unloading_stiffness": 5.0e4},
        {"c": ELASTIC},
        nodes={
            "a": {"position": [0.0, 0.0], "fixed": ["y"], "mass": 50.0},
            "b": {"position": [0.3, 0.1], "mass": 2.0},
        },
        prescribed_motion=[
            {"node": "a", "quantity": "velocity", "direction": "x", "curve": "v", "scale": 2.0}
        ],
    ),
    "rate_elastic": _two_node(
        {"type": "rate_elastic", "curves": [{"rate": 0.0, "curve": "c"}, {"rate": 4.0, "curve": "f"}]},
        {"c": ELASTIC, "f": _curve([-0.1, 0.0, 0.1], [-12000.0, 0.0, 10000.0])},
    ),
}
MATERIAL_MODELS["crush"]["curves"]["v"] = _curve([0.0, 0.02, 0.04], [0.0, 1.0, 1.0])
MATERIAL_MODELS["linear_elastic"]["springs"]["s"]["initial_elongation"] = 0.01


def _deck(model: dict[str, Any] | Path, tmp_path: Path) -> tuple[Path, dict[str, Any]]:
    lm = (
        load_model(str(model))
        if isinstance(model, Path)
        else parse_model(loads_yaml(yaml.safe_dump(model, sort_keys=False), "m.yaml"))
    )
    text, rounded = export_deck(lm.model, lm.doc)
    assert rounded == []
    deck = tmp_path / "model.k"
    deck.write_text(text)
    return deck, dict(lm.doc.data)


def _same_results(original: dict[str, Any] | str, imported: dict[str, Any]) -> None:
    a, _, _ = run_model(original, kernel="generic")
    b, _, _ = run_model(imported, kernel="generic")
    assert a.histories, "the model keeps histories, so the comparison is not vacuous"
    assert output_differences(a, b, 0, 0) == []


@pytest.mark.parametrize("path", MODELS, ids=[p.stem for p in MODELS])
def test_example_model_exported_and_imported_gives_identical_results(path: Path, tmp_path: Path) -> None:
    deck, _ = _deck(path, tmp_path)
    data, notes = import_deck(str(deck))
    assert notes == []
    _same_results(path.read_text(), data)


@pytest.mark.parametrize("kind", list(MATERIAL_MODELS))
def test_each_material_exported_and_imported_gives_identical_results(kind: str, tmp_path: Path) -> None:
    deck, data = _deck(MATERIAL_MODELS[kind], tmp_path)
    imported, _ = import_deck(str(deck))
    assert imported["springs"]["s"]["material"]["type"] == kind
    _same_results(MATERIAL_MODELS[kind], imported)


def test_float_fields_hold_the_shortest_exact_text() -> None:
    assert fmt_float(2.0e7, 10) == ("20000000.0", True)
    assert fmt_float(-1.5e-5, 10) == ("-1.5e-5", True)
    assert fmt_float(1.0e30, 10) == ("1.e30", True)
    text, exact = fmt_float(0.1234567890123, 10)
    assert not exact and len(text) <= 10 and abs(float(text) - 0.1234567890123) < 1e-8


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


def _col(table: dict[str, Any], name: str) -> list[Any]:
    v = table[name]
    return v.tolist() if hasattr(v, "tolist") else list(v)


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


def load_model_data(data: dict[str, Any]) -> Any:
    return parse_model(loads_yaml(yaml.safe_dump(data, sort_keys=False), "m.yaml")).model


@pytest.mark.parametrize(
    "case", [*MODELS, *MATERIAL_MODELS], ids=[p.stem for p in MODELS] + list(MATERIAL_MODELS)
)
def test_every_card_of_our_decks_read_back_by_dynars(case: Path | str, tmp_path: Path) -> None:
    pytest.importorskip("dynars")
    deck, data = _deck(case if isinstance(case, Path) else copy.deepcopy(MATERIAL_MODELS[case]), tmp_path)
    _check_with_dynars(deck, data)


# --- decks written by hand from the manual's layouts, against closed forms ---------------------------

DECKS = Path(__file__).resolve().parent / "dyna_decks"


def _run_deck(name: str) -> tuple[Any, dict[str, Any]]:
    data, _ = import_deck(str(DECKS / name))
    out, _, plan = run_model(data, kernel="generic")
    return out, data


def test_hand_written_fixed_width_oscillator_peaks_at_v0_over_omega() -> None:
    out, data = _run_deck("oscillator-fixed.k")
    assert data["units"] == "SI" and data["springs"]["s1"]["material"] == {
        "type": "linear_elastic",
        "stiffness": 2.0e4,
    }
    omega = np.sqrt(2.0e4 / 2.0)  # rad/s
    assert out.max_elongation[0, 0] == pytest.approx(1.0 / omega, rel=1e-3)  # 0.01 m


def test_hand_written_comma_format_damper_decays_exponentially() -> None:
    out, data = _run_deck("damper-comma.k")
    assert data["units"] == "mm-ms-kg-kN" and data["output"] == {"interval": 0.1}
    t = np.arange(out.histories["velocity"].shape[0]) * 0.1  # ms
    v = out.histories["velocity"][:, 1, 0, 0]
    x = out.histories["displacement"][:, 1, 0, 0]
    assert np.allclose(v, 5.0 * np.exp(-t / 20.0), rtol=1e-3, atol=1e-4 * 5.0)
    assert x[-1] == pytest.approx(100.0 * (1.0 - np.exp(-2.0)), rel=1e-3)  # 86.47 mm


def test_hand_written_deck_with_include_crushes_and_rebounds_as_energy_says() -> None:
    out, data = _run_deck("crush-main.k")
    assert data["springs"]["s1"]["material"]["type"] == "crush"
    assert out.max_crush[0, 0] == pytest.approx(0.001 + (5.0e4 - 50.0) / 1.0e5, rel=1e-3)  # 0.5005 m
    assert out.histories["velocity"][-1, 1, 0, 0] == pytest.approx(1.0, rel=1e-2)  # sqrt(2 F^2 / (2 KU) / m)


# --- a study variant -----------------------------------------------------------------------------------


def test_study_variant_exported_runs_as_that_variant(tmp_path: Path, cli: Any) -> None:
    """Variants are numbered row-major over (mass, curve scale, impact speed): 5 = (3 kg, 1.0, 4 m/s) is
    bitwise the study's run; 7 = (3 kg, 1.3, 4 m/s) to round-off (the scale multiplies the written points)."""
    model = tmp_path / "m.yaml"
    model.write_text(yaml.safe_dump(MATERIAL_MODELS["nonlinear_elastic"], sort_keys=False))
    study = tmp_path / "s.yaml"
    study.write_text(
        "name: s\nmodel: m.yaml\nmatrix:\n  nodes.b.mass: [2.0, 3.0]\n  curves.c.scale: [1.0, 1.3]\n"
        "  impact_velocity: [2.0, 4.0]\n"
    )
    for n, scale in ((5, 1.0), (7, 1.3)):
        r = cli("export", str(study), "--dyna", str(tmp_path / f"v{n}.k"), "--variant", str(n))
        assert r.returncode == 0, r.stderr
        data, _ = import_deck(str(tmp_path / f"v{n}.k"))
        assert data["nodes"]["b"]["mass"] == 3.0
        ref, _, _ = run_model(
            MATERIAL_MODELS["nonlinear_elastic"],
            kernel="generic",
            variants={"nodes.b.mass": [3.0], "curves.c.scale": [scale], "impact_velocity": [4.0]},
        )
        got, _, _ = run_model(data, kernel="generic")
        if scale == 1.0:
            assert output_differences(ref, got, 0, 0) == []
        for name, h in ref.histories.items():
            assert np.allclose(got.histories[name], h, rtol=1e-12, atol=1e-12 * np.nanmax(np.abs(h))), name
    r = cli("export", str(study), "--dyna", str(tmp_path / "v9.k"), "--variant", "9")
    assert r.returncode == 2 and "variant 9 does not exist" in r.stderr and "0 to 7" in r.stderr


# --- bad input: exit 2 naming file, line and keyword ----------------------------------------------------

GOOD = (DECKS / "oscillator-fixed.k").read_text()


@pytest.mark.parametrize(
    "edit, where, words",
    [
        (
            lambda t: t.replace("*END", "*CONTACT_AUTOMATIC_SINGLE_SURFACE\n0\n*END"),
            ":39: *CONTACT_AUTOMATIC_SINGLE_SURFACE",
            "--skip-unsupported",
        ),
        (
            lambda t: t.replace("         1   20000.0", "         1   2OOOO.0"),
            ":35: *MAT_SPRING_ELASTIC",
            "field K",
        ),
        (
            lambda t: t.replace(
                "*SECTION_DISCRETE\n$#   secid       dro        kd        v0        cl        fd\n"
                "         1         0       0.0       0.0       0.0       0.0\n$#     cdl       tdl\n"
                "       0.0       0.0\n",
                "*SECTION_DISCRETE\n         1         0\n",
            ),
            ":29: *SECTION_DISCRETE",
            "second is missing",
        ),
        (
            lambda t: t.replace("0             1.0       0", "0                       0"),
            ":38: *ELEMENT_DISCRETE S",
            "blank S reads as 0",
        ),
        (lambda t: t.replace("*END", "*INCLUDE\nnot-there.k\n*END"), ":40: *INCLUDE", "not-there.k"),
    ],
)
def test_bad_deck_exits_2_naming_file_line_and_keyword(
    edit: Any, where: str, words: str, tmp_path: Path, cli: Any
) -> None:
    deck = tmp_path / "bad.k"
    deck.write_text(edit(GOOD))
    assert edit(GOOD) != GOOD
    r = cli("import", str(deck), "-o", str(tmp_path / "m.yaml"))
    assert r.returncode == 2, r.stderr
    assert f"{deck}{where}" in r.stderr and words in r.stderr and "Traceback" not in r.stderr
    assert not (tmp_path / "m.yaml").exists()


def test_skip_unsupported_lists_and_skips(tmp_path: Path, cli: Any) -> None:
    deck = tmp_path / "extra.k"
    deck.write_text(GOOD.replace("*END", "*CONTROL_ENERGY\n2\n*END"))
    r = cli("import", str(deck), "-o", str(tmp_path / "m.yaml"), "--skip-unsupported")
    assert r.returncode == 0, r.stderr
    assert f"{deck}:39: *CONTROL_ENERGY" in r.stderr
    assert (
        yaml.safe_load((tmp_path / "m.yaml").read_text())["springs"]["s1"]["material"]["stiffness"] == 2.0e4
    )
    r = cli("import", str(deck), "-o", str(tmp_path / "m.yaml"), "--skip-unsupported")
    assert r.returncode == 2 and "--force" in r.stderr  # never overwritten without --force


def test_include_loop_is_an_error(tmp_path: Path) -> None:
    (tmp_path / "a.k").write_text("*KEYWORD\n*INCLUDE\nb.k\n*END\n")
    (tmp_path / "b.k").write_text("*KEYWORD\n*INCLUDE\na.k\n*END\n")
    from crashstudy.errors import InputError

    with pytest.raises(InputError, match="include loop: a.k -> b.k -> a.k"):
        import_deck(str(tmp_path / "a.k"))


def test_feature_without_keyword_is_refused_by_name(tmp_path: Path, cli: Any) -> None:
    m = copy.deepcopy(MATERIAL_MODELS["linear_elastic"])
    m["springs"]["s"]["failure"] = {"tension": 0.05}
    m["rigid_walls"] = [{"id": "w", "point": [0.0, -1.0], "normal": [0.0, 1.0], "stiffness": 1.0e6}]
    (tmp_path / "m.yaml").write_text(yaml.safe_dump(m, sort_keys=False))
    r = cli("export", str(tmp_path / "m.yaml"), "--dyna", str(tmp_path / "m.k"))
    assert r.returncode == 2, r.stderr
    assert "springs.s.failure:" in r.stderr and "rigid_walls.0.stiffness:" in r.stderr
    assert f"{tmp_path / 'm.yaml'}:" in r.stderr and not (tmp_path / "m.k").exists()


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


def test_damaged_crashstudy_comments_are_ignored_not_a_traceback(tmp_path: Path) -> None:
    deck, _ = _deck(copy.deepcopy(MATERIAL_MODELS["elastoplastic"]), tmp_path)
    text = deck.read_text().replace('"nodes":["a","b"]', '"nodes":[1,2]')
    assert text != deck.read_text()
    deck.write_text(text)
    data, notes = import_deck(str(deck))
    assert (
        "damaged" in notes[0]
        and set(data["nodes"]) == {"n1", "n2"}
        and data["rigid_walls"][0]["nodes"] == ["n2"]
    )


def test_node_defined_twice_is_an_error(tmp_path: Path) -> None:
    from crashstudy.errors import InputError

    deck = tmp_path / "twice.k"
    deck.write_text(GOOD.replace("       2             0.1", "       1             0.1"))
    with pytest.raises(
        InputError, match=r"twice.k:12: \*NODE NID: node 1 is defined twice \(also at line 11"
    ):
        import_deck(str(deck))


def test_node_constraint_codes_hold_like_spcs(tmp_path: Path) -> None:
    """*NODE TC = 7 (all translations held) reads as the fixed node of an SPC card."""
    deck = tmp_path / "tc.k"
    spc = "         1         0         1         1         1         1         1         1\n"
    text = GOOD.replace(spc, "").replace(
        "       1             0.0             0.0             0.0\n",
        "       1             0.0             0.0             0.0       7       7\n",
    )
    assert text.count("\n") == GOOD.count("\n") - 1
    deck.write_text(text)
    assert (
        import_deck(str(deck))[0]["nodes"]
        == import_deck(str(DECKS / "oscillator-fixed.k"))[0]["nodes"]
        == {"n1": {"position": [0.0], "fixed": True}, "n2": {"position": [0.1], "mass": 2.0}}
    )


def test_a_link_planted_at_the_output_is_replaced_never_followed(tmp_path: Path) -> None:
    from crashstudy.cli.main import main

    victim = tmp_path / "victim"
    for argv, out in (
        (["export", str(MODELS[0]), "--dyna"], tmp_path / "m.k"),
        (["import", str(DECKS / "oscillator-fixed.k"), "-o"], tmp_path / "m.yaml"),
    ):
        victim.write_text("precious\n")
        out.symlink_to(victim)
        assert main([*argv, str(out), "--force"]) == 0
        assert victim.read_text() == "precious\n" and not out.is_symlink() and out.stat().st_size > 100


def test_a_value_too_long_for_its_field_is_rounded_in_the_deck_and_restored_on_import(tmp_path: Path) -> None:
    import dynars

    m = copy.deepcopy(MATERIAL_MODELS["linear_elastic"])
    m["springs"]["s"]["material"]["stiffness"] = 20000.123456789  # 15 digits: a 10-character K holds 7
    m["springs"]["t"] = {
        "nodes": ["a", "b"],
        "material": {"type": "linear_elastic", "stiffness": 20000.1234567},
    }
    lm = load_model_data(m)
    text, rounded = export_deck(lm)
    assert len(rounded) == 2 and "20000.123456789 written as 20000.1235" in rounded[0]
    deck = tmp_path / "r.k"
    deck.write_text(text)
    assert _col(dynars.parse_deck(str(deck)).table("MAT_SPRING_ELASTIC"), "K") == [20000.1235, 20000.1235]
    data, _ = import_deck(str(deck))
    # two values behind one written text: ambiguous, both stay rounded (and were reported)
    assert [s["material"]["stiffness"] for s in data["springs"].values()] == [20000.1235, 20000.1235]
    del m["springs"]["t"]
    text, rounded = export_deck(load_model_data(m))
    deck.write_text(text)
    data, _ = import_deck(str(deck))
    assert data["springs"]["s"]["material"]["stiffness"] == 20000.123456789
    _same_results(m, data)
