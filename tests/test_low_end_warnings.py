"""Issue 23 item 3: plausibility warnings at the low end, naming the likely cause.

A speed left in m/s in an ``mm-s-t-N`` file (15.6 read as 15.6 mm/s = 0.0156 m/s) ran silently and the
coach peaked at 0.1 g. Now ``validate``/``simulate``/``run`` warn about an impact slower than a walking
pace (and say "did you mean 15.6 m/s? In mm-s-t-N that is 15600 mm/s"), about a body that never reaches
1 g, and about an ``end_time`` far from the model's first natural period. Truths: unit arithmetic and the
closed-form periods of one and two masses on springs. The examples in ``studies/`` raise none of these
(test_new_user.py::test_the_example_models_raise_no_plausibility_warning and the period check below).
"""

from __future__ import annotations

import glob
import math
from pathlib import Path

import pytest

from crashstudy.arrays.vibration import first_period
from crashstudy.schema.plausible import peak_g_warnings
from helpers import run_main

ROOT = Path(__file__).resolve().parents[1]

SLOW = """\
name: slow
units: mm-s-t-N
curves:
  crush: {x: [-500.0, -10.0, 0.0], y: [-4.0e5, -4.0e5, 0.0]}
nodes:
  base: {position: [0.0], fixed: true}
  m1: {position: [1000.0], mass: 1.5}
springs:
  s: {nodes: [base, m1], material: {type: crush, loading: crush, unloading_stiffness: 1.0e5}}
initial_velocity: {m1: [-15.6]}
end_time: 0.1
output: {histories: none}
"""


def run(*argv: str) -> tuple[int, str]:
    """``crashstudy ARGV`` in this process: (exit code, stderr)."""
    rc, _, err = run_main(*argv)
    return rc, err


def test_a_speed_in_m_s_in_an_mm_s_t_n_model_warns_and_names_the_likely_unit(tmp_path: Path) -> None:
    model = tmp_path / "slow.yaml"
    model.write_text(SLOW, encoding="utf-8")
    rc, err = run("validate", str(model))
    assert rc == 0
    # 15.6 mm/s = 0.0156 m/s; read as m/s it is 15600 mm/s
    assert (
        f"warning: {model}: initial velocity 15.6 mm/s is 0.0156 m/s, slower than a walking pace (1 m/s): did "
        "you mean 15.6 m/s? In mm-s-t-N that is 15600 mm/s"
    ) in err
    rc, err = run("simulate", str(model), "-o", str(tmp_path / "out"))
    assert rc == 0
    # KE 182 mJ stops within 0.1 mm on the 4e4 N/mm first segment: 3.8 kN on 1.5 t = 0.26 g
    lines = [ln for ln in err.splitlines() if "peak deceleration" in ln]
    assert lines and "of node 'm1'" in lines[0] and "is below 1 g" in lines[0], err
    assert "likely cause: its initial velocity 15.6 mm/s is 0.0156 m/s" in lines[0]
    fixed = SLOW.replace("[-15.6]", "[-15600.0]")
    model.write_text(fixed, encoding="utf-8")
    rc, err = run("simulate", str(model), "-o", str(tmp_path / "out2"))
    assert rc == 0 and "warning" not in err, err


def test_a_bumper_test_at_4_km_h_does_not_warn(tmp_path: Path) -> None:
    model = tmp_path / "m.yaml"
    model.write_text(SLOW.replace("[-15.6]", "[-1111.0]"), encoding="utf-8")  # 4 km/h = 1.11 m/s
    rc, err = run("validate", str(model))
    assert rc == 0 and "walking pace" not in err, err


def test_a_slow_impact_velocity_axis_value_warns_naming_the_axis(tmp_path: Path) -> None:
    (tmp_path / "m.yaml").write_text(SLOW.replace("[-15.6]", "[-15600.0]"), encoding="utf-8")
    study = tmp_path / "s.yaml"
    study.write_text(
        "name: s\nmodel: m.yaml\nmatrix:\n  impact_velocity: [0.0, 15.6, 15600.0]\n", encoding="utf-8"
    )
    rc, err = run("validate", str(study))
    assert rc == 0
    assert (
        f"warning: {study}: impact_velocity value 15.6 mm/s is 0.0156 m/s, slower than a walking pace" in err
    ), err


def test_a_body_below_1_g_at_a_plausible_speed_names_forces_or_masses() -> None:
    speeds = [15600.0]  # mm/s: 15.6 m/s, a plausible crash speed
    got = peak_g_warnings("mm-s-t-N", "m1", 0.5, 3, speeds)
    assert (
        len(got) == 1 and "0.5 g of node 'm1'" in got[0] and "forces too small or masses too large" in got[0]
    )
    assert peak_g_warnings("mm-s-t-N", "m1", 1.5, 3, speeds) == []
    assert peak_g_warnings("mm-s-t-N", "m1", 0.5, 3) == []  # no speeds: nothing known about the cause
    assert (
        peak_g_warnings("mm-s-t-N", "m1", 0.5, 3, speeds, prescribed=True) == []
    )  # driven: not a crash pulse


BODIES = """\
name: bodies
units: SI
nodes:
  base: {position: [0.0, 0.0], fixed: true}
  rail: {position: [0.0, 1.0], mass: 5000.0, fixed: [x]}
  body: {position: [1.0, 0.0], mass: 1000.0}
  tip: {position: [2.0, 0.0], mass: 10.0}
  cart: {position: [3.0, 0.0], mass: 3000.0}
springs:
  s1: {nodes: [base, body], material: {type: linear_elastic, stiffness: 1.0e5}}
  s2: {nodes: [body, tip], material: {type: linear_elastic, stiffness: 1.0e5}}
  s3: {nodes: [base, rail], material: {type: linear_elastic, stiffness: 1.0e5}}
  s4: {nodes: [tip, cart], material: {type: linear_elastic, stiffness: 1.0e5}}
prescribed_motion:
  - {node: cart, quantity: velocity, direction: x, curve: v}
curves:
  v: {x: [0.0, 1.0], y: [0.0, 0.0]}
initial_velocity: {body: [-3.0, 4.0], tip: [1.0, 0.0]}
end_time: 0.01
output: {histories: none}
"""


