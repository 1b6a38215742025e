"""Small models shared by test modules (text or dicts, as the tests write them to files)."""

from __future__ import annotations

from typing import Any

TWO_SPRING_CRUSH: dict[str, Any] = {  # the study tests' model (tests/test_study.py, tests/test_new_user.py)
    "name": "two-spring-crush",
    "description": "1-D frontal impact: crush spring against a wall, body mass behind a linear spring.",
    "units": "SI",
    "curves": {"crush-loading": {"x": [-0.2, -0.02, 0.0], "y": [-60000.0, -40000.0, 0.0]}},
    "nodes": {
        "wall": {"position": [0.0], "fixed": True},
        "front": {"position": [0.3], "mass": 50.0},
        "body": {"position": [0.9], "mass": 800.0},
    },
    "springs": {
        "crush": {
            "nodes": ["wall", "front"],
            "material": {"type": "crush", "loading": "crush-loading", "unloading_stiffness": 5.0e6},
        },
        "body": {"nodes": ["front", "body"], "material": {"type": "linear_elastic", "stiffness": 2.0e6}},
    },
    "initial_velocity": {"front": [-10.0], "body": [-10.0]},
    "end_time": 0.02,
    "output": {"interval": 2.0e-4},
}

DROP = """\
name: drop
nodes:
  ground: {position: [0.0], fixed: true}
  body: {position: [0.5], mass: 100.0}
springs:
  pad: {nodes: [ground, body], material: {type: linear_elastic, stiffness: 1.0e6}}
initial_velocity: {body: [-5.0]}
end_time: 0.03
time_step: {safety_factor: 0.9}
output: {histories: none}
"""  # a 100 kg body dropped on a pad (tests/test_design.py, tests/test_sensitivity.py)
