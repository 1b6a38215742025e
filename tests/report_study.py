"""A tiny study for the report tests, with numbers known in closed form.

A 1-D body (mass m, speed v) hits a ``crush`` spring whose loading curve rises within 0.01 m to a flat
plateau F = 100 kN: the peak deceleration is F / m (12.75 g at 800 kg, 10.20 g at 1000 kg) and the crush
m v^2 / (2 F) + ~0.005 m. The 15 m/s variants are zipped with an unloading stiffness of 1e12 N/m, whose
critical step 2 sqrt(m / k) (57 and 63 us) is below the fixed step of 100 us: both fail with that reason,
the four others are ok. The study's ``optimize:``
block constrains ``peak_deceleration_g.body <= 12``: the 800 kg variants violate it, the 1000 kg ones hold it.
"""

from __future__ import annotations

from pathlib import Path

import yaml

PLATEAU = 100_000.0  # N
MASSES = [800.0, 1000.0]  # kg
SPEEDS = [5.0, 10.0, 15.0]  # m/s
STIFFNESS = [1.0e7, 1.0e7, 1.0e12]  # N/m, unloading; zipped with SPEEDS
DT = 1.0e-4  # s, fixed step
G = 9.80665
CONSTRAINT_G = 12.0


def fails(m: float, k: float) -> bool:
    """A fixed step above the critical step 2 sqrt(m / k) of the stiffest slope fails the variant."""
    return DT > 2.0 * (m / k) ** 0.5


def write_and_run(folder: Path) -> Path:
    from crashstudy.run.runner import run_study

    folder.mkdir(parents=True, exist_ok=True)
    model = {
        "name": "crush-block",
        "units": "SI",
        "curves": {"c1": {"x": [-10.0, -0.01, 0.0], "y": [-PLATEAU, -PLATEAU, 0.0]}},
        "nodes": {"ground": {"position": [0.0], "fixed": True}, "body": {"position": [1.0], "mass": 1000.0}},
        "springs": {
            "s1": {
                "nodes": ["ground", "body"],
                "material": {"type": "crush", "loading": "c1", "unloading_stiffness": 1.0e7},
            }
        },
        "initial_velocity": {"body": [-5.0]},
        "end_time": 0.25,
        "time_step": {"dt": DT},
        "metrics": [
            {"node": "body", "cfc": 60, "criteria": ["peak_g", "hic15", "clip3ms", "olc", "delta_v"]}
        ],
        "output": {"histories": ["acceleration", "filtered_acceleration", "spring_force"]},
    }
    study = {
        "name": "crush-report",
        "model": "model.yaml",
        "matrix": {"nodes.body.mass": MASSES},
        "zip": [{"impact_velocity": SPEEDS, "springs.s1.material.unloading_stiffness": STIFFNESS}],
        "optimize": {
            "minimize": "max_crush.s1",
            "constraints": [f"peak_deceleration_g.body <= {CONSTRAINT_G}"],
            "variables": {"nodes.body.mass": [800.0, 1000.0]},
        },
    }
    (folder / "model.yaml").write_text(yaml.safe_dump(model, sort_keys=False))
    (folder / "study.yaml").write_text(yaml.safe_dump(study, sort_keys=False))
    run_study(folder / "study.yaml", folder / "out", force=True)
    return folder / "out"
