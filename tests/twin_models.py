"""The model builders of the bitwise twin tests: the same model run by the NumPy reference kernel and by
each fast kernel (tests/test_kernel_twins.py, tests/test_metrics_record.py's per-step record), shared with the
physics and knot-peak tests that check some of them against closed forms. The twin cases (a builder and
its study axes) are tests/twins.py; the v2 spring features' builders tests/twin_v2_models.py."""

from __future__ import annotations

import copy
from typing import Any

from helpers import STUDIES
from model_parts import disjoint
from twin_v2_models import _v2_intact, _v2_springs, rate_elastic_model

G = 9.80665  # m/s^2
HELICOPTER = STUDIES / "models" / "helicopter-subfloor.yaml"
MASSES = [6.0, 8.0, 10.0, 12.0, 14.0]

TWIN_1D: dict[str, Any] = {  # crush, linear + damper, nonlinear, general_nonlinear; wall, gravity, load, pm
    "name": "twin-1d",
    "curves": {
        "plateau": {"x": [-1.0, -0.002, 0.0], "y": [-3000.0, -3000.0, 0.0]},
        "soft": {"x": [-0.1, -0.01, 0.0, 0.01, 0.1], "y": [-4000.0, -500.0, 0.0, 500.0, 4000.0]},
        "gn-load": {"x": [-0.5, -0.005, 0.0, 0.005, 0.5], "y": [-2500.0, -1500.0, 0.0, 1500.0, 2500.0]},
        "gn-unload": {"x": [-0.01, 0.0, 0.01], "y": [-3000.0, 0.0, 3000.0]},
        "pulse": {"x": [0.0, 0.01, 0.03], "y": [0.0, 1.0, 0.0]},
        "pull": {"x": [0.0, 0.2], "y": [-1.0, -1.0]},
    },
    "nodes": {
        "ground": {"position": [0.0], "fixed": True},
        "a": {"position": [0.5], "mass": 4.0},
        "b": {"position": [1.0], "mass": 3.0},
        "c": {"position": [1.5], "mass": 2.0},
        "driver": {"position": [2.0], "mass": 1.0},
    },
    "springs": {
        "crush": {
            "nodes": ["ground", "a"],
            "material": {"type": "crush", "loading": "plateau", "unloading_stiffness": 2.0e6},
        },
        "link": {"nodes": ["a", "b"], "material": {"type": "linear_elastic", "stiffness": 2.0e5}},
        "dash": {"nodes": ["a", "b"], "material": {"type": "damper", "damping": 150.0}},
        "rubber": {"nodes": ["b", "c"], "material": {"type": "nonlinear_elastic", "curve": "soft"}},
        "yielding": {
            "nodes": ["c", "driver"],
            "material": {
                "type": "general_nonlinear",
                "loading": "gn-load",
                "unloading": "gn-unload",
                "tension_yield": 1500.0,
                "compression_yield": -1500.0,
            },
        },
    },
    "initial_velocity": {"a": [-6.0], "b": [-6.0], "c": [-6.0], "driver": [-2.0]},
    "gravity": [-G],
    "loads": [{"node": "b", "force": [-800.0], "curve": "pulse"}],
    "prescribed_motion": [
        {"node": "driver", "quantity": "velocity", "direction": "x", "curve": "pull", "scale": 2.0}
    ],
    "rigid_walls": [{"id": "stop", "point": [0.47], "normal": [1.0], "nodes": ["a"]}],
    "end_time": 0.06,
    "output": {"interval": 5.0e-4},
}

