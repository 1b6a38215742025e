"""Small models shared by test modules (text or dicts, as the tests write them to files)."""

from __future__ import annotations

from typing import Any

TWO_SPRING_CRUSH: dict[str, Any] = {  # the study tests' model (tests/test_study_*.py, tests/test_new_user.py)
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


# ------------------------------------------------------------------------------------------------
# One generated-kernel shape for the physics tests of several files (tests/test_wall_physics.py,
# tests/test_spring_features_*.py): their small models side by side in ONE model (model_parts.disjoint), so the
# generated kernel compiles once for all of them (~6 CPU s per shape) and each test reads its own part
# (helpers.generated_part). The reference and generic kernels still run each model alone.
# ------------------------------------------------------------------------------------------------


def one_spring(
    material: dict[str, Any],
    mass: float,
    v0: float = 0.0,
    dim: int = 1,
    end_time: float = 0.1,
    dt: float | None = None,
    interval: float = 1.0e-4,
    **options: Any,
) -> dict[str, Any]:
    """Node ``a`` fixed at the origin, node ``b`` (``mass``) 1 m away (in 2-D along (0.6, 0.8)) moving away
    from ``a`` at ``v0`` along the spring; spring ``s`` with ``material`` and spring ``options``."""
    axis = [1.0] if dim == 1 else [0.6, 0.8]
    model: dict[str, Any] = {
        "name": "one-spring",
        "curves": material.pop("_curves", {}),
        "nodes": {"a": {"position": [0.0] * dim, "fixed": True}, "b": {"position": axis, "mass": mass}},
        "springs": {"s": {"nodes": ["a", "b"], "material": material, **options}},
        "end_time": end_time,
        "output": {"interval": interval},
    }
    if v0:
        model["initial_velocity"] = {"b": [v0 * c for c in axis]}
    if dt is not None:
        model["time_step"] = {"dt": dt}
    return model


def wall_hit(dt: float, spring: bool = False) -> dict[str, Any]:
    """1-D: a 4 t front mass at 15.6 m/s 0.5 m in front of a wall (normal +x at x = 0); with ``spring``
    a 1 t rear mass 1 m behind it on a 1e6 N/m spring, moving at the same speed."""
    model: dict[str, Any] = {
        "name": "hit",
        "nodes": {"front": {"position": [0.5], "mass": 4000.0}},
        "rigid_walls": [{"id": "wall", "point": [0.0], "normal": [1.0], "nodes": ["front"]}],
        "initial_velocity": {"front": [-15.6]},
        "end_time": 0.08,
        "time_step": {"dt": dt},
        "output": {"interval": 1.0e-3},
    }
    if spring:
        model["nodes"]["rear"] = {"position": [1.5], "mass": 1000.0}
        model["springs"] = {
            "s": {"nodes": ["front", "rear"], "material": {"type": "linear_elastic", "stiffness": 1.0e6}}
        }
        model["initial_velocity"]["rear"] = [-15.6]
    return model


def wall_rest() -> dict[str, Any]:
    """1-D: a 10 kg mass on a wall (normal +x at x = 0), pushed in by a spring compressed 0.01 m."""
    return {
        "name": "rest",
        "nodes": {"anchor": {"position": [1.0], "fixed": True}, "m": {"position": [0.0], "mass": 10.0}},
        "springs": {
            "s": {
                "nodes": ["m", "anchor"],
                "initial_elongation": -0.01,
                "material": {"type": "linear_elastic", "stiffness": 1.0e5},
            }
        },
        "rigid_walls": [{"id": "wall", "point": [0.0], "normal": [1.0], "nodes": ["m"]}],
        "end_time": 0.05,
        "output": {"interval": 1.0e-3, "histories": ["wall_force", "acceleration"]},
    }


def damped_stroke() -> dict[str, Any]:
    """1-D: node p (1 kg) driven by a piecewise-linear displacement (rest 10 ms, then 6 m/s for 10 ms,
    then rest) against a fixed anchor through a spring (1e4 N/m) and a damper (c = 1000 N s/m) in parallel."""
    return {
        "name": "stroke",
        "nodes": {"anchor": {"position": [0.0], "fixed": True}, "p": {"position": [1.0], "mass": 1.0}},
        "springs": {
            "k": {"nodes": ["anchor", "p"], "material": {"type": "linear_elastic", "stiffness": 1.0e4}},
            "c": {"nodes": ["anchor", "p"], "material": {"type": "damper", "damping": 1000.0}},
        },
        "curves": {"u": {"x": [0.0, 0.01, 0.02, 0.05], "y": [0.0, 0.0, 0.06, 0.06]}},
        "prescribed_motion": [{"node": "p", "quantity": "displacement", "direction": "x", "curve": "u"}],
        "end_time": 0.04,
        "time_step": {"dt": 1.0e-4},
        "output": {"interval": 1.0e-3},
    }


def penalty_hit(dt: float | None, k: float = 1.0e6) -> dict[str, Any]:
    """1-D: a 1 kg mass at 2 m/s, 1 mm in front of a penalty wall of contact stiffness k."""
    return {
        "name": "penalty",
        "nodes": {"p": {"position": [0.001], "mass": 1.0}},
        "rigid_walls": [{"id": "wall", "point": [0.0], "normal": [1.0], "stiffness": k}],
        "initial_velocity": {"p": [-2.0]},
        "end_time": 0.006,
        **({"time_step": {"dt": dt}} if dt else {}),
        "output": {"interval": 1.0e-5, "histories": ["wall_force", "velocity", "wall_energy"]},
    }


# a 1 kg mass leaving a fixed node at 1 m/s on a 100 N/m spring, x = sin(10 t) / 10 until t = 0.1 s
PULL: dict[str, Any] = {
    "name": "pull",
    "nodes": {"a": {"position": [0.0], "fixed": True}, "b": {"position": [1.0], "mass": 1.0}},
    "springs": {"s": {"nodes": ["a", "b"], "material": {"type": "linear_elastic", "stiffness": 100.0}}},
    "initial_velocity": {"b": [1.0]},
    "end_time": 0.1,
    "output": {"histories": "all"},
}


def breaking_spring() -> dict[str, Any]:
    """A linear spring (1e4 N/m) under a 1 kg mass leaving at 2 m/s that breaks at 0.01 m elongation."""
    return one_spring(
        {"type": "linear_elastic", "stiffness": 1.0e4}, 1.0, 2.0, end_time=0.01, failure={"tension": 0.01}
    )


SCALED_K0, SCALED_M, SCALED_V0 = 4.0e4, 2.0, 3.0  # N/m, kg, m/s


def scaled_spring(dt: float) -> dict[str, Any]:
    """A mass on a straight nonlinear_elastic curve of slope SCALED_K0 (3 knots), moving at SCALED_V0
    (tests/test_curve_factors.py, with the study's scale axes :data:`SCALES`)."""
    return {
        "name": "one-spring",
        "units": "SI",
        "curves": {"c": {"x": [-1.0, 0.0, 1.0], "y": [-SCALED_K0, 0.0, SCALED_K0]}},
        "nodes": {"wall": {"position": [0.0], "fixed": True}, "m": {"position": [1.0], "mass": SCALED_M}},
        "springs": {"s": {"nodes": ["wall", "m"], "material": {"type": "nonlinear_elastic", "curve": "c"}}},
        "initial_velocity": {"m": [-SCALED_V0]},
        "end_time": 0.05,
        "time_step": {"dt": dt},
        "output": {"histories": "none", "interval": 0.05},
    }


SCALES = {"curves.c.scale": [0.5, 1.0, 2.0, 3.0], "curves.c.x_scale": [1.0, 2.0, 0.5, 1.5]}


def generated_parts() -> dict[str, dict[str, Any]]:
    """The parts of the one model that :func:`helpers.generated_part` runs on the generated kernel (prefix
    -> model). Its step, end time and output interval are those of the test that asks (numbers, not the
    kernel's shape); it runs the four variants of :data:`SCALES` on the ``scaled`` part's curve (the
    other parts are the same in every variant). The stroke's rest at 0.06 m is held to 1 s (past its curve's end at 0.05 s the
    displacement would fall to 0) and the penalty wall holds its one node by name (as it does by default)."""
    stroke = damped_stroke()
    stroke["curves"]["u"]["x"][-1] = 1.0
    penalty = penalty_hit(None)
    penalty["rigid_walls"][0]["nodes"] = ["p"]
    return {
        "hit": wall_hit(1.0e-4),
        "held": wall_hit(1.0e-4, spring=True),
        "rest": wall_rest(),
        "stroke": stroke,
        "penalty": penalty,
        "pull": PULL,
        "break": breaking_spring(),
        "scaled": scaled_spring(1.0e-4),  # its curve scaled per variant by SCALES (helpers.generated_part)
    }


# ------------------------------------------------------------------------------------------------
# One generated-kernel shape for two tests that need the generated kernel on a whole model of their own
# (its energies and its status are per model, not per part): tests/test_properties_models.py's node that
# reaches a wall in the first step, and tests/test_stress.py's instability forced by hand. The wall's
# place, the speed, the stiffness, the step and the end time are numbers of the model, not of its shape:
# one compile (~10 CPU s) serves both files.
# ------------------------------------------------------------------------------------------------


def wall_spring(
    wall: str = "1.0", speed: float = -10.0, stiffness: float = 1.0e4, end_time: float = 0.01
) -> str:
    """YAML text: node ``a`` fixed at 0, node ``b`` (1 kg) at 1 m on a linear spring (``stiffness``
    [N/m]) moving at ``speed`` [m/s], a rigid wall (normal +x) at ``wall`` [m] that stops ``b``; every
    history, sampled every 1e-5 s, safety factor 0.9."""
    return f"""\
name: wall-start
nodes:
  a: {{position: [0.0], fixed: true}}
  b: {{position: [1.0], mass: 1.0}}
springs:
  s: {{nodes: [a, b], material: {{type: linear_elastic, stiffness: {stiffness!r}}}}}
initial_velocity: {{b: [{speed!r}]}}
rigid_walls:
  - {{id: floor, point: [{wall}], normal: [1.0], nodes: [b]}}
end_time: {end_time!r}
time_step: {{safety_factor: 0.9}}
output: {{interval: 1.0e-5, histories: all}}
"""
