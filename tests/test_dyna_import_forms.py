"""LS-DYNA import of the other spellings a hand-written deck uses: ``_TITLE`` variants, ``*MAT_Snn`` names,
curve scale factors (SFA, SFO), and ``--variant`` refused for a model. Truth: the same model written directly
as crashstudy YAML, run with the same kernel (bitwise)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from conftest import run_model
from crashstudy.exchange.dyna_import import import_deck
from helpers import output_differences

DECK = """\
*KEYWORD
*TITLE
titled cards, units mm-ms-kg-kN
*CONTROL_TERMINATION
      20.0
*NODE
       1             0.0             0.0             0.0       7       7
       2            50.0             0.0             0.0       0       0
*ELEMENT_MASS
       1       2             5.0
*BOUNDARY_SPC_NODE
         2         0         0         1         1         1         1         1
*INITIAL_VELOCITY_NODE
         2      -4.0
*PART
spring
         1         1         1
*PART
damper
         2         1         2
*SECTION_DISCRETE
         1         0       0.0       0.0       0.0       0.0
       0.0       0.0
*MAT_SPRING_NONLINEAR_ELASTIC_TITLE
a curve twice as stiff as written (SFO 2) and in cm (SFA 10)
         1        11         0
*MAT_S02
         2     0.002
*DEFINE_CURVE_TITLE
force vs elongation
        11         0      10.0       2.0
                -2.0                -3.0
                 0.0                 0.0
                 2.0                 1.0
*ELEMENT_DISCRETE
       1       1       1       2       0             1.0
       2       2       1       2       0             1.0
*END
"""

DIRECT: dict[str, Any] = {
    "name": "titled-cards",
    "units": "mm-ms-kg-kN",
    "curves": {"curve-11": {"x": [-20.0, 0.0, 20.0], "y": [-6.0, 0.0, 2.0]}},
    "nodes": {"n1": {"position": [0.0], "fixed": True}, "n2": {"position": [50.0], "mass": 5.0}},
    "springs": {
        "s1": {"nodes": ["n1", "n2"], "material": {"type": "nonlinear_elastic", "curve": "curve-11"}},
        "s2": {"nodes": ["n1", "n2"], "material": {"type": "damper", "damping": 0.002}},
    },
    "initial_velocity": {"n2": [-4.0]},
    "end_time": 20.0,
}


def test_title_variants_material_numbers_and_curve_scales_read_as_the_same_model(tmp_path: Path) -> None:
    deck = tmp_path / "titled.k"
    deck.write_text(DECK)
    data, notes = import_deck(str(deck))
    assert notes == []
    assert data["curves"] == DIRECT["curves"] and data["springs"] == DIRECT["springs"]
    a, _, _ = run_model(DIRECT, kernel="generic")
    b, _, _ = run_model(data, kernel="generic")
    assert a.max_crush[0, 0] > 0.0 and output_differences(a, b, 0, 0) == []


def test_variant_of_a_model_is_refused(tmp_path: Path, cli: Any) -> None:
    model = Path(__file__).resolve().parents[1] / "studies" / "models" / "linear-spring.yaml"
    r = cli("export", str(model), "--dyna", str(tmp_path / "m.k"), "--variant", "2")
    assert r.returncode == 2 and "--variant applies to a study file" in r.stderr
    assert not (tmp_path / "m.k").exists()