TWIN_2D_HELI: dict[str, Any] = {  # helicopter-like, 2 general_nonlinear, sliding onto a floor, gravity, load
    "name": "twin-2d-heli",
    "curves": {
        "uf-load": {
            "x": [-0.5, -0.223, -0.045, -0.009, 0.0, 10.0],
            "y": [-76000.0, -57200.0, -70000.0, -40000.0, 0.0, 5000.0],
        },
        "uf-unload": {"x": [-0.009, 0.0, 0.009], "y": [-40000.0, 0.0, 40000.0]},
        "cab-load": {"x": [-0.3, -0.27, -0.225, -0.01, 0.0], "y": [-1.0e6, -5.0e5, -1.5e5, -1.5e5, 0.0]},
        "cab-unload": {"x": [-0.006, 0.0, 0.006], "y": [-1.7e5, 0.0, 1.7e5]},
        "gust": {"x": [0.0, 0.02, 0.04], "y": [0.0, 1.0, 0.0]},
    },
    "nodes": {
        "ground": {"position": [0.0, 0.0], "fixed": True},
        "transmission": {"position": [0.02, 0.3], "mass": 100.0},
        "cabin": {"position": [0.0, 0.9], "mass": 300.0},
    },
    "springs": {
        "underfloor": {
            "nodes": ["ground", "transmission"],
            "material": {
                "type": "general_nonlinear",
                "loading": "uf-load",
                "unloading": "uf-unload",
                "tension_yield": 5000.0,
                "compression_yield": -40000.0,
            },
        },
        "cabin": {
            "nodes": ["transmission", "cabin"],
            "material": {
                "type": "general_nonlinear",
                "loading": "cab-load",
                "unloading": "cab-unload",
                "compression_yield": -150000.0,
            },
        },
    },
    "initial_velocity": {"transmission": [0.5, -8.2], "cabin": [0.0, -8.2]},
    "gravity": [0.0, -G],
    "loads": [{"node": "cabin", "force": [2000.0, -5000.0], "curve": "gust"}],
    "rigid_walls": [{"id": "floor", "point": [0.0, 0.1], "normal": [0.0, 1.0], "nodes": ["transmission"]}],
    "end_time": 0.12,
    "output": {"interval": 1.0e-3},
}

TWIN_2D_MIXED: dict[
    str, Any
] = {  # crush, damper, linear, nonlinear; displacement + acceleration pm; inclined wall
    "name": "twin-2d-mixed",
    "curves": {
        "crumple": {"x": [-1.0, -0.05, -0.005, 0.0], "y": [-9000.0, -4000.0, -5000.0, 0.0]},
        "bushing": {"x": [-0.02, 0.0, 0.02], "y": [-3000.0, 0.0, 1500.0]},
        "push": {"x": [0.0, 0.05, 0.1], "y": [0.0, -0.03, -0.02]},
        "shake": {"x": [0.0, 0.02, 0.04, 0.1], "y": [0.0, 50.0, -50.0, 0.0]},
    },
    "nodes": {
        "base": {"position": [0.0, 0.0], "fixed": True},
        "ram": {"position": [0.0, 0.4], "mass": 2.0, "fixed": ["x"]},
        "bob": {"position": [0.3, 0.5], "mass": 1.5},
        "tip": {"position": [0.6, 0.3], "mass": 1.0},
        "shaker": {"position": [0.6, 0.0], "mass": 0.5},
    },
    "springs": {
        "crumple": {
            "nodes": ["base", "bob"],
            "material": {"type": "crush", "loading": "crumple", "unloading_stiffness": 4.0e5},
        },
        "dash": {"nodes": ["ram", "bob"], "material": {"type": "damper", "damping": 40.0}},
        "strut": {"nodes": ["ram", "bob"], "material": {"type": "linear_elastic", "stiffness": 5.0e4}},
        "bushing": {"nodes": ["bob", "tip"], "material": {"type": "nonlinear_elastic", "curve": "bushing"}},
        "arm": {"nodes": ["tip", "shaker"], "material": {"type": "linear_elastic", "stiffness": 2.0e4}},
    },
    "initial_velocity": {"bob": [-2.0, -3.0], "tip": [1.0, -1.0]},
    "gravity": [0.0, -G],
    "prescribed_motion": [
        {"node": "ram", "quantity": "displacement", "direction": "y", "curve": "push", "scale": 1.0},
        {"node": "shaker", "quantity": "acceleration", "direction": "x", "curve": "shake", "scale": 1.0},
    ],
    "rigid_walls": [{"id": "slope", "point": [0.6, 0.297], "normal": [-0.3, 1.0], "nodes": ["tip"]}],
    "end_time": 0.1,
    "output": {"interval": 1.0e-3},
}

TWINS = {
    "1d-all-materials": (TWIN_1D, "nodes.a.mass", [1.0, 2.0, 4.0, 6.0, 8.0]),
    "2d-helicopter-wall": (TWIN_2D_HELI, "nodes.cabin.mass", [200.0, 250.0, 300.0, 350.0, 400.0]),
    "2d-mixed-prescribed": (TWIN_2D_MIXED, "nodes.bob.mass", [0.5, 1.0, 1.5, 2.0, 3.0]),
}

