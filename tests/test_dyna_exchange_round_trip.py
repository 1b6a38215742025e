"""LS-DYNA keyword decks (SPEC 8c): ``export --dyna`` then ``import`` gives the same results, for the
example models, every material, a study variant and a value too long for its field (rounded in the
deck, restored on import); decks written by hand from the manual's layouts
(fixed width, comma format, an include) simulate to closed forms.

Truths: the original model's own run (bitwise, or 1e-12 where a study axis scales a curve), closed forms
of a single mass on a linear spring, a viscous damper and a constant-force crush (relative 1e-3, the
central-difference error at the steps used)."""

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
from dyna_models import DECKS, MATERIAL_MODELS, MODELS, _col, _deck, load_model_data
from helpers import output_differences


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
