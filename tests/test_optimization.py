"""``crashstudy optimize`` and ``crashstudy calibrate`` against closed forms and an independent
integrator (scipy solve_ivp), and their errors. (The calibration of a spring to noisy solve_ivp data, with
its intervals, is in tests/test_analysis_output_exceedance_and_calibration.py.)"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from crashstudy.analysis.optimization import INFEASIBLE, scores
from crashstudy.cli.main import main

CRUSH = """\
name: crush-stop
units: SI
curves:
  plateau: {x: [-1.0, -0.001, 0.0], y: [-1.0e5, -1.0e5, 0.0]}
nodes:
  wall: {position: [0.0], fixed: true}
  body: {position: [1.0], mass: 1000.0}
springs:
  crush: {nodes: [wall, body], material: {type: crush, loading: plateau, unloading_stiffness: 1.0e8}}
initial_velocity: {body: [-10.0]}
end_time: 0.08
output: {histories: none}
"""


def _write(tmp: Path, model: str, study: dict) -> Path:
    (tmp / "model.yaml").write_text(model)
    path = tmp / "study.yaml"
    path.write_text(yaml.safe_dump({"name": "opt", "model": "model.yaml", **study}, sort_keys=False))
    return path


def test_optimum_plateau_force_of_a_crush_stop_matches_the_closed_form(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """1000 kg at 10 m/s into a crush spring whose plateau force F is the variable: peak deceleration F/m
    is smallest for the weakest F that keeps max crush <= 0.2 m. Energy: m v^2 / 2 = F (d - 0.0005)
    (the 1 mm ramp absorbs F / 2 per mm), so F* = 50 kJ / 0.1995 m = 250.63 kN, scale 2.5063, 25.557 g.
    The optimiser finds it within 1% (measured 0.03%) and the optimum is feasible."""
    study = _write(
        tmp_path,
        CRUSH,
        {
            "optimize": {
                "minimize": "peak_deceleration_g.body",
                "constraints": ["max_crush.crush <= 0.2"],
                "variables": {"curves.plateau.scale": [0.5, 5.0]},
                "budget": 300,
                "seed": 1,
            }
        },
    )
    out = tmp_path / "out"
    assert main(["optimize", str(study), "-o", str(out)]) == 0
    opt = yaml.safe_load((out / "optimum.yaml").read_text())
    f_star = 0.5 * 1000.0 * 10.0**2 / (0.2 - 0.0005)
    assert opt["variables"]["curves.plateau.scale"] == pytest.approx(f_star / 1.0e5, rel=0.01)
    assert opt["objective"]["peak_deceleration_g.body"] == pytest.approx(f_star / 1000.0 / 9.80665, rel=0.01)
    assert opt["feasible"] and opt["constraints"]["max_crush.crush <= 0.2"] <= 0.2
    hist = pd.read_csv(out / "history.csv")
    assert len(hist) == opt["evaluations"] and hist["generation"].nunique() == opt["generations"]
    assert "generation 0:" in capsys.readouterr().err
    s = pd.read_parquet(out / "summary.parquet")  # the optimum's own results
    assert s["curves.plateau.scale"].iloc[0] == pytest.approx(opt["variables"]["curves.plateau.scale"])


def test_infeasible_and_failed_candidates_rank_after_every_feasible_one() -> None:
    df = pd.DataFrame(
        {
            "status": ["ok", "ok", "ok", "failed"],
            "obj": [5.0, 1.0, 1.0, np.nan],
            "c": [0.1, 0.3, 0.25, np.nan],
        }
    )
    score, feasible = scores(df, "obj", [("c", "<=", 0.2)])
    assert feasible.tolist() == [True, False, False, False]
    assert score[0] == 5.0 and INFEASIBLE < score[2] < score[1] < score[3]  # least violating first


@pytest.mark.parametrize(
    ("block", "expected"),
    [
        ({}, "no optimize: block"),
        (
            {
                "optimize": {
                    "minimize": "peak_force.nope",
                    "variables": {"curves.plateau.scale": [0.5, 5.0]},
                    "budget": 30,
                }
            },
            "no summary column 'peak_force.nope'",
        ),
        (
            {"optimize": {"minimize": "peak_force.crush", "variables": {"curves.plateau.scale": [5.0, 0.5]}}},
            "need low < high",
        ),
        (
            {
                "optimize": {
                    "minimize": "peak_force.crush",
                    "constraints": ["max_crush.crush < 0.2"],
                    "variables": {"curves.plateau.scale": [0.5, 5.0]},
                }
            },
            "optimize.constraints.0",
        ),
    ],
)
def test_a_bad_optimize_block_is_exit_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], block: dict, expected: str
) -> None:
    study = _write(tmp_path, CRUSH, block)
    capsys.readouterr()
    assert main(["optimize", str(study), "-o", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert expected in err and "Traceback" not in err, err


STUDIES = Path(__file__).resolve().parents[1] / "studies"


def _small_copy(src: Path, tmp: Path, **changes: object) -> Path:
    data = yaml.safe_load(src.read_text())
    data["model"] = str((src.parent / data["model"]).resolve())
    for block, values in changes.items():
        data.setdefault(block, {}).update(values)  # type: ignore[call-overload]
    path = tmp / src.name
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def test_the_frontal_optimize_example_at_small_size_beats_the_base_design(tmp_path: Path) -> None:
    """studies/frontal-optimize.yaml with a budget of 150: the optimum is feasible and its survival-room
    peak deceleration is below the base design's (both scales 1.0, run here as the reference)."""
    from crashstudy.run.runner import simulate

    study = _small_copy(STUDIES / "frontal-optimize.yaml", tmp_path, optimize={"budget": 150})
    out = tmp_path / "out"
    assert main(["optimize", str(study), "-o", str(out)]) == 0
    opt = yaml.safe_load((out / "optimum.yaml").read_text())
    base = simulate(STUDIES / "models" / "frontal-9mass.yaml", tmp_path / "base").summary
    assert (
        opt["feasible"]
        and opt["objective"]["peak_deceleration_g.survival_room"]
        < base["peak_deceleration_g.survival_room"].iloc[0]
    )


def test_the_helicopter_calibrate_example_at_small_size_gives_back_the_values_of_its_record(
    tmp_path: Path,
) -> None:
    """studies/helicopter-calibrate.yaml on the first 40 ms of its synthetic record (made with scale 1.25,
    troop mass 320 kg at a 20x finer step, 2% noise): both recovered within 1%."""
    record = pd.read_csv(STUDIES / "data" / "helicopter-drop.csv")
    record[record["time"] <= 0.04].to_csv(tmp_path / "drop.csv", index=False)
    study = _small_copy(
        STUDIES / "helicopter-calibrate.yaml",
        tmp_path,
        calibrate={"data": "drop.csv"},
        set={"end_time": 0.04},
    )
    out = tmp_path / "out"
    assert main(["calibrate", str(study), "-o", str(out)]) == 0
    cal = yaml.safe_load((out / "calibrated.yaml").read_text())["variables"]
    assert cal["curves.underfloor-loading.scale"] == pytest.approx(1.25, rel=0.01)
    assert cal["nodes.troop_compartment.mass"] == pytest.approx(320.0, rel=0.01)