# A curve whose |force| has a local maximum of 1500 N at the knot x = -0.01 m (and, mirrored, at +0.01):
# from there the force falls to 1000 N (crush) or 500 N (elastic, general) over the next 0.09 m.
PEAK_Y = 1500.0  # N
MASS = 10.0  # kg
CURVES = {
    "crush": {"x": [-1.0, -0.1, -0.01, 0.0], "y": [-2000.0, -1000.0, -PEAK_Y, 0.0]},
    "elastic": {"x": [-0.1, -0.01, 0.0, 0.01, 0.1], "y": [-500.0, -PEAK_Y, 0.0, PEAK_Y, 500.0]},
    "steep": {"x": [-0.01, 0.0, 0.01], "y": [-1.0e5, 0.0, 1.0e5]},
}
MATERIALS = {
    "crush": {"type": "crush", "loading": "crush", "unloading_stiffness": 1.0e6},
    "nonlinear_elastic": {"type": "nonlinear_elastic", "curve": "elastic"},
    # yields at -1000 N on the first segment, then crushes on over the knot (mode -1 loading path)
    "general_nonlinear": {
        "type": "general_nonlinear",
        "loading": "elastic",
        "unloading": "steep",
        "compression_yield": -1000.0,
    },
}


def one_mass(kind: str, dim: int = 1, dt: float = 2.5e-4) -> dict[str, Any]:
    """A 10 kg mass at 1 m from a fixed node, moving toward it at 4 m/s on one spring of ``kind``.

    The spring passes over the 1500 N knot while loading (at ~2.5 ms), turns at -0.064 / -0.073 m below
    1300 N,
    and (crush) separates. ``dim`` 2 puts the spring on the diagonal (0.6, 0.8). Fixed ``dt``; histories at
    every step.
    """
    pos, vel = ([1.0], [-4.0]) if dim == 1 else ([0.6, 0.8], [-2.4, -3.2])
    return {
        "name": f"knot-{kind}-{dim}d",
        "curves": CURVES,
        "nodes": {
            "ground": {"position": [0.0] * dim, "fixed": True},
            "body": {"position": pos, "mass": MASS},
        },
        "springs": {"s": {"nodes": ["ground", "body"], "material": MATERIALS[kind]}},
        "initial_velocity": {"body": vel},
        "end_time": 0.06,
        "time_step": {"dt": dt},
        "output": {"interval": dt, "histories": ["spring_force", "spring_elongation"]},
    }


FRONT_X = [-0.9, -0.7, -0.05, -0.01, 0.0]  # m
FRONT_Y = [-2.0e6, -3.5e5, -2.5e5, -3.2e5, 0.0]  # N
M_B, M_O, K_BELT, K_U, V0, T_END = 1200.0, 80.0, 1.5e5, 4.0e7, 15.0, 0.15
CRUSH_REBOUND: dict[str, Any] = {
    "name": "crush-rebound",
    "curves": {"front": {"x": FRONT_X, "y": FRONT_Y}},
    "nodes": {
        "barrier": {"position": [0.0], "fixed": True},
        "body": {"position": [0.8], "mass": M_B},
        "occupant": {"position": [1.6], "mass": M_O},
    },
    "springs": {
        "front": {
            "nodes": ["barrier", "body"],
            "material": {"type": "crush", "loading": "front", "unloading_stiffness": K_U},
        },
        "belt": {"nodes": ["body", "occupant"], "material": {"type": "linear_elastic", "stiffness": K_BELT}},
    },
    "initial_velocity": {"body": [-V0], "occupant": [-V0]},
    "end_time": T_END,
    "output": {"interval": T_END, "histories": "none"},
}


def without_walls_and_loads(
    model: dict[str, Any], keep_gravity: bool = True, keep_walls: bool = False
) -> dict[str, Any]:
    """``model`` without what generated kernels leave to the generic one (prescribed motion), and without
    its walls and loads / gravity unless kept."""
    m = copy.deepcopy(model)
    for key in (
        ("prescribed_motion",)
        + (() if keep_walls else ("rigid_walls", "loads"))
        + (() if keep_gravity else ("gravity",))
    ):
        m.pop(key, None)
    for node in m["nodes"].values():  # a prescribed dof of the twin becomes a free one
        node.pop("fixed", None) if node.get("fixed") is not True else None
    m["output"]["histories"] = "all"
    return m


