"""Models of the work-precision benchmark: the example models in ``studies/models`` plus four built here.

Each entry: name -> (model dict as a YAML file loads, smooth?, quantities that have no converged
value). ``smooth`` models (linear / nonlinear elastic springs and dampers, no hysteresis, no
prescribed motion) get the scipy reference and scipy runs; the others are referenced to crashstudy
itself at ``safety_factor`` 0.001.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from common import MODELS

G = 9.80665  # m/s^2


def _load(name: str) -> dict[str, Any]:
    from crashstudy.schema.yamlio import load_yaml

    return load_yaml(str(MODELS / f"{name}.yaml")).data


# 2-D, smooth: nonlinear_elastic + linear_elastic chain under gravity and a trapezoidal load pulse
# (the chain of tests/test_physics_2d_and_walls.py).
CHAIN_2D: dict[str, Any] = {
    "name": "chain-2d",
    "curves": {
        "soft-stiff": {"x": [-0.1, -0.02, 0.0, 0.02, 0.1], "y": [-6000.0, -1000.0, 0.0, 1000.0, 6000.0]},
        "pulse": {"x": [0.0, 0.05, 0.1, 0.15], "y": [0.0, 1.0, 1.0, 0.0]},
    },
    "nodes": {
        "anchor": {"position": [0.0, 0.0], "fixed": True},
        "a": {"position": [0.3, -0.1], "mass": 2.0},
        "b": {"position": [0.6, -0.3], "mass": 1.0},
        "c": {"position": [0.8, -0.6], "mass": 1.5},
    },
    "springs": {
        "s1": {"nodes": ["anchor", "a"], "material": {"type": "nonlinear_elastic", "curve": "soft-stiff"}},
        "s2": {"nodes": ["a", "b"], "material": {"type": "linear_elastic", "stiffness": 2.0e4}},
        "s3": {"nodes": ["b", "c"], "material": {"type": "nonlinear_elastic", "curve": "soft-stiff"}},
        "s4": {"nodes": ["anchor", "c"], "material": {"type": "linear_elastic", "stiffness": 5.0e3}},
    },
    "initial_velocity": {"b": [0.5, 1.0]},
    "gravity": [0.0, -G],
    "loads": [{"node": "c", "force": [80.0, -40.0], "curve": "pulse"}],
    "end_time": 0.4,
}

# 1-D, smooth, damped: a 3-mass seat/occupant-like chain; a hardening buffer (nonlinear_elastic) in
# parallel with a damper at the base, linear springs above, 8 m/s impact.
_E = np.linspace(-0.08, 0.08, 33)
DAMPED_CHAIN: dict[str, Any] = {
    "name": "damped-chain",
    "curves": {"buffer": {"x": [float(x) for x in _E], "y": [float(y) for y in 2.0e5 * _E + 4.0e8 * _E**3]}},
    "nodes": {
        "base": {"position": [0.0], "fixed": True},
        "sled": {"position": [0.2], "mass": 40.0},
        "seat": {"position": [0.5], "mass": 15.0},
        "occupant": {"position": [0.9], "mass": 75.0},
    },
    "springs": {
        "buffer": {"nodes": ["base", "sled"], "material": {"type": "nonlinear_elastic", "curve": "buffer"}},
        "buffer-damper": {"nodes": ["base", "sled"], "material": {"type": "damper", "damping": 800.0}},
        "seat-mount": {"nodes": ["sled", "seat"], "material": {"type": "linear_elastic", "stiffness": 3.0e5}},
        "belt": {"nodes": ["seat", "occupant"], "material": {"type": "linear_elastic", "stiffness": 6.0e4}},
    },
    "initial_velocity": {"sled": [-8.0], "seat": [-8.0], "occupant": [-8.0]},
    "end_time": 0.15,
}

# 1-D crush: a 1200 kg car front (crush, 250 kN progressive folding then bottoming) hitting a rigid
# barrier at 15 m/s, with an 80 kg occupant on a linear belt; crush, elastic spring-back, separation.
CRUSH_REBOUND: dict[str, Any] = {
    "name": "crush-rebound",
    "curves": {"front": {"x": [-0.9, -0.7, -0.05, -0.01, 0.0], "y": [-2.0e6, -3.5e5, -2.5e5, -3.2e5, 0.0]}},
    "nodes": {
        "barrier": {"position": [0.0], "fixed": True},
        "body": {"position": [0.8], "mass": 1200.0},
        "occupant": {"position": [1.6], "mass": 80.0},
    },
    "springs": {
        "front": {
            "nodes": ["barrier", "body"],
            "material": {"type": "crush", "loading": "front", "unloading_stiffness": 4.0e7},
        },
        "belt": {"nodes": ["body", "occupant"], "material": {"type": "linear_elastic", "stiffness": 1.5e5}},
    },
    "initial_velocity": {"body": [-15.0], "occupant": [-15.0]},
    "end_time": 0.15,
}

# 1-D general_nonlinear with yield both ways: an engine mount on a rigid frame shaken by an
# impacting 170 kg engine (rebound through tension yield), beside a linear neighbour.
MOUNT_CYCLE: dict[str, Any] = {
    "name": "mount-cycle",
    "curves": {
        "mount-loading": {
            "x": [-0.1, -0.04, -0.01, 0.0, 0.01, 0.04, 0.1],
            "y": [-3.0e5, -3.0e4, -2.0e4, 0.0, 2.0e4, 3.0e4, 3.0e5],
        },
        "mount-unloading": {"x": [-0.01, 0.0, 0.01], "y": [-4.5e4, 0.0, 4.5e4]},
    },
    "nodes": {
        "frame": {"position": [0.0], "fixed": True},
        "engine": {"position": [0.3], "mass": 170.0},
        "gearbox": {"position": [0.7], "mass": 60.0},
    },
    "springs": {
        "mount": {
            "nodes": ["frame", "engine"],
            "material": {
                "type": "general_nonlinear",
                "loading": "mount-loading",
                "unloading": "mount-unloading",
                "tension_yield": 2.0e4,
                "compression_yield": -2.0e4,
            },
        },
        "flange": {
            "nodes": ["engine", "gearbox"],
            "material": {"type": "linear_elastic", "stiffness": 2.0e6},
        },
    },
    "initial_velocity": {"engine": [-4.0], "gearbox": [-4.0]},
    "end_time": 0.25,
}


def models() -> dict[str, tuple[dict[str, Any], bool, tuple[str, ...]]]:
    """name -> (model dict, smooth, quantities without a converged value)."""
    return {
        "linear-spring": (_load("linear-spring"), True, ()),
        "nonlinear-elastic": (_load("nonlinear-elastic"), True, ()),
        "chain-2d": (CHAIN_2D, True, ()),
        "damped-chain": (DAMPED_CHAIN, True, ()),
        "general-nonlinear-compression": (_load("general-nonlinear-compression"), False, ()),
        # the prescribed displacement has kinks: the exact acceleration there is a delta
        "general-nonlinear-tension": (_load("general-nonlinear-tension"), False, ("peak_deceleration",)),
        "helicopter-subfloor": (_load("helicopter-subfloor"), False, ()),
        "frontal-9mass": (_load("frontal-9mass"), False, ()),
        "crush-rebound": (CRUSH_REBOUND, False, ()),
        "mount-cycle": (MOUNT_CYCLE, False, ()),
    }