def test_results_carry_the_body_node_and_the_warning_after_a_run_reads_it_not_the_yaml(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The body is the heaviest node fixed in no direction and not driven: not the partly fixed 5 t rail,
    not the driven 3 t cart, but the 1 t body; the initial speeds are |(-3, 4)| = 5 and 1. The check after
    ``simulate`` takes them from the results' ``body`` attribute, never re-validating the stored YAML."""
    import json

    from crashstudy.cli import main as cli_main
    from crashstudy.results.attributes import body_facts
    from crashstudy.results.store import open_results

    assert body_facts(_plan(BODIES)) == {
        "node": "body",
        "initial_speeds": [5.0, 1.0],
        "prescribed_motion": True,
    }
    (tmp_path / "slow.yaml").write_text(SLOW, encoding="utf-8")
    assert run("simulate", str(tmp_path / "slow.yaml"), "-o", str(tmp_path / "out"))[0] == 0
    res = open_results(tmp_path / "out")
    assert json.loads(res.dataset.attrs["body"]) == {
        "node": "m1",
        "initial_speeds": [15.6],
        "prescribed_motion": False,
    }

    def refuse(*a: object, **k: object) -> None:
        raise AssertionError("the stored model was validated again")

    monkeypatch.setattr("crashstudy.schema.validate_model_data", refuse)
    said: list[str] = []
    monkeypatch.setattr(cli_main, "_warn", said.extend)
    cli_main._after_run(res)  # 0.26 g: the low-g warning names the stored 15.6 mm/s as the likely cause
    res.close()
    assert (
        len(said) == 1
        and "of node 'm1'" in said[0]
        and "likely cause: its initial velocity 15.6 mm/s" in said[0]
    )


TWO_DOF = """\
name: two
units: SI
nodes:
  base: {{position: [0.0], fixed: true}}
  body: {{position: [1.0], mass: 1000.0}}
  tip: {{position: [1.1], mass: 0.1}}
springs:
  soft: {{nodes: [base, body], material: {{type: linear_elastic, stiffness: 1.0e5}}}}
  stiff: {{nodes: [body, tip], material: {{type: linear_elastic, stiffness: 1.0e9}}}}
initial_velocity: {{body: [-5.0], tip: [-5.0]}}
end_time: {end}
output: {{histories: none}}
"""


def _plan(text: str):  # type: ignore[no-untyped-def]
    from helpers import model_plan

    return model_plan(text)


def test_the_first_natural_period_is_the_closed_form_of_one_and_two_masses() -> None:
    one = _plan(
        TWO_DOF.format(end=0.1)
        .replace("  tip: {position: [1.1], mass: 0.1}\n", "")
        .replace("  stiff: {nodes: [body, tip], material: {type: linear_elastic, stiffness: 1.0e9}}\n", "")
        .replace(", tip: [-5.0]", "")
    )
    assert first_period(one.topology, one.base) == pytest.approx(
        2 * math.pi * math.sqrt(1000.0 / 1.0e5), rel=1e-12
    )
    free = _plan(
        TWO_DOF.format(end=0.1).replace(
            "base: {position: [0.0], fixed: true}", "base: {position: [0.0], mass: 500.0}"
        )
    )
    # three free masses on two springs: omega^2 are the eigenvalues of M^-1 K; here the soft pair dominates
    import numpy as np

    m = np.array([500.0, 1000.0, 0.1])
    K = np.array([[1e5, -1e5, 0.0], [-1e5, 1e5 + 1e9, -1e9], [0.0, -1e9, 1e9]])
    w2 = np.sort(np.linalg.eigvals(K / m[:, None]).real)
    assert first_period(free.topology, free.base) == pytest.approx(2 * math.pi / math.sqrt(w2[1]), rel=1e-6)


@pytest.mark.parametrize(("end", "side"), [(0.01, "shorter"), (70.0, "longer")])
def test_an_end_time_far_from_the_first_natural_period_warns(tmp_path: Path, end: float, side: str) -> None:
    """T1 = 2 pi sqrt(1000 / 1e5) = 0.628 s: 0.01 s is 0.016 T1 (yet 500 critical steps of the stiff tip),
    70 s is 111 T1."""
    model = tmp_path / "m.yaml"
    model.write_text(TWO_DOF.format(end=end), encoding="utf-8")
    rc, err = run("validate", str(model))
    assert rc == 0
    assert (
        f"times the model's first natural period (0.628 s, springs at their steepest slope): far {side}"
        in err
    ), err
    model.write_text(TWO_DOF.format(end=1.0), encoding="utf-8")
    assert "natural period" not in run("validate", str(model))[1]


def test_no_example_ends_far_from_its_first_natural_period() -> None:
    from crashstudy.schema import load_model
    from crashstudy.schema.plausible import PERIOD_RATIO
    from crashstudy.study.plan import load_study, plan_from_model

    for f in sorted(glob.glob(str(ROOT / "studies" / "models" / "*.yaml"))):
        plan = plan_from_model(load_model(f))
        T = first_period(plan.topology, plan.base)
        end = float(plan.base[plan.topology.blocks["end_time"].start])
        assert T == math.inf or PERIOD_RATIO[0] * 10 <= end / T <= PERIOD_RATIO[1] / 10, (f, end, T)
    assert load_study  # the studies run these models (their warnings: test_examples)