def one_d_materials(mirror: bool = False, gravity: bool = False) -> dict[str, Any]:
    """TWIN_1D without loads and prescribed motion: crush, linear + damper in parallel, nonlinear elastic,
    general_nonlinear; ``gravity`` keeps its gravity, its rigid wall and its load pulse. ``mirror`` draws
    the model right to left (every spring's 1-D sign is -1)."""
    m = without_walls_and_loads(TWIN_1D, keep_gravity=gravity, keep_walls=gravity)
    if mirror:
        for node in m["nodes"].values():
            node["position"] = [-node["position"][0]]
        m["initial_velocity"] = {k: [-v[0]] for k, v in m["initial_velocity"].items()}
    return m


def mount_reversal() -> dict[str, Any]:
    """A 170 kg engine driven at 3 m/s into an engine mount (general_nonlinear, yield +-20 kN): it yields
    in compression, unloads along the 4.5e6 N/m line and the spring-back (about 100 J stored against
    44 J needed) carries it past the tension yield: general_nonlinear rule 4 (the reversal path) runs."""
    return {
        "name": "mount-reversal",
        "curves": {
            "load": {
                "x": [-0.1, -0.04, -0.01, 0.0, 0.01, 0.04, 0.1],
                "y": [-3.0e5, -3.0e4, -2.0e4, 0.0, 2.0e4, 3.0e4, 3.0e5],
            },
            "unload": {"x": [-0.01, 0.0, 0.01], "y": [-4.5e4, 0.0, 4.5e4]},
        },
        "nodes": {"frame": {"position": [0.0], "fixed": True}, "engine": {"position": [0.2], "mass": 170.0}},
        "springs": {
            "mount": {
                "nodes": ["frame", "engine"],
                "material": {
                    "type": "general_nonlinear",
                    "loading": "load",
                    "unloading": "unload",
                    "tension_yield": 2.0e4,
                    "compression_yield": -2.0e4,
                },
            }
        },
        "initial_velocity": {"engine": [-3.0]},
        "end_time": 0.08,
        "output": {"interval": 2.0e-4, "histories": ["spring_force", "spring_elongation", "acceleration"]},
    }


def crush_bounce(v0: float = 10.0) -> dict[str, Any]:
    """A 100 kg mass at v0 onto a crush spring with a 20 kN plateau (reached after 0.1 mm) and unloading
    stiffness 2e6 N/m, then free flight: crush for m v0 / F0, spring-back for a quarter period of
    sqrt(k_u / m), then the spring is separated and opening."""
    return {
        "name": "crush-bounce",
        "curves": {"plateau": {"x": [-2.0, -1.0e-4, 0.0], "y": [-2.0e4, -2.0e4, 0.0]}},
        "nodes": {"wall": {"position": [0.0], "fixed": True}, "body": {"position": [1.0], "mass": 100.0}},
        "springs": {
            "pad": {
                "nodes": ["wall", "body"],
                "material": {"type": "crush", "loading": "plateau", "unloading_stiffness": 2.0e6},
            }
        },
        "initial_velocity": {"body": [-v0]},
        "end_time": 0.2,
        "time_step": {"tolerance": 1.0e-5},
        "termination": {"kinetic_energy_fraction": 1.0e-3},
        "output": {"interval": 1.0e-3, "histories": ["spring_force"]},
    }


def full_twin_both_ways() -> dict[str, Any]:
    """TWIN_1D (every material left to right, walls, gravity, load, prescribed velocity) with
    :func:`one_d_materials` drawn right to left beside it (``rev-``, under the same gravity), to 0.03 s
    instead of TWIN_1D's 0.06 (the reference run 1.5 s of CPU instead of 4.0): by then the crush springs
    have reached their plateau and unloaded, the general_nonlinear ones yielded and unloaded."""
    model = disjoint({"rev": one_d_materials(True)}, base=TWIN_1D)
    model["end_time"] = 0.03
    return model


def knots(dim: int, scaled: bool = False) -> dict[str, Any]:
    """:func:`one_mass` of every curve material side by side (``crush-``, ``elastic-``, ``general-``);
    ``scaled`` adds them a second time (``s-crush-`` ...), for the curves that :data:`SCALED_KNOTS` scales."""
    parts = {p: one_mass(k, dim=dim, dt=4e-4) for k, p in _KNOT_PREFIX.items()}
    return disjoint(parts | ({f"s-{p}": part for p, part in parts.items()} if scaled else {}))


def _v2_parts(dim: int) -> dict[str, dict[str, Any]]:
    """The SPEC v2 spring features breaking (``f-``) beside rate_elastic (``r-``); in 1-D, intact (``i-``)
    too. (2-D has no ``i-``: a spring's 2-D code and its breaking code are separate, each checked here: 2-D
    in ``f-``, intact in 1-D ``i-``; in 2-D the springs without a failure option, ``f-nd``, ``f-gn`` and
    ``r-``, still run beside breaking ones.)"""
    return (
        {"f": _v2_springs(dim)}
        | ({"i": _v2_intact(dim)} if dim == 1 else {})
        | {"r": rate_elastic_model(dim)}
    )


def springs_1d() -> dict[str, Any]:
    """:func:`knots` 1-D on constant and on scaled curves (``k-``), :data:`CRUSH_REBOUND` (``cr-``),
    :func:`mount_reversal` (``mount-``) and :func:`_v2_parts` 1-D side by side, on the knots' fixed step of
    0.4 ms, to 0.08 s (the mount's reversal ends after 0.06 s; the v2 springs that break do by then)."""
    parts = {"k": knots(1, scaled=True), "cr": CRUSH_REBOUND, "mount": mount_reversal(), **_v2_parts(1)}
    model = disjoint(parts)
    model["end_time"] = 0.08
    return model


def springs_2d() -> dict[str, Any]:
    """:func:`_v2_parts` 2-D (its step, end time 0.3 s and output) with :func:`one_mass` 2-D of every curve
    material beside them (``crush-``, ``elastic-``, ``general-``), to 0.1 s (the v2 springs that break do
    by then; the reference run 0.9 s of CPU instead of 2.3 at 0.3 s)."""
    model = disjoint(_v2_parts(2) | {p: one_mass(k, dim=2) for k, p in _KNOT_PREFIX.items()})
    model["end_time"] = 0.1
    return model


_KNOT_PREFIX = {"crush": "crush", "nonlinear_elastic": "elastic", "general_nonlinear": "general"}


def _helicopter_walls() -> dict[str, Any]:
    model = without_walls_and_loads(TWIN_2D_HELI, keep_walls=True)
    model["rigid_walls"][0]["nodes"] = ["transmission", "cabin"]  # the floor
    model["rigid_walls"].append(
        {"id": "side", "point": [0.03, 0.0], "normal": [-1.0, 0.0], "nodes": ["transmission", "cabin"]}
    )
    return model


def _helicopter_penalty_side() -> dict[str, Any]:
    """:func:`_helicopter_walls` with a penalty side wall (contact stiffness a study axis)."""
    model = _helicopter_walls()
    model["rigid_walls"][1]["stiffness"] = 1.0e6
    return model


def full_twin_2d() -> dict[str, Any]:
    """TWIN_2D_MIXED (crush, damper, linear, nonlinear; prescribed displacement and acceleration, an
    inclined rigid wall ``slope``), with :func:`_helicopter_penalty_side` beside it (``h-``: two
    general_nonlinear springs, its load pulse, a rigid floor and a penalty side wall holding both masses),
    under the same gravity, to 0.06 s (TWIN_2D_MIXED's 0.1 s: the reference run 8.6 s of CPU instead of
    4.2; by 0.06 s every wall is hit and the helicopter's underfloor has passed its largest crush)."""
    model = disjoint({"h": _helicopter_penalty_side()}, base=TWIN_2D_MIXED)
    model["end_time"] = 0.06
    return model


def _bounce_many() -> dict[str, Any]:
    """:func:`crush_bounce` to 0.3 s on a step tolerance of 1e-3 (6900 steps at most instead of 67800 at
    1e-5: the reference run, twice per test session, 1.3 s of CPU instead of 12): every variant of the
    early-termination case still stops before 0.2 s, each at its own time."""
    model = crush_bounce()
    model["end_time"] = 0.3
    model["time_step"] = {"tolerance": 1.0e-3}
    return model
